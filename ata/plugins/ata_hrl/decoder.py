"""Capacity-aware decoding of an allocation, step by step, for the ITA policy and pi_TR.

POI after POI, in the order the policy sets (it points at the next POI among those left); within
a POI the robot, then the navigator, then the classifier, each choice conditioned on the ones
before it. After every choice the chosen members' dynamic keys are updated, as attention-model
decoders for capacitated routing do: the robot's projected free time and position, each human's
projected free time, booked work (hence fatigue) and busy intervals (hence utilisation), and,
when reallocating, who has been re-briefed. The masks follow: a robot that can reach nothing by
the horizon is done; only highly skilled humans navigate.

Everything the decoder computes comes from what a policy may read: the inherent information I,
the (reconstructed) observed state S and the model's tables, in expectation. For each candidate
it gives the network features (times, image quality, success probability with fatigue and
workload projected to the moment the work would start, expected points) and the score of the
greedy heuristic as a prior (greedy's own scorer, `ata.model.greedy_score`, in its compiled
scalar form `ata.model.scalar`: the rate of points per robot second, the net value of a
classifier), so that the network with its learned part switched off decodes like greedy. The
humans' projected load is the domain library's (`ata.model.load.HumanLoad`); the capture time
and the fatigue floor are the plan start's (what the team models published).

The four steps' inputs are computed by compiled loops over the episodes (`poi_step`,
`member_steps`), which give the bits the array formulation gave (tests/test_compiled_steps.py);
so are the commits and the replay of the kept POIs (`commit_step`); the start and the keep
step are numpy. A decode by the mode runs all of its steps in one compiled loop (`fused`).
"""

from __future__ import annotations

import copy

import numpy as np

from ata.core.state import Allocation
from ata.model import tables
from ata.model.load import BIN_S, HumanLoad
from ata.model.plan import PlanStart
from ata.model.tables import MAX_POINTS
from ata.plugins.ata_hrl.commit_step import commit_step, replay_step
from ata.plugins.ata_hrl.inputs import (CLS_FEATURES, NAV_FEATURES, POI_FEATURES,
                                        ROBOT_FEATURES, DecodeSettings, StepInputs)
from ata.plugins.ata_hrl.member_steps import cls_step, nav_step, robot_step
from ata.plugins.ata_hrl.poi_step import poi_step

__all__ = ["Decoder", "DecodeSettings", "StepInputs", "POI_FEATURES", "SHORTLIST"]

SHORTLIST = 48
"""The POI step weighs the POIs greedy's prior ranks among the 48 best of an episode: the shipped
networks chose none beyond the 46th (none beyond the 13th in (a)) in the POI steps counted, and
the learned part of a step stops growing with the POIs left."""


