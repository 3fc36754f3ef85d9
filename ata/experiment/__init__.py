"""Experiments around the kernel, above the plugins: loading a mission into a session
(`runner`), one run path for `ata run` and `ata eval` (`execute`: a plan's work units on an
executor, `units`, with a durable record that makes every run resumable, `runlog`), evaluation
suites on held-out scenarios (`suites`, `evaluate`), and what reads their folders back:
evaluation reports (`results`, `report`), comparisons (`compare`) and training curves
(`curves`); `terminal` and `tables` draw them for the command line.

``ata.core`` is the kernel and ``ata.runtime`` the helpers below the plugins; everything here
uses them, never the other way round."""
