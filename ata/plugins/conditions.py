"""Condition policies: when to reallocate. `never`, `always`, and `on_event` (a new robot
failure or task attribute change shows in the observed state)."""

from __future__ import annotations

import numpy as np

from ata import hookimpl
from ata.core.state import DecisionContext
from ata.model.events import EventWatch


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
        self.events = EventWatch()

    @hookimpl
    def ata_should_reallocate(self, ctx: DecisionContext) -> np.ndarray:
        failed, changed = self.events.step(ctx, ctx.observed["robots"].col("working") > 0.5)
        return failed.any(axis=1) | changed.any(axis=1)


@hookimpl
def ata_register_components(register) -> None:
    register("condition", "never", Never)
    register("condition", "always", Always)
    register("condition", "on_event", OnEvent)
