"""The run path of `ata run`, `ata eval` and `ata train`: a plan's work units on an executor
(`execute`, `units`), each unit run by its job's backend (``ata.backend``) and recorded in a
durable log that makes every run resumable (`runlog`); a mission's plan and run folder
(`runner`); suites of methods on held-out scenarios (`suites`, `evaluate`); training runs and
folders of seeds (`training`); published rows reproduced (`reproduce`).

Below it: the session (``ata.session``), the backends (``ata.backend``, ``ata.isolation``,
``ata.published``), the training layer, the runtime and the kernel. What reads the folders
back (tables, reports, curves) is ``ata.results``; the command line is ``ata.cli``."""
