"""The phases of the trainer ``ata_hrl``, one module each, in the order they run: ``aux`` (the
reconstructors), ``status`` (the aux module's status head), ``ita`` (the ITA policy alone),
``cond`` (pi_C's fitted rule) and ``ctr`` (pi_C and pi_TR after the ITA). Each module holds the
settings of its phase (a group of the ``[ata_hrl]`` table) and a class that makes the phase's
``ata.training.Phase`` for the trainer's phase loop; ``policy`` holds what the ITA and CTR
phases share.

Each phase draws its training scenarios (root seed ``seed``) from an id range of its own.
"""

FIRST_ID = {"aux": 0, "ita": 10_000_000, "ctr": 20_000_000, "cond": 30_000_000}
"""First scenario id of each phase's range (the status head draws from the aux range, after
the aux phase's own rollouts)."""
SPAN = 10_000_000
"""Scenario ids in each phase's range."""
