"""The POI task model: positions, kinds, difficulties, points, status, scoring and the bound U.

Group ``tasks`` holds, per scenario and POI: ``pos`` (m), ``est_kind``/``est_diff`` (the
satellite estimate), ``true_kind``/``true_diff``, ``reveal_time`` (when a changed attribute
shows), ``capture_time``, ``quality`` (of the captured image), ``cls_ready`` (when it waits for a
human classifier), ``classified_at`` and ``gain`` (points won or lost), ``expected_gain`` (the
points it expected, given its success probability), and ``outcome_u`` (the pre-drawn uniform that
decides the classification's success).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ata import hookimpl
from ata.core.settings import param
from ata.core.state import Observation, SimState
from ata.plugins import tables

TASK_INHERENT = ("x", "y", "kind", "difficulty", "points")
TASK_STATE = ("unvisited", "captured", "classified", "kind", "difficulty")


class PoiTaskModel:
    """POIs uniform over the area, kinds and difficulties as in MODEL.md section 1."""

    @dataclass
    class Settings:
        area_m: float = param(2000.0, min=1.0, help="side of the square area in metres")
        air_fraction: float = param(0.5, min=0.0, max=1.0, help="share of air POIs")

    def __init__(self, settings: "PoiTaskModel.Settings", mission: object):
        self.settings = settings

    @hookimpl
    def ata_setup(self, sim: SimState) -> None:
        B, P = sim.batch_size, sim.sizes.tasks
        rng, s = sim.rng, self.settings
        t = sim.group("tasks")
        t.area_m = s.area_m
        t.pos = rng.uniform("tasks.pos", 0, (P, 2)) * s.area_m
        t.est_kind = np.where(rng.uniform("tasks.kind", 0, (P,)) < s.air_fraction,
                              tables.AIR, tables.GROUND).astype(np.int64)
        t.est_diff = rng.integers("tasks.difficulty", 0, 3, (P,))
        t.true_kind = t.est_kind.copy()
        t.true_diff = t.est_diff.copy()
        t.reveal_time = np.full((B, P), np.inf)
        t.capture_time = np.full((B, P), np.inf)
        t.quality = np.full((B, P), -1, dtype=np.int64)
        t.cls_ready = np.full((B, P), np.inf)
        t.classified_at = np.full((B, P), np.inf)
        t.gain = np.zeros((B, P))
        t.expected_gain = np.zeros((B, P))
        t.outcome_u = rng.uniform("tasks.outcome", 0, (P,))

    @hookimpl
    def ata_inherent(self, sim: SimState, inherent: Observation) -> None:
        t = sim.group("tasks")
        feats = np.stack([t.pos[..., 0] / t.area_m, t.pos[..., 1] / t.area_m,
                          t.est_kind, t.est_diff, tables.POINTS[t.est_diff]], axis=-1)
        inherent.add("tasks", TASK_INHERENT, feats.astype(np.float64))
        inherent.extras["area_m"] = np.full(sim.batch_size, t.area_m)

    @hookimpl
    def ata_observe(self, sim: SimState, obs: Observation) -> None:
        t, now = sim.group("tasks"), sim.now
        captured = t.capture_time <= now
        classified = t.classified_at <= now
        revealed = (t.reveal_time <= now) | captured
        feats = np.stack([~captured, captured & ~classified, classified,
                          np.where(revealed, t.true_kind, t.est_kind),
                          np.where(revealed, t.true_diff, t.est_diff)], axis=-1)
        obs.add("tasks", TASK_STATE, feats.astype(np.float64))
        obs.restrict_reallocation(~captured)

    @hookimpl
    def ata_epoch_end(self, sim: SimState, epoch: int) -> None:
        t, clock = sim.group("tasks"), sim.clock
        start, end = epoch * clock.epoch_s, (epoch + 1) * clock.epoch_s
        done = (t.classified_at >= start) & (t.classified_at < end)
        sim.record.r_perf[:, epoch] = np.where(done, t.gain, 0.0).sum(axis=1)
        sim.record.r_expected[:, epoch] = np.where(done, t.expected_gain, 0.0).sum(axis=1)

    @hookimpl
    def ata_episode_end(self, sim: SimState) -> None:
        t = sim.group("tasks")
        sim.record.upper_bound[:] = upper_bound(sim)
        classified = t.classified_at < sim.clock.horizon_s
        sim.record.task_gain = np.where(classified, t.gain, 0.0)
        sim.record.task_epoch = np.where(classified, np.floor(t.classified_at / sim.clock.epoch_s),
                                         -1).astype(np.int64)
        sim.record.metrics["classified_share"] = classified.mean(axis=1)
        sim.record.metrics["correct_share"] = np.where(classified, t.gain > 0, False).sum(1) \
            / np.maximum(classified.sum(1), 1)


def upper_bound(sim: SimState) -> np.ndarray:
    """U = sum_p max(0, points_p (2 P*_p - 1)), MODEL.md section 8.

    P*_p is the best success probability any member could reach on p's true attributes with
    F_f = F_w = 1: the best image quality any robot reaches there (auto, or under the team's most
    skilled navigator), classified onboard or by the best human.
    """
    t, h, r = sim.group("tasks"), sim.group("humans"), sim.group("robots")
    best_nav = np.maximum(h.skill.max(axis=1), 1)                         # (B,): auto is class 1
    # best quality per (scenario, robot) on each POI: (B, R, P)
    q = tables.QUALITY[r.type[:, :, None], t.true_kind[:, None, :], best_nav[:, None, None]]
    q_best = q.max(axis=1)                                                 # (B, P)
    d = t.true_diff
    p_robot = tables.P_RC[q_best, d]
    eta_lam = (h.eta * h.lam).max(axis=1)                                  # (B,)
    p_human = 0.5 + eta_lam[:, None] * tables.F_D[q_best, d]
    p_star = np.maximum(p_robot, p_human)
    return np.maximum(0.0, tables.expected_points(tables.POINTS[d], p_star)).sum(axis=1)


@hookimpl
def ata_register_components(register) -> None:
    register("task_model", "poi", PoiTaskModel)
