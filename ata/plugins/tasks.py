"""The POI task model: positions, kinds, difficulties, points, status, scoring and the bound U.

It owns group ``tasks`` (`TaskState`) and scores every classification: its success is decided
here, by the POI's pre-drawn uniform against the success probability of whoever classified it.
Work reaches it through queues (docs/model.md: "The allocation", "Robots", "Humans", "Uncertainty"):

* ``tasks.captured`` (from the robot model): ``b, p, time, quality, robot, classifier``. An
  onboard classification is scored at once (P_rc); one for a human goes on to
  ``humans.classify``.
* ``tasks.classified`` (from the human model): ``b, p, time, p_ok``, a human's classification.
* ``tasks.attribute_change`` (from a perturbation, at set-up): ``b, p, kind, difficulty, reveal``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ata import hookimpl
from ata.core.settings import param
from ata.core.queues import scatter
from ata.core.state import Observation, SimState
from ata.model import tables

TASK_INHERENT = ("x", "y", "kind", "difficulty", "points")
TASK_STATE = ("unvisited", "captured", "classified", "kind", "difficulty")


@dataclass
class TaskState:
    """Per scenario and POI, (B, P) unless said."""

    area_m: float                 # side of the square area
    pos: np.ndarray               # (B, P, 2) m
    est_kind: np.ndarray          # the satellite estimate (AIR / GROUND)
    est_diff: np.ndarray          # estimated difficulty 0..2
    true_kind: np.ndarray
    true_diff: np.ndarray
    reveal_time: np.ndarray       # when a changed attribute shows (inf: never changed)
    outcome_u: np.ndarray         # the pre-drawn uniform that decides the classification
    capture_time: np.ndarray      # inf until captured
    quality: np.ndarray           # of the captured image (-1 until captured)
    classified_at: np.ndarray     # inf until classified
    gain: np.ndarray              # points won or lost
    expected_gain: np.ndarray     # the points expected, given the success probability


class PoiTaskModel:
    """POIs uniform over the area, kinds and difficulties as in docs/model.md, "World and team"."""

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
        est_kind = np.where(rng.uniform("tasks.kind", 0, (P,)) < s.air_fraction,
                            tables.AIR, tables.GROUND).astype(np.int64)
        est_diff = rng.integers("tasks.difficulty", 0, 3, (P,))
        self.state = sim.own("tasks", TaskState(
            area_m=s.area_m, pos=rng.uniform("tasks.pos", 0, (P, 2)) * s.area_m,
            est_kind=est_kind, est_diff=est_diff, true_kind=est_kind.copy(),
            true_diff=est_diff.copy(), reveal_time=np.full((B, P), np.inf),
            outcome_u=rng.uniform("tasks.outcome", 0, (P,)),
            capture_time=np.full((B, P), np.inf), quality=np.full((B, P), -1, dtype=np.int64),
            classified_at=np.full((B, P), np.inf), gain=np.zeros((B, P)),
            expected_gain=np.zeros((B, P))))

    def _take_work(self, sim: SimState) -> None:
        """Apply what the queues hold: attribute changes, captures, human classifications."""
        t = self.state
        changes = sim.queue("tasks.attribute_change").take()
        if changes is not None:
            scatter(t, changes, ("b", "p"), {"true_kind": "kind", "true_diff": "difficulty",
                                             "reveal_time": "reveal"})
        captured = sim.queue("tasks.captured").take()
        if captured is not None:
            b, p, te, q = captured["b"], captured["p"], captured["time"], captured["quality"]
            t.capture_time[b, p] = te
            t.quality[b, p] = q
            onboard = captured["classifier"] < 0
            if onboard.any():
                ob, op = b[onboard], p[onboard]
                self._score(ob, op, te[onboard], tables.P_RC[q[onboard], t.true_diff[ob, op]])
            human = ~onboard
            if human.any():
                hb, hp = b[human], p[human]
                sim.queue("humans.classify").put(
                    b=hb, p=hp, ready=te[human], human=captured["classifier"][human],
                    robot=captured["robot"][human], quality=q[human],
                    difficulty=t.true_diff[hb, hp])
        classified = sim.queue("tasks.classified").take()
        if classified is not None:
            self._score(classified["b"], classified["p"], classified["time"],
                        classified["p_ok"])

    def _score(self, b: np.ndarray, p: np.ndarray, time: np.ndarray, p_ok: np.ndarray) -> None:
        """A classification of POI p at `time` that succeeds with probability p_ok."""
        t = self.state
        points = tables.POINTS[t.true_diff[b, p]]
        t.classified_at[b, p] = time
        t.gain[b, p] = np.where(t.outcome_u[b, p] < p_ok, points, -points)
        t.expected_gain[b, p] = tables.expected_points(points, p_ok)

    @hookimpl
    def ata_advance(self, sim: SimState, t0: float, t1: float) -> None:
        self._take_work(sim)

    @hookimpl
    def ata_inherent(self, sim: SimState, inherent: Observation) -> None:
        self._take_work(sim)
        t = self.state
        feats = np.stack([t.pos[..., 0] / t.area_m, t.pos[..., 1] / t.area_m,
                          t.est_kind, t.est_diff, tables.POINTS[t.est_diff]], axis=-1)
        inherent.add("tasks", TASK_INHERENT, feats.astype(np.float64))
        inherent.extras["area_m"] = np.full(sim.batch_size, t.area_m)

    @hookimpl
    def ata_observe(self, sim: SimState, obs: Observation) -> None:
        self._take_work(sim)
        t, now = self.state, sim.now
        captured = t.capture_time <= now
        classified = t.classified_at <= now
        revealed = (t.reveal_time <= now) | captured
        feats = np.stack([~captured, captured & ~classified, classified,
                          np.where(revealed, t.true_kind, t.est_kind),
                          np.where(revealed, t.true_diff, t.est_diff)], axis=-1)
        obs.add("tasks", TASK_STATE, feats.astype(np.float64))
        # a captured POI's own row holds it: its triple may no longer change
        obs.hold("tasks", np.where(captured, np.arange(sim.sizes.tasks), -1), sim.sizes.tasks)

    @hookimpl
    def ata_epoch_end(self, sim: SimState, epoch: int) -> None:
        self._take_work(sim)
        t, clock = self.state, sim.clock
        start, end = epoch * clock.epoch_s, (epoch + 1) * clock.epoch_s
        done = (t.classified_at >= start) & (t.classified_at < end)
        sim.record.r_perf[:, epoch] = np.where(done, t.gain, 0.0).sum(axis=1)
        sim.record.r_expected[:, epoch] = np.where(done, t.expected_gain, 0.0).sum(axis=1)

    @hookimpl
    def ata_episode_end(self, sim: SimState) -> None:
        self._take_work(sim)
        t = self.state
        sim.record.upper_bound[:] = upper_bound(sim)
        classified = t.classified_at < sim.clock.horizon_s
        sim.record.task_gain = np.where(classified, t.gain, 0.0)
        sim.record.task_epoch = np.where(classified, np.floor(t.classified_at / sim.clock.epoch_s),
                                         -1).astype(np.int64)
        sim.record.metrics["classified_share"] = classified.mean(axis=1)
        sim.record.metrics["correct_share"] = np.where(classified, t.gain > 0, False).sum(1) \
            / np.maximum(classified.sum(1), 1)
        # the score in expectation over the classification outcomes (each classification's
        # expected points given how it was made): the same episode, without the outcome draws'
        # noise, so comparisons of methods need far fewer scenarios
        sim.record.metrics["expected_score"] = sim.record.r_expected.sum(axis=1)


def upper_bound(sim: SimState) -> np.ndarray:
    """U = sum_p max(0, points_p (2 P*_p - 1)), docs/methods.md, "Methods compared".

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
    p_human = tables.human_success(eta_lam[:, None], 1.0, 1.0, 1.0, tables.F_D[q_best, d])
    p_star = np.maximum(p_robot, p_human)
    return np.maximum(0.0, tables.expected_points(tables.POINTS[d], p_star)).sum(axis=1)


@hookimpl
def ata_register_components(register) -> None:
    register("task_model", "poi", PoiTaskModel)
