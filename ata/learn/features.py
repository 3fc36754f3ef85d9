"""Observations to tensors: per-entity feature vectors for the networks of ATA-HRL.

Inherent information I: humans (eta, lambda, skill one-hot), robots (UAV, UGV, speed / 8),
tasks (x, y, kind, difficulty one-hot, points / 35). Dynamic state S: humans (working hours / 3,
fatigue, idleness, SA), robots (x, y, idleness, working, has a target), tasks (unvisited,
captured, classified, kind, difficulty one-hot). Masks mark real entities.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from ata.core.state import Observation

I_DIMS = {"humans": 5, "robots": 3, "tasks": 7}
S_DIMS = {"humans": 4, "robots": 5, "tasks": 7}
GROUPS = ("humans", "robots", "tasks")


def _onehot3(x: np.ndarray) -> np.ndarray:
    return np.eye(3)[np.clip(np.rint(x).astype(np.int64), 0, 2)]


def inherent_features(I: Observation) -> dict[str, np.ndarray]:
    h, r, t = I["humans"], I["robots"], I["tasks"]
    return {
        "humans": np.concatenate([np.stack([h.col("cognitive"), h.col("expertise")], -1),
                                  _onehot3(h.col("skill"))], -1),
        "robots": np.stack([r.col("uav"), r.col("ugv"), r.col("speed") / 8.0], -1),
        "tasks": np.concatenate([np.stack([t.col("x"), t.col("y"), t.col("kind")], -1),
                                 _onehot3(t.col("difficulty")),
                                 (t.col("points") / 35.0)[..., None]], -1),
    }


def state_features(S: Observation, fatigue: np.ndarray | None = None) -> dict[str, np.ndarray]:
    """S as features; `fatigue` (B, H) replaces the observed fatigue column when given."""
    h, r, t = S["humans"], S["robots"], S["tasks"]
    f = h.col("fatigue") if fatigue is None else fatigue
    return {
        "humans": np.stack([h.col("working_time") / 3.0, f, h.col("idleness"), h.col("sa")], -1),
        "robots": np.stack([r.col("x"), r.col("y"), r.col("idleness"), r.col("working"),
                            (r.col("target") >= 0).astype(float)], -1),
        "tasks": np.concatenate([np.stack([t.col("unvisited"), t.col("captured"),
                                           t.col("classified"), t.col("kind")], -1),
                                 _onehot3(t.col("difficulty"))], -1),
    }


def to_tensors(feats: dict[str, np.ndarray]) -> dict[str, torch.Tensor]:
    return {k: torch.as_tensor(v, dtype=torch.float32) for k, v in feats.items()}


@dataclass
class Masks:
    """Which choices are legal, as bool tensors."""

    robot: torch.Tensor        # (B, R) robots that may take POIs
    human: torch.Tensor        # (B, H) humans that may navigate or classify
    navigator: torch.Tensor    # (B, H) humans that may navigate (highly skilled only)


def masks_for(I: Observation, S: Observation | None, nav_high_only: bool = True) -> Masks:
    skill = I["humans"].col("skill")
    B, H = skill.shape
    robot_ok = np.ones(I["robots"].features.shape[:2], dtype=bool)
    if S is not None:
        robot_ok &= S["robots"].col("working") > 0.5
    robot_ok[~robot_ok.any(axis=1)] = True      # no working robot seen: leave all choosable
    nav_ok = skill > 1.5 if nav_high_only else np.ones((B, H), dtype=bool)
    return Masks(robot=torch.as_tensor(robot_ok), human=torch.ones((B, H), dtype=torch.bool),
                 navigator=torch.as_tensor(nav_ok))
