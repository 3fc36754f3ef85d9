"""Latency: each robot's and each task's observed row is, with probability p, the one observed
at the previous epoch. Human states have no latency (the humans are on site). A stale row holds
what it held then: a stale task row shows its POI uncaptured if it was, a stale robot row the POI
it was on its way to, and the observation's ``reallocatable`` follows the rows as shown."""

from __future__ import annotations

from dataclasses import dataclass


from ata import hookimpl
from ata.core.settings import param
from ata.core.state import EntityTable, Observation, SimState


class Latency:
    """docs/model.md, "Uncertainty". Stale rows chain: a row kept twice is two epochs old."""

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
        self.previous: dict[str, EntityTable] = {}

    @hookimpl
    def ata_inject(self, sim: SimState, obs: Observation) -> None:
        for group in self.groups:
            table = obs[group]
            prev = self.previous.get(group)
            if prev is not None and self.p > 0:
                stale = sim.rng.uniform(f"latency.{group}", sim.epoch,
                                        (table.features.shape[1],)) < self.p
                # the row and what it holds (the POI a robot is on its way to, a captured
                # POI): `reallocatable` is read off the rows as observed
                table.keep_rows(stale, prev)
                obs.extras[f"stale_{group}"] = stale
            self.previous[group] = table.copy()


@hookimpl
def ata_register_components(register) -> None:
    register("injector", "latency", Latency)
