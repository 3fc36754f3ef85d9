"""The phase loop that trainers run their phases with: step counters, log.csv rows, held-out
validation and best.pt, checkpoint.pt every few steps, and resume from where the counters stand.

A trainer describes each phase as a ``Phase`` (how many steps, what one step does, how it is
validated) and hands it to ``PhaseLoop.run_phase``; the loop owns everything else, so that every
phase of every trainer counts, logs, checkpoints and resumes alike:

    loop = PhaseLoop(["warmup", "main"], checkpoint=lambda name: {"kind": ..., **loop.state()})
    loop.run = train_run                         # the TrainRun folder, once `run` is called
    loop.run_phase(Phase("main", steps=100, step=one_step, eval_every=10, validate=check))
    return loop.finish()

A step is whole or not done: a run killed inside one does it again on resume, so a step must be
a function of the checkpointed state (weights, optimiser, random generators, counters).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import Any, Callable, Iterable

from ata.training.run import TrainRun

__all__ = ["Phase", "PhaseLoop"]


@dataclass
class Phase:
    """One phase of a trainer, as the loop runs it.

    :param step: runs step ``k`` (counted from 0) and returns its log.csv columns and the
        episodes it played (the loop adds ``phase``, ``step``, ``episodes``, ``episodes_per_s``
        and ``wall_s``).
    :param validate: the held-out validation: the score best.pt follows, and its log columns.
    :param eval_every: validate after every N-th step and after the last (0: never).
    :param validate_first: validate once before the first step, logged as step 0 (what the
        phase starts from).
    :param fresh_best: that step-0 validation forgets the best score so far, so that best.pt
        is chosen among this phase's steps and the ones after it.
    :param start: called before the phase's steps whenever this process has steps of it to do
        (a first run or a resume): data to collect, learning rates to set.
    :param end: called after the phase's last step, in the process that made it; its report.
    """

    name: str
    steps: int
    step: Callable[[int], tuple[dict[str, Any], int]]
    checkpoint_every: int = 1
    eval_every: int = 0
    validate: Callable[[], tuple[float, dict[str, Any]]] | None = None
    validate_first: bool = False
    fresh_best: bool = False
    start: Callable[[], None] | None = None
    end: Callable[[], dict[str, float]] | None = None


class PhaseLoop:
    """Counters, log rows, validation and checkpoints of a trainer's phases.

    :param phases: the names of the phases, each with a step counter of its own.
    :param checkpoint: the trainer's checkpoint dict for a file name (``checkpoint.pt`` or
        ``best.pt``); it should hold ``state()``, which ``load_state`` reads back.
    """

    def __init__(self, phases: Iterable[str], checkpoint: Callable[[str], dict[str, Any]]):
        self.counters: dict[str, int] = {**{p: 0 for p in phases}, "episodes": 0}
        self.best_eval = -math.inf
        self.wall = 0.0
        self.validated_at_start: set[str] = set()     # phases whose step-0 row is logged
        self.checkpoint = checkpoint
        self.run: TrainRun | None = None

    def done_steps(self) -> int:
        """Steps done over every phase (the progress bar)."""
        return sum(n for name, n in self.counters.items() if name != "episodes")

    def state(self) -> dict[str, Any]:
        """The loop's part of a checkpoint."""
        return {"counters": dict(self.counters), "best_eval": float(self.best_eval),
                "wall_s": float(self.wall), "validated_at_start": sorted(self.validated_at_start)}

    def load_state(self, data: dict[str, Any]) -> None:
        """Take the counters, best score and training time of a checkpoint (``state()``)."""
        self.counters.update({k: int(v) for k, v in data["counters"].items()})
        self.validated_at_start = set(data.get("validated_at_start", []))
        self.best_eval = float(data.get("best_eval", -math.inf))
        self.wall = float(data.get("wall_s", 0.0))

    def save(self, name: str = "checkpoint.pt") -> None:
        self.run.save(self.checkpoint(name), name)

    def run_phase(self, phase: Phase) -> dict[str, float]:
        """The steps of `phase` that are not done yet; its report if it ended here."""
        if phase.steps == 0 or self.counters[phase.name] >= phase.steps:
            return {}
        if phase.start is not None:
            phase.start()
        if phase.validate_first and self.counters[phase.name] == 0 \
                and phase.name not in self.validated_at_start:
            self._validate(phase, {"phase": phase.name, "step": 0, "wall_s": f"{self.wall:.1f}"})
            self.validated_at_start.add(phase.name)
            self.save()                       # a resumed run neither redoes nor loses its row
        while self.counters[phase.name] < phase.steps:
            k = self.counters[phase.name]
            t0 = time.perf_counter()
            columns, episodes = phase.step(k)
            dt = time.perf_counter() - t0
            self.counters[phase.name] = done = k + 1
            self.counters["episodes"] += episodes
            self.wall += dt
            row = {"phase": phase.name, "step": done, **columns}
            if episodes:
                row.update(episodes=self.counters["episodes"],
                           episodes_per_s=f"{episodes / dt:.1f}")
            row["wall_s"] = f"{self.wall:.1f}"
            if phase.eval_every and (done % phase.eval_every == 0 or done == phase.steps):
                self._validate(phase, row)
            else:
                self.run.log(row)
            if done % phase.checkpoint_every == 0:
                self.save()
        self.save()
        return phase.end() if phase.end is not None else {}

    def _validate(self, phase: Phase, row: dict[str, Any]) -> None:
        score, columns = phase.validate()
        row.update(columns)
        if row["step"] == 0 and phase.fresh_best:
            self.best_eval = -math.inf
        if score > self.best_eval:
            self.best_eval = score
            self.save("best.pt")
        self.run.log(row)

    def finish(self) -> dict[str, Any]:
        """best.pt written if no validation wrote one, and the run's summary."""
        if not self.run.best_path.exists():
            self.save("best.pt")
        return {"best_eval": self.best_eval, "wall_s": self.wall,
                "counters": dict(self.counters), "best": str(self.run.best_path)}
