"""Experiments around the kernel: loading a mission into a session, running its scenarios in
chunks on an executor (serial, local processes, Ray) with a durable record that makes every run
resumable, evaluation suites on held-out scenarios, the run-scoped cache, and reports.

``ata.core`` is the kernel alone (kernel, state, rng, registry, settings, mission, errors);
everything here uses it, never the other way round."""
