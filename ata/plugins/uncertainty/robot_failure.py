"""Robot failure: with probability p a robot stops for good at a uniform random time (sent to
the robot model through the queue ``robots.failure``)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ata import hookimpl
from ata.core.settings import param
from ata.core.state import SimState


class RobotFailure:
    """docs/model.md: the failure shows in S from the next epoch; the robot's POIs stay
    assigned to it, and score nothing, until reallocated."""

    @dataclass
    class Settings:
        probability: float | None = param(None, min=0.0, max=1.0,
                                          help="per-robot probability; default: the level's p")

    def __init__(self, settings: "RobotFailure.Settings", mission):
        self.p = (settings.probability if settings.probability is not None
                  else mission.event_probability)

    @hookimpl
    def ata_setup(self, sim: SimState) -> None:
        R = sim.sizes.robots
        fails = sim.rng.uniform("robot_failure.event", 0, (R,)) < self.p
        when = sim.rng.uniform("robot_failure.time", 0, (R,)) * sim.clock.horizon_s
        b, r = np.nonzero(fails)
        sim.queue("robots.failure").put(b=b, r=r, time=when[b, r])


@hookimpl
def ata_register_components(register) -> None:
    register("perturbation", "robot_failure", RobotFailure)
