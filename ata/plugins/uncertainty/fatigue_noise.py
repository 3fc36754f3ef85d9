"""Fatigue noise: the observed fatigue is the true F_f plus N(0, sigma^2), fresh each epoch."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ata import hookimpl
from ata.core.settings import param
from ata.core.state import Observation, SimState


class FatigueNoise:
    """docs/model.md; sigma^2 from the mission's uncertainty level unless set here."""

    @dataclass
    class Settings:
        variance: float | None = param(None, min=0.0, max=10.0,
                                       help="noise variance; default: the mission's level")

    def __init__(self, settings: "FatigueNoise.Settings", mission):
        self.variance = (settings.variance if settings.variance is not None
                         else mission.fatigue_variance)

    @hookimpl
    def ata_inject(self, sim: SimState, obs: Observation) -> None:
        if self.variance <= 0:
            return
        humans = obs["humans"]
        noise = sim.rng.normal("fatigue_noise", sim.epoch, (humans.features.shape[1],))
        humans.set("fatigue", humans.col("fatigue") + np.sqrt(self.variance) * noise)


@hookimpl
def ata_register_components(register) -> None:
    register("injector", "fatigue_noise", FatigueNoise)
