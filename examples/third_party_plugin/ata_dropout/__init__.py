"""ata-dropout: an example third-party plugin contributing the `sensor_dropout` injector.

With probability ``probability`` per epoch, scenario and human, the fatigue sensor of that human
drops out: the observed fatigue is replaced by ``fill`` (1.0 by default, the reading of a rested
human, which is what a policy would assume without a reading) and the dropout is flagged in
``obs.extras["fatigue_dropout"]``, a (B, H) bool array, so that a reconstructor or a policy can
tell a lost reading from a real one. The true state in ``sim`` is untouched, and the human stays
in the observation (its mask is not changed): only the one reading is lost.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ata import hookimpl
from ata.core.settings import param
from ata.core.state import Observation, SimState

__version__ = "0.1.0"


class SensorDropout:
    """Loses humans' fatigue readings at random; see the module docstring."""

    @dataclass
    class Settings:
        probability: float = param(0.2, min=0.0, max=1.0,
                                   help="chance a human's fatigue reading is lost in an epoch")
        fill: float = param(1.0, min=0.0, max=1.0,
                            help="fatigue value observed in place of a lost reading")

    def __init__(self, settings: "SensorDropout.Settings", mission: object):
        self.probability = settings.probability
        self.fill = settings.fill

    @hookimpl
    def ata_inject(self, sim: SimState, obs: Observation) -> None:
        humans = obs["humans"]
        # a stream name of our own, counted by epoch: draws depend on (seed, scenario) alone
        lost = sim.rng.uniform("sensor_dropout", sim.epoch,
                               (humans.features.shape[1],)) < self.probability
        humans.set("fatigue", np.where(lost, self.fill, humans.col("fatigue")))
        obs.extras["fatigue_dropout"] = lost


@hookimpl
def ata_register_components(register) -> None:
    register("injector", "sensor_dropout", SensorDropout)
