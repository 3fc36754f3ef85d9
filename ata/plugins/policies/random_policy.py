"""The random allocation: every triple drawn uniformly (the floor every method must beat)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ata import hookimpl
from ata.core.settings import param
from ata.core.state import Allocation, DecisionContext


class RandomPolicy:
    """Robot uniform; navigator auto with probability p_auto, else a uniform human; classifier
    onboard with probability p_onboard, else a uniform human."""

    @dataclass
    class Settings:
        p_auto: float = param(0.5, min=0.0, max=1.0, help="probability of autonomous driving")
        p_onboard: float = param(0.5, min=0.0, max=1.0, help="probability of onboard "
                                 "classification")

    def __init__(self, settings: "RandomPolicy.Settings", mission: object):
        self.s = settings

    def _draw(self, ctx: DecisionContext) -> Allocation:
        P, H, R = ctx.sizes.tasks, ctx.sizes.humans, ctx.sizes.robots
        k = ctx.epoch
        robot = ctx.rng.integers("random.robot", k, R, (P,))
        nav_h = ctx.rng.integers("random.navigator", k, H, (P,))
        cls_h = ctx.rng.integers("random.classifier", k, H, (P,))
        auto = ctx.rng.uniform("random.auto", k, (P,)) < self.s.p_auto
        onboard = ctx.rng.uniform("random.onboard", k, (P,)) < self.s.p_onboard
        return Allocation(robot, np.where(auto, -1, nav_h), np.where(onboard, -1, cls_h))

    @hookimpl
    def ata_initial_allocation(self, ctx: DecisionContext) -> Allocation:
        return self._draw(ctx)

    @hookimpl
    def ata_reallocate(self, ctx: DecisionContext, active: np.ndarray) -> Allocation:
        return self._draw(ctx)


@hookimpl
def ata_register_components(register) -> None:
    register("policy", "random", RandomPolicy)
