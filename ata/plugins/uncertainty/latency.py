"""Latency: each robot's and each task's observed row is, with probability p, the one observed
at the previous epoch. Human states have no latency (the humans are on site). A task whose row is
stale is seen as reallocatable or not as it was at the previous epoch too (whether it had been
captured, whether a robot was on its way to it): the observation's ``reallocatable``."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ata import hookimpl
from ata.core.settings import param
from ata.core.state import Observation, SimState


class Latency:
    """MODEL.md section 6. Stale rows chain: a row kept twice is two epochs old."""

    @dataclass
    class Settings:
        probability: float | None = param(None, min=0.0, max=1.0,
                                          help="per-row probability; default: the level's p")
        groups: list[str] = param(["robots", "tasks"], choices=("humans", "robots", "tasks"),
                                  help="entity groups that lag")

    def __init__(self, settings: "Latency.Settings", mission):
        self.p = (settings.probability if settings.probability is not None
                  else mission.event_probability)
        self.groups = list(settings.groups)
        self.previous: dict[str, np.ndarray] = {}
        self.previous_open: np.ndarray | None = None    # reallocatable as last observed

    @hookimpl
    def ata_inject(self, sim: SimState, obs: Observation) -> None:
        for group in self.groups:
            table = obs[group]
            prev = self.previous.get(group)
            if prev is not None and self.p > 0:
                stale = sim.rng.uniform(f"latency.{group}", sim.epoch,
                                        (table.features.shape[1],)) < self.p
                table.features[:] = np.where(stale[..., None], prev, table.features)
                obs.extras[f"stale_{group}"] = stale
                if group == "tasks" and obs.reallocatable is not None \
                        and self.previous_open is not None:
                    obs.reallocatable = np.where(stale, self.previous_open, obs.reallocatable)
            self.previous[group] = table.features.copy()
        if "tasks" in self.groups and obs.reallocatable is not None:
            self.previous_open = obs.reallocatable.copy()


@hookimpl
def ata_register_components(register) -> None:
    register("injector", "latency", Latency)