class Decoder:
    """The decoding state of E episodes (one allocation each) from a PlanStart.

    :param start: where the plan starts (`ata.model.plan.plan_start`).
    :param todo: (E, P) the POIs to decode; the others keep ``previous`` (or robot 0, auto,
        onboard when there is none).
    :param fatigue_now: (E, H) the fatigue estimate now (raw or reconstructed S), a feature;
        the plan projects fatigue forward with the start's belief (``start.belief``).
    :param util_now: (E, H) each human's utilisation over the trailing window now.
    :param previous: the allocation in force (reallocation), or None (initial allocation).
    """

    def __init__(self, start: PlanStart, todo: np.ndarray, fatigue_now: np.ndarray,
                 util_now: np.ndarray, settings: DecodeSettings,
                 previous: Allocation | None = None):
        s = self.s = settings
        self.start = start
        E, P = todo.shape
        H, R = start.eta.shape[1], start.speed.shape[1]
        self.E, self.P, self.H, self.R = E, P, H, R
        self.now, self.horizon = start.now, start.horizon
        self.e = np.arange(E)
        self.left = todo & start.open
        self.previous = previous
        if previous is not None:
            self.robot, self.nav, self.cls = (previous.robot.copy(), previous.navigator.copy(),
                                              previous.classifier.copy())
        else:
            self.robot = np.zeros((E, P), np.int64)
            self.nav = np.full((E, P), -1, np.int64)
            self.cls = np.full((E, P), -1, np.int64)
        self.robot_free = start.robot_free.copy()
        self.robot_xy = start.robot_xy.copy()
        self.robot_done = ~np.isfinite(self.robot_free)
        self.n_assigned = np.zeros((E, R))
        self.load = HumanLoad(start, fatigue_now, util_now, s.window_s)
        self.human_free = self.load.free          # the load's array, updated in place
        self.capture_s = start.capture_s
        self.touched = np.zeros((E, H), bool)
        # static per decode
        self.high = start.skill == 2
        self.points = start.points
        self.tx, self.ty = start.task_xy[..., 0], start.task_xy[..., 1]
        self.prev_valid = np.zeros((E, P), bool) if previous is None else \
            np.isfinite(np.take_along_axis(start.robot_free, previous.robot, axis=1))
        # every robot's expected points at every POI, onboard and autonomous (E, R, P)
        q_all = tables.QUALITY[start.robot_type[..., None], start.kind[:, None, :], 1]
        self._ev_onboard = tables.expected_points(self.points[:, None, :],
                                                  tables.P_RC[q_all, start.diff[:, None, :]])

    _ROWS = ("left", "robot", "nav", "cls", "robot_free", "robot_xy", "robot_done",
             "n_assigned", "touched", "high", "points", "tx", "ty", "prev_valid", "_ev_onboard")
    """The per-episode arrays beside the start, the load and the allocation in force."""

    @property
    def _dummy(self) -> np.ndarray:
        """An (E, P) index array standing for the allocation in force where there is none
        (the compiled steps take arrays, and read it only when there is one)."""
        return self.robot

    def take(self, rows: np.ndarray) -> "Decoder":
        """The decoding state of episodes `rows` alone, to go on decoding those (a copy)."""
        out = copy.copy(self)
        for name in self._ROWS:
            setattr(out, name, getattr(self, name)[rows])
        out.start, out.load = self.start.take(rows), self.load.take(rows)
        out.human_free = out.load.free
        out.previous = None if self.previous is None else self.previous.take(rows)
        out.E, out.e = rows.size, np.arange(rows.size)
        return out

    def put(self, into: "Decoder", rows: np.ndarray) -> None:
        """Write what this decoder (of `into`'s episodes `rows`) has decided into `into`."""
        for name in ("left", "robot", "nav", "cls", "robot_free"):
            getattr(into, name)[rows] = getattr(self, name)

    def replay(self, kept: np.ndarray, alloc: Allocation | None = None) -> None:
        """Book the POIs in `kept` (E, P) with their triples in `alloc` (default: the previous
        allocation), as the robots will visit them (the robot free first goes to its nearest
        kept POI), before any POI is decoded: the decoded POIs then follow the work the kept
        ones give the members."""
        prev = alloc if alloc is not None else self.previous
        left = kept & self.left
        owner = prev.robot
        left &= np.isfinite(np.take_along_axis(self.robot_free, owner, axis=1))
        s, load, st = self.s, self.load, self.start
        charge = self.previous is not None and s.rebrief_s > 0
        dummy = self._dummy
        work = [np.zeros(self.E, np.int64) for _ in range(4)]
        if replay_step(left, owner, prev.navigator, prev.classifier, self.tx, self.ty, *work,
                       self.left, self.robot_free, self.robot_xy, self.n_assigned, self.robot,
                       self.nav, self.cls, self.touched,
                       self.previous.navigator if charge else dummy,
                       self.previous.classifier if charge else dummy, charge, float(self.now),
                       float(s.rebrief_s), float(self.capture_s), st.speed, st.skill,
                       st.robot_type, st.kind, st.diff, st.task_xy, tables.TABLES, load.cum,
                       load.booked, load.free, load.edges):
            load.forget()
        self.left &= ~kept

    # -- sub-decisions ---------------------------------------------------------------------------
    def keep_inputs(self, expected: np.ndarray, finish: np.ndarray, changed: np.ndarray,
                    heuristic: Allocation) -> StepInputs:
        """Reallocation: for every POI to decide, one of three: decode it again (0), keep its
        triple (1), or take the triple of the greedy heuristic's reallocation (2). Features of
        the POI's expected outcome if kept (``expected`` points and ``finish`` time from the
        projection of the allocation in force), who holds it and how loaded they are, whether
        its robot is down or its kind or difficulty `changed` since it was planned, and whether
        greedy changes it. The prior follows greedy's keep-or-repair reallocation: keep (+1)
        where greedy keeps; where greedy changes the POI, decode it again (+1), with greedy's
        triple as the other choice (0). Keeping is masked where the robot is down; greedy's
        triple where it keeps (it is the same as keeping) or names a robot that is down."""
        E, P = self.E, self.P
        prev, hz = self.previous, self.horizon
        heuristic_keeps = (heuristic.stack() == prev.stack()).all(-1)
        cls_h = np.maximum(prev.classifier, 0)
        by_human = prev.classifier >= 0
        util = np.take_along_axis(self.load.util_now, cls_h, axis=1)
        fat = np.take_along_axis(self.load.fatigue_now, cls_h, axis=1)
        load = np.zeros((E, self.R))
        lb, lp = np.nonzero(self.left)
        np.add.at(load, (lb, prev.robot[lb, lp]), 1.0)
        held = np.take_along_axis(load, prev.robot, axis=1)
        feats = np.stack([self.prev_valid.astype(float), expected / MAX_POINTS,
                          np.clip((finish - self.now) / hz, 0, 2),
                          by_human.astype(float), (prev.navigator >= 0).astype(float),
                          np.where(by_human, util, 0.0), np.where(by_human, fat, 1.0),
                          changed.astype(float), self.points / MAX_POINTS,
                          np.full((E, P), (hz - self.now) / hz), held / max(P, 1),
                          np.isfinite(finish).astype(float), heuristic_keeps.astype(float)], -1)
        heuristic_ok = np.isfinite(np.take_along_axis(self.robot_free, heuristic.robot, axis=1))
        mask = np.stack([self.left, self.left & self.prev_valid,
                         self.left & ~heuristic_keeps & heuristic_ok], -1)
        prior = np.stack([np.where(heuristic_keeps, -1.0, 1.0),
                          np.where(heuristic_keeps, 1.0, -1.0), np.zeros((E, P))], -1)
        return StepInputs(feats.astype(np.float32), mask, prior, self.left.any(1))

    def poi_inputs(self) -> StepInputs:
        """Which POI next: features relative to the robot free first (the greedy robot). They
        are computed for the legal (episode, POI) pairs alone: those left that some robot
        reaches by the horizon and that greedy's prior ranks on the episode's shortlist (its
        `SHORTLIST` best, ties included); the others' logits are masked, and their features
        are zero. The features: the arrival of the robot free first, alone and with the first
        free highly skilled navigator (as greedy), the expected points onboard and of the best
        human (workload and fatigue projected to the item's start) for both, greedy's rate of
        both, how much sooner and how much better onboard another robot gets there, the POI's
        points, kind and difficulty, the robot's time left, the share of POIs left, and, when
        reallocating, whether the POI's robot, validity and classifier stay. Compiled
        (`poi_step`), one loop over the (episode, POI) pairs."""
        E, P, s, st = self.E, self.P, self.s, self.start
        feats = np.zeros((E, P, POI_FEATURES), np.float32)
        mask = np.zeros((E, P), bool)
        prior = np.full((E, P), -1.0)
        self.r_ff = np.zeros(E, np.int64)
        prev = self.previous
        load = self.load
        poi_step(self.left, self.robot_free, self.robot_done, self.robot_xy, st.speed,
                 self.tx, self.ty, st.robot_type, st.kind, st.diff, self.points,
                 self.human_free, self.high, load.fatigue_greedy(), load.fatigue_at(),
                 load.eta_lam, load.cum.reshape(-1), load.edges.size, float(load.edges[-1]),
                 BIN_S, self._ev_onboard, prev is not None,
                 self._dummy if prev is None else prev.robot,
                 self._dummy if prev is None else prev.classifier, self.prev_valid,
                 float(self.now), float(self.horizon), float(self.capture_s), s.window_s,
                 s.human_time_cost, s.rate_offset_s, float(tables.SKILL_SPEED[2]), SHORTLIST,
                 MAX_POINTS, tables.TABLES, feats, mask, prior, self.r_ff)
        return StepInputs(feats, mask, prior, mask.any(axis=1))

    def robot_inputs(self, p: np.ndarray) -> StepInputs:
        """Which robot for POI p: features of each robot's arrival, when it is free, its
        travel, its expected points onboard, whether it is the robot free first (the prior),
        its share of the POIs assigned, whether it holds the POI in the allocation in force,
        its type and the image quality. Compiled (`member_steps.robot_step`)."""
        E, R, st = self.E, self.R, self.start
        feats = np.empty((E, R, ROBOT_FEATURES), np.float32)
        mask = np.empty((E, R), bool)
        prior = np.empty((E, R))
        prev = self.previous
        robot_step(p, self.robot_free, self.robot_done, self.robot_xy, st.speed, self.tx,
                   self.ty, st.robot_type, st.kind, st.diff, self.points, self.r_ff,
                   self.n_assigned, prev is not None, self._dummy if prev is None else prev.robot,
                   self.P, float(self.now), float(self.horizon), float(self.capture_s),
                   MAX_POINTS, tables.TABLES, feats, mask, prior)
        return StepInputs(feats, mask, prior, mask.any(1))

    def nav_inputs(self, p: np.ndarray, r: np.ndarray) -> StepInputs:
        """Who drives robot r to POI p: autonomous (0), or one highly skilled human (h + 1).
        Features of each option's arrival, the wait for the navigator, the leg, the expected
        points onboard, greedy's rate (the prior; F_w = 1, the best human classifier at that
        quality), the navigator's utilisation, whether it navigates in the allocation in force,
        and the image quality. Compiled (`member_steps.nav_step`)."""
        E, H, s, st, load = self.E, self.H, self.s, self.start, self.load
        feats = np.empty((E, H + 1, NAV_FEATURES), np.float32)
        mask = np.empty((E, H + 1), bool)
        prior = np.empty((E, H + 1))
        prev = self.previous
        nav_step(p, r, self.robot_free, self.robot_xy, st.speed, self.tx, self.ty,
                 st.robot_type, st.kind, st.diff, self.points, st.skill, self.high,
                 self.human_free, load.eta_lam, load.fatigue_greedy(), load.cum.reshape(-1),
                 load.edges.size, float(load.edges[-1]), BIN_S, prev is not None,
                 self._dummy if prev is None else prev.navigator, float(self.now),
                 float(self.horizon), float(self.capture_s), s.window_s, s.human_time_cost,
                 s.rate_offset_s, MAX_POINTS, tables.TABLES, feats, mask, prior)
        return StepInputs(feats, mask, prior, np.ones(E, bool))

    def cls_inputs(self, p: np.ndarray, r: np.ndarray, n: np.ndarray) -> StepInputs:
        """Who classifies POI p's image: onboard (0) or a human (h + 1). Features of each
        option's expected points, success probability, finish, the wait before the item
        starts, the human's projected utilisation, F_w and F_f at that start, the item's
        length, greedy's net value (the prior beside onboard's expected points), whether the
        human would be re-briefed, whether it classifies in the allocation in force, and the
        image quality. The navigator is busy until the capture: for it the item starts then
        at the earliest. Compiled (`member_steps.cls_step`)."""
        E, H, s, st, load = self.E, self.H, self.s, self.start, self.load
        feats = np.empty((E, H + 1, CLS_FEATURES), np.float32)
        prior = np.empty((E, H + 1))
        prev = self.previous
        cls_step(p, r, n, self.robot_free, self.robot_xy, st.speed, self.tx, self.ty,
                 st.robot_type, st.kind, st.diff, self.points, st.skill, self.human_free,
                 load.eta_lam, load.fatigue_greedy(), load.fatigue_at(), self.touched,
                 load.cum.reshape(-1), load.edges.size, float(load.edges[-1]), BIN_S,
                 prev is not None, self._dummy if prev is None else prev.classifier,
                 s.rebrief_s > 0, float(self.now), float(self.horizon), float(self.capture_s),
                 s.window_s, s.human_time_cost, MAX_POINTS, tables.TABLES, feats, prior)
        return StepInputs(feats, np.ones((E, H + 1), bool), prior, np.ones(E, bool))

    # -- commit ----------------------------------------------------------------------------------
    def commit(self, active: np.ndarray, p: np.ndarray, r: np.ndarray, n: np.ndarray,
               c: np.ndarray) -> None:
        """Give POI p (robot r, navigator n, classifier c; -1 auto / onboard) in the active
        episodes, and update the members' projected state: re-brief (with an allocation in
        force) every human whose work this choice first changes; the robot sets off when it
        and its navigator are free, books the navigator over its leg and the classifier from
        the capture (or from when they are free) for T_bar; the robot's free time and place
        move to the POI's capture."""
        s, load, st = self.s, self.load, self.start
        prev = self.previous
        charge = prev is not None and s.rebrief_s > 0
        dummy = self._dummy
        if commit_step(active, p, r, n, c, self.robot_free, self.robot_xy, self.n_assigned,
                       self.robot, self.nav, self.cls, self.left, self.touched,
                       prev.navigator if charge else dummy,
                       prev.classifier if charge else dummy, charge, float(self.now),
                       float(s.rebrief_s), float(self.capture_s), st.speed, st.skill,
                       st.robot_type, st.kind, st.diff, st.task_xy, tables.TABLES,
                       load.cum, load.booked, load.free, load.edges):
            load.forget()

    def finish(self) -> Allocation:
        """The allocation: POIs nobody could reach go, as greedy's leftovers do, to the robot
        whose plan ends first, autonomous and onboard."""
        left = self.left
        if left.any():
            lb, lp = np.nonzero(left)
            free = np.where(self.robot_done, np.inf, self.robot_free)
            fallback = np.where(np.isfinite(free).any(1), free.argmin(1), 0)
            keep = self.prev_valid[lb, lp] if self.previous is not None else np.zeros(lb.size,
                                                                                      bool)
            self.robot[lb, lp] = np.where(keep, self.robot[lb, lp], fallback[lb])
            self.nav[lb, lp] = np.where(keep, self.nav[lb, lp], -1)
            self.cls[lb, lp] = np.where(keep, self.cls[lb, lp], -1)
        return Allocation(self.robot.copy(), self.nav.copy(), self.cls.copy())
