"""Condition policies: when to reallocate. `never`, `always`, and `on_event` (a new robot
failure or task attribute change shows in the observed state)."""

from __future__ import annotations

import numpy as np

from ata import hookimpl
from ata.core.state import DecisionContext


class Never:
    """Never reallocate: the initial allocation stands (ITA-only methods)."""

    def __init__(self, settings: None, mission: object):
        pass

    @hookimpl
    def ata_should_reallocate(self, ctx: DecisionContext) -> np.ndarray:
        return np.zeros(ctx.reallocatable.shape[0], dtype=bool)


class Always:
    """Reallocate at every epoch (the w/o.C ablation, TR-POMDP)."""

    def __init__(self, settings: None, mission: object):
        pass

    @hookimpl
    def ata_should_reallocate(self, ctx: DecisionContext) -> np.ndarray:
        return np.ones(ctx.reallocatable.shape[0], dtype=bool)


class OnEvent:
    """Reallocate when the observation shows a robot newly down or a task's kind or
    difficulty newly different from the last epoch's observation."""

    def __init__(self, settings: None, mission: object):
        self.prev_working: np.ndarray | None = None
        self.prev_attrs: np.ndarray | None = None

    @hookimpl
    def ata_should_reallocate(self, ctx: DecisionContext) -> np.ndarray:
        robots, tasks = ctx.observed["robots"], ctx.observed["tasks"]
        working = robots.col("working") > 0.5
        attrs = np.stack([tasks.col("kind"), tasks.col("difficulty")], axis=-1)
        if self.prev_working is None:   # first call: compare with the state at t = 0
            estimate = ctx.inherent["tasks"]
            self.prev_working = np.ones_like(working)
            self.prev_attrs = np.stack([estimate.col("kind"), estimate.col("difficulty")], -1)
        event = (self.prev_working & ~working).any(axis=1)
        event |= (attrs != self.prev_attrs).any(axis=(1, 2))
        self.prev_working, self.prev_attrs = working, attrs
        return event


@hookimpl
def ata_register_components(register) -> None:
    register("condition", "never", Never)
    register("condition", "always", Always)
    register("condition", "on_event", OnEvent)
