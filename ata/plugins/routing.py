"""Nearest-neighbour routing: a free robot goes to its closest assigned, not yet visited POI."""

from __future__ import annotations

import numpy as np

from ata import hookimpl
from ata.core.state import SimState


class NearestRouting:
    """MODEL.md section 3: nearest-neighbour order from where the robot is."""

    def __init__(self, settings: None, mission: object):
        pass

    @hookimpl
    def ata_next_targets(self, sim: SimState, free: np.ndarray) -> np.ndarray:
        r, t = sim.group("robots"), sim.group("tasks")
        out = np.full(free.shape, -1, dtype=np.int64)
        rows = np.nonzero(free.any(axis=1))[0]
        if rows.size == 0:
            return out
        robot_of = sim.allocation.robot[rows]                                    # (b, P)
        open_ = ~np.isfinite(t.capture_time[rows])                               # (b, P)
        # POIs another robot is already heading to are not open
        targeted = np.zeros_like(open_)
        tb, tr = np.nonzero(r.target[rows] >= 0)
        targeted[tb, r.target[rows][tb, tr]] = True
        open_ &= ~targeted
        R = free.shape[1]
        mine = (robot_of[:, None, :] == np.arange(R)[None, :, None]) & open_[:, None, :]
        mine &= free[rows][:, :, None]
        diff = t.pos[rows][:, None, :, :] - r.pos[rows][:, :, None, :]            # (b, R, P, 2)
        dist = np.where(mine, np.hypot(diff[..., 0], diff[..., 1]), np.inf)
        best = dist.argmin(axis=2)
        out[rows] = np.where(np.isfinite(dist.min(axis=2)), best, -1)
        return out


@hookimpl
def ata_register_components(register) -> None:
    register("routing", "nearest", NearestRouting)
