"""What a trainer component is: the class `ata train` builds (`TrainerFactory`) and the trainer
it runs (`Trainer`), declared once for the built-in trainers and a third party's alike."""

from __future__ import annotations

from typing import Any, Protocol, runtime_checkable

from ata.core.mission import Mission
from ata.core.registry import Register
from ata.training.run import TrainRun


@runtime_checkable
class Trainer(Protocol):
    """A component of kind ``trainer``: built as ``factory(settings, mission, registry)`` from
    its table of a training mission, then run once (or resumed) into a run folder.

    Two optional members: ``presets`` (``{name: {key: value}}`` of its table, ``ata train
    --preset NAME``) and ``trained_components()`` (the components whose ``checkpoint`` key its
    best.pt serves)."""

    log_fields: list[str]
    """The columns of its log.csv."""

    def scenario_ranges(self) -> list[tuple[int, int, int]]:
        """Every (root seed, first id, end id) the training may draw: below the evaluation ids,
        recorded in each checkpoint, refused by `ata eval`."""

    def total_steps(self) -> int:
        """The steps of the whole training, for the progress bar."""

    def done_steps(self) -> int:
        """The steps done so far."""

    def run(self, run: TrainRun, resume: bool = False) -> dict[str, Any]:
        """Train into `run` (from its last checkpoint when `resume`) to the end; its report
        (``best_eval``, ``wall_s``, ``counters``)."""


class TrainerFactory(Protocol):
    """What is registered as a ``trainer``: a class with a ``Settings`` dataclass (its table's
    keys), built as ``factory(settings, mission, registry)`` into a `Trainer`."""

    @property
    def Settings(self) -> type:                                       # noqa: N802 - a class
        """The dataclass of the trainer's table."""

    def __call__(self, settings: Any, mission: Mission, registry: Register) -> Trainer:
        """The trainer of a training mission, from its table's settings."""
