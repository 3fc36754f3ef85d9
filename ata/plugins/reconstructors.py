"""The identity reconstructor: passes the observed state on unchanged (the w/o.AUX ablation); the
arrivals reconstructor: captures that the latency hides, read from the robot rows."""

from __future__ import annotations

import numpy as np

from ata import hookimpl
from ata.core.state import DecisionView, Observation


class IdentityReconstructor:
    """Writes each observed group's features under its own name."""

    def __init__(self, settings: None, mission: object):
        pass

    @hookimpl
    def ata_reconstruct(self, sim: DecisionView, obs: Observation, inherent: Observation,
                        out: dict[str, np.ndarray]) -> None:
        for group, table in obs.items():
            out.setdefault(group, table.features)


class ArrivalReconstructor:
    """Captures the latency hides, read from the robot rows: a POI whose observed row is as it
    was an epoch before (so it may be stale) and shows it unvisited, although the robot that
    headed for it, still allocated to it and seen fresh and working now, heads for another POI
    or for none. A robot leaves its target only once it has captured it (MODEL.md section 4),
    unless a reallocation took the POI away, which the allocation in force shows. The guess goes
    under ``captured_guess`` (B, P, 1); `plan_start` takes such POIs as captured, for every
    policy that plans from it (greedy and ATA-HRL alike). Uses the observed S, its previous
    epoch and the allocation in force only."""

    def __init__(self, settings: None, mission: object):
        self.prev_robots: np.ndarray | None = None
        self.prev_tasks: np.ndarray | None = None

    @hookimpl
    def ata_reconstruct(self, sim: DecisionView, obs: Observation, inherent: Observation,
                        out: dict[str, np.ndarray]) -> None:
        rob, tasks = obs["robots"], obs["tasks"]
        guess = np.zeros(tasks.features.shape[:2], dtype=bool)
        if self.prev_robots is not None and sim.allocation is not None:
            t_col = rob.index("target")
            target = rob.features[..., t_col].astype(np.int64)
            before = self.prev_robots[..., t_col].astype(np.int64)
            fresh = (rob.features != self.prev_robots).any(-1) & (rob.col("working") > 0.5)
            moved_on = fresh & (before >= 0) & (target != before)
            b, r = np.nonzero(moved_on)
            p = before[b, r]
            still_its = sim.allocation.robot[b, p] == r
            guess[b[still_its], p[still_its]] = True
            maybe_stale = (tasks.features == self.prev_tasks).all(-1)
            guess &= maybe_stale & (tasks.col("unvisited") > 0.5)
        self.prev_robots = rob.features.copy()
        self.prev_tasks = tasks.features.copy()
        out["captured_guess"] = guess[..., None].astype(float)


@hookimpl
def ata_register_components(register) -> None:
    register("reconstructor", "identity", IdentityReconstructor)
    register("reconstructor", "arrivals", ArrivalReconstructor)
