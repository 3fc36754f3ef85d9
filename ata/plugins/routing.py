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
        fb, fr = np.nonzero(free)
        if fb.size == 0:
            return out
        # open: assigned to this robot, not captured, and no other robot heading there
        open_ = ~np.isfinite(t.capture_time[fb]) & (sim.allocation.robot[fb] == fr[:, None])
        tb, tr = np.nonzero(r.target >= 0)
        heading = np.zeros(t.capture_time.shape, dtype=bool)
        heading[tb, r.target[tb, tr]] = True
        open_ &= ~heading[fb]
        diff = t.pos[fb] - r.pos[fb, fr][:, None, :]                               # (n, P, 2)
        dist = np.where(open_, np.hypot(diff[..., 0], diff[..., 1]), np.inf)
        best = dist.argmin(axis=1)
        out[fb, fr] = np.where(open_.any(axis=1), best, -1)
        return out


@hookimpl
def ata_register_components(register) -> None:
    register("routing", "nearest", NearestRouting)
