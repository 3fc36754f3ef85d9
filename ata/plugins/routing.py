"""Routing: the order in which a robot visits its POIs, a setting of the robot model
(``[robot] routing``). Each routing is a function ``(sim, free) -> (B, R) int``: each free
robot's next POI, -1 for none."""

from __future__ import annotations

from typing import Callable

import numpy as np

from ata.core.state import SimState


def nearest(sim: SimState, free: np.ndarray) -> np.ndarray:
    """MODEL.md section 3: a free robot goes to its closest assigned, not yet visited POI that no
    other robot is heading for, from where it is."""
    r, t = sim.group("robots"), sim.group("tasks")
    out = np.full(free.shape, -1, dtype=np.int64)
    fb, fr = np.nonzero(free)
    if fb.size == 0:
        return out
    # open: assigned to this robot, not captured, and no other robot heading there
    open_ = ~r.visited[fb] & (sim.allocation.robot[fb] == fr[:, None])
    tb, tr = np.nonzero(r.target >= 0)
    heading = np.zeros(r.visited.shape, dtype=bool)
    heading[tb, r.target[tb, tr]] = True
    open_ &= ~heading[fb]
    diff = t.pos[fb] - r.pos[fb, fr][:, None, :]                               # (n, P, 2)
    dist = np.where(open_, np.hypot(diff[..., 0], diff[..., 1]), np.inf)
    best = dist.argmin(axis=1)
    out[fb, fr] = np.where(open_.any(axis=1), best, -1)
    return out


ROUTINGS: dict[str, Callable[[SimState, np.ndarray], np.ndarray]] = {"nearest": nearest}
"""The routings the robot model's ``routing`` setting may name."""
