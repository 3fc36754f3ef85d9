"""Observations to the inputs of ATA-HRL's networks and decoder.

Encoder tokens: the inherent information I (humans: eta, lambda, skill one-hot; robots: UAV, UGV,
speed / 8, a UAV's speed; tasks: x, y, kind, difficulty one-hot, points / 35, the most a POI is
worth) and, when reallocating, the state S as the policy sees it (`STATE_COLUMNS`: humans:
working hours / 3, fatigue, idleness, SA; robots: x, y, idleness, working, has a target; tasks:
unvisited, captured, classified, kind, difficulty one-hot).

"As the policy sees it": the raw observed S, or, where the mission's reconstructors give them,
their estimates (the ``aux`` reconstructor's fatigue, robot and task rows). The w/o.AUX ablation
is the same code reading the raw S.
"""

from __future__ import annotations

import numpy as np

from ata.core.state import DecisionContext, Observation
from ata.model.tables import MAX_POINTS
from ata.model.team import UAV_SPEED

GROUPS = ("humans", "robots", "tasks")


def onehot3(x: np.ndarray) -> np.ndarray:
    return np.eye(3)[np.clip(np.rint(x).astype(np.int64), 0, 2)]


def inherent_features(I: Observation) -> dict[str, np.ndarray]:
    h, r, t = I["humans"], I["robots"], I["tasks"]
    return {
        "humans": np.concatenate([np.stack([h.col("cognitive"), h.col("expertise")], -1),
                                  onehot3(h.col("skill"))], -1),
        "robots": np.stack([r.col("uav"), r.col("ugv"), r.col("speed") / UAV_SPEED], -1),
        "tasks": np.concatenate([np.stack([t.col("x"), t.col("y"), t.col("kind")], -1),
                                 onehot3(t.col("difficulty")),
                                 (t.col("points") / MAX_POINTS)[..., None]], -1),
    }


HOURS_UNIT = 3.0
"""`state_features` gives a human's working time in units of this many hours."""

STATE_COLUMNS = {
    "humans": ("working_time", "fatigue", "idleness", "sa"),
    "robots": ("x", "y", "idleness", "working", "has_target"),
    "tasks": ("unvisited", "captured", "classified", "kind", "difficulty_low",
              "difficulty_medium", "difficulty_high"),
}
"""The columns of `state_features`, by group, in order (working_time in `HOURS_UNIT`s)."""


def state_column(feats: dict[str, np.ndarray], group: str, name: str) -> np.ndarray:
    """Column `name` of `group` in features laid out as `state_features` lays them out (the
    raw S's, or a reconstructor's estimate in the same space)."""
    return feats[group][..., STATE_COLUMNS[group].index(name)]


def state_features(S: Observation, fatigue: np.ndarray | None = None) -> dict[str, np.ndarray]:
    """S as features (the columns of `STATE_COLUMNS`); `fatigue` (B, H) replaces the observed
    fatigue column when given."""
    h, r, t = S["humans"], S["robots"], S["tasks"]
    f = h.col("fatigue") if fatigue is None else fatigue
    return {
        "humans": np.stack([h.col("working_time") / HOURS_UNIT, f, h.col("idleness"),
                            h.col("sa")], -1),
        "robots": np.stack([r.col("x"), r.col("y"), r.col("idleness"), r.col("working"),
                            (r.col("target") >= 0).astype(float)], -1),
        "tasks": np.concatenate([np.stack([t.col("unvisited"), t.col("captured"),
                                           t.col("classified"), t.col("kind")], -1),
                                 onehot3(t.col("difficulty"))], -1),
    }


def seen_state(ctx: DecisionContext) -> dict[str, np.ndarray]:
    """S as the policy sees it: the reconstructors' estimates where present, else the raw S."""
    rec = ctx.reconstructed
    feats = state_features(ctx.observed, fatigue=rec.get("aux_fatigue"))
    for group in ("robots", "tasks"):
        if f"aux_{group}" in rec:
            feats[group] = rec[f"aux_{group}"]
    return feats


def equal_runs(feats: dict[str, np.ndarray]) -> np.ndarray | None:
    """The first episode of each run of equal consecutive episodes of `feats` (a training
    step's samples of one scenario share its I), or None where no two consecutive episodes are
    equal (an evaluation's batch): what an encoder need read once."""
    E = feats["tasks"].shape[0]
    same = np.ones(max(E - 1, 0), bool)
    if E > 1:
        for v in feats.values():
            same &= (v[1:] == v[:-1]).reshape(E - 1, -1).all(1)
    if not same.any():
        return None
    return np.flatnonzero(np.concatenate([[True], ~same]))
