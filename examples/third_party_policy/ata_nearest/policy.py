"""The nearest capable robot: each POI goes to the nearest working robot whose type suits its
kind (a UAV for an air POI, a UGV for a ground one), or the nearest working robot when none of
that type works, the humans classifying in turn; as a reallocation policy it moves only the
POIs it may move.
"""

from dataclasses import dataclass

import numpy as np

from ata import hookimpl
from ata.core.settings import param
from ata.core.state import Allocation


class NearestCapable:
    name = "nearest_capable"           # the component's name, and its settings table's

    @dataclass
    class Settings:
        any_type: bool = param(False, help="ignore the robot type: the nearest robot of all")

    def __init__(self, settings: "NearestCapable.Settings", mission):
        self.any_type = settings.any_type

    def _choose(self, ctx) -> Allocation:
        tasks, robots = ctx.inherent["tasks"], ctx.inherent["robots"]
        state = ctx.observed["robots"] if ctx.observed is not None else None
        rx = state.col("x") if state is not None else np.zeros(robots.col("uav").shape)
        ry = state.col("y") if state is not None else np.zeros(robots.col("uav").shape)
        working = state.col("working") > 0.5 if state is not None else \
            np.ones(rx.shape, dtype=bool)
        kind = tasks.col("kind")                                      # (B, P): 0 air, 1 ground
        dist = np.hypot(tasks.col("x")[:, :, None] - rx[:, None, :],
                        tasks.col("y")[:, :, None] - ry[:, None, :])  # (B, P, R)
        suits = np.where(kind[:, :, None] < 0.5, robots.col("uav")[:, None, :],
                         robots.col("ugv")[:, None, :]) > 0.5
        suits = suits & working[:, None, :]
        if self.any_type:
            suits = np.broadcast_to(working[:, None, :], dist.shape)
        anyone = suits.any(axis=2, keepdims=True)
        allowed = np.where(anyone, suits, working[:, None, :])
        robot = np.where(allowed, dist, np.inf).argmin(axis=2)
        auto = np.full(robot.shape, -1)                               # robots drive themselves
        humans = np.broadcast_to(np.arange(robot.shape[1]) % ctx.sizes.humans, robot.shape)
        return Allocation(robot, auto, humans.copy())                 # humans classify in turn

    @hookimpl
    def ata_initial_allocation(self, ctx):
        return self._choose(ctx)

    @hookimpl
    def ata_reallocate(self, ctx, active):
        new, old = self._choose(ctx), ctx.previous
        move = ctx.reallocatable & active[:, None]
        return Allocation(np.where(move, new.robot, old.robot), old.navigator.copy(),
                          np.where(move, new.classifier, old.classifier))
