"""What a trainer component needs from ata, for built-in and third-party trainers alike.

A *trainer* is a component of kind ``trainer``, registered by name like any other and chosen in
a training mission's ``[components] trainer``; its settings are the table named after it. `ata
train MISSION` builds it as ``factory(settings, mission, registry)`` and calls ``run``
(`TrainerFactory` declares the class, `Trainer` what it builds):

    class MyTrainer:
        log_fields = ["phase", "step", ...]                         # the columns of log.csv

        @dataclass
        class Settings: ...

        def __init__(self, settings, mission, registry): ...
        def scenario_ranges(self) -> list[tuple[int, int, int]]: ...   # (seed, first, end)
        def total_steps(self) -> int: ...
        def done_steps(self) -> int: ...                            # for the progress bar
        def run(self, run: TrainRun, resume: bool = False) -> dict: ...

Two optional members: ``presets`` (a class attribute, ``{name: {key: value}}`` of the trainer's
table: ``ata train --preset NAME``, ``ata.training.presets``) and ``trained_components()`` (the
components whose ``checkpoint`` key best.pt serves: the run folder's resolved mission names it,
so ``ata run RUN_DIR`` evaluates the trained weights).

``scenario_ranges`` lists every (root seed, scenario id range) the training may draw; the trainer
records it in each checkpoint, the components it trains report it through the
``ata_trained_on`` hook, and `ata eval` refuses to evaluate a method on any scenario in it.
Training ids must stay below ``TRAINING_ID_LIMIT`` (evaluation ids start at 2**40).

``TrainRun`` is the run folder: the resolved mission, ``log.csv`` (one row per step, and the
same scalars in TensorBoard event files where the ``tensorboard`` package is installed), and
checkpoints written atomically (a temporary file, then a rename), so a killed run resumes from
its last checkpoint with ``ata train --resume DIR``. ``PhaseLoop`` runs a trainer's phases
(``Phase``) over it: counters, log rows, validation, best.pt, checkpoints and resume, the same
for every trainer (both built-in ones use it).

A component's ``checkpoint`` setting may name a family of shipped weights (``builtin:ata_hrl``:
``ata_hrl_a`` and ``ata_hrl_b_ft``); ``weights_for(spec, team)`` resolves it to the member that
suits the mission's team, called from the settings' ``for_team`` (docs/plugins.md).
"""

from ata.runtime.inputs import WEIGHTS, family, file_digest, resolve, weights_for
from ata.training.checkpoints import (TRAINING_ID_LIMIT, VALIDATION_SEED_OFFSET, CheckpointError,
                                      load_cached, read_checkpoint, trained_on, trained_parts)
from ata.training.loop import Phase, PhaseLoop
from ata.training.protocol import Trainer, TrainerFactory
from ata.training.run import TrainRun

__all__ = ["TRAINING_ID_LIMIT", "VALIDATION_SEED_OFFSET", "WEIGHTS", "CheckpointError", "Phase",
           "PhaseLoop", "TrainRun", "Trainer", "TrainerFactory", "family", "file_digest",
           "load_cached", "read_checkpoint", "resolve", "trained_on", "trained_parts",
           "weights_for"]
