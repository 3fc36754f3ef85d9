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
greedy heuristic as a prior (greedy's own scorer, `ata.model.greedy_score`: the rate of points
per robot second, the net value of a classifier), so that the network with its learned part
switched off decodes like greedy. The humans' projected load is the domain library's
(`ata.model.load.HumanLoad`); the capture time and the fatigue floor are the plan start's (what
the team models published).
"""

from __future__ import annotations

import copy

import numpy as np

from ata.core.state import Allocation
from ata.model import greedy_score, tables
from ata.model.load import HumanLoad
from ata.model.plan import PlanStart
from ata.model.tables import MAX_POINTS
from ata.plugins.ata_hrl.inputs import (CLS_FEATURES, NAV_FEATURES, POI_FEATURES,
                                        ROBOT_FEATURES, DecodeSettings, StepInputs, _fill,
                                        _quiet)

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
        E, R = self.E, self.R
        for _ in range(self.P):
            has = np.zeros((E, R), dtype=bool)
            lb, lp = np.nonzero(left)
            if lb.size == 0:
                break
            has[lb, owner[lb, lp]] = True
            rs = np.where(has, self.robot_free, np.inf).argmin(axis=1)
            act = has.any(axis=1)
            gx = self.tx - self.robot_xy[self.e, rs, 0][:, None]
            gy = self.ty - self.robot_xy[self.e, rs, 1][:, None]
            dist = np.where(left & (owner == rs[:, None]), gx * gx + gy * gy, np.inf)
            p = dist.argmin(axis=1)
            self.commit(act, p, rs, prev.navigator[self.e, p], prev.classifier[self.e, p])
            left[self.e[act], p[act]] = False
        self.left &= ~kept

    # -- projections -----------------------------------------------------------------------------
    def _book(self, e: np.ndarray, h: np.ndarray, a: np.ndarray, b: np.ndarray) -> None:
        self.load.book(e, h, a, b)

    def _legs_to(self, e: np.ndarray, p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Travel seconds (n, R) at autonomous speed from each robot's position to POI p of
        plan e (each (n,)), and the autonomous arrival times."""
        gx = self.tx[e, p][:, None] - self.robot_xy[e, :, 0]
        gy = self.ty[e, p][:, None] - self.robot_xy[e, :, 1]
        travel = np.sqrt(gx * gx + gy * gy) / np.maximum(self.start.speed[e], 1e-9)
        return travel, self.robot_free[e] + travel + self.capture_s

    def _greedy_net(self, q: np.ndarray, d: np.ndarray, pts: np.ndarray, arrive: np.ndarray,
                    t_ref: np.ndarray, rows: np.ndarray | None = None
                    ) -> tuple[np.ndarray, np.ndarray]:
        """Greedy's net value of each human classifying an image of quality q and difficulty d
        captured at `arrive` (each (E, N)), worth `pts`: its expected points less the price of
        the human's time (the item, and its wait from `t_ref` (E,)); with the finish times.
        Both (E, N, H). `rows`: the plan of each row (`HumanLoad.classification`)."""
        p_g, fin_g, _, _, _, _ = self.load.classification(q, d, arrive, greedy=True, rows=rows)
        free = self.human_free if rows is None else self.human_free[rows]
        delay = np.maximum(free[:, None, :] - t_ref[:, None, None], 0.0)
        net = greedy_score.human_net(tables.expected_points(pts[..., None], p_g),
                                     tables.T_BAR[q, d][..., None], delay,
                                     self.s.human_time_cost)
        return net, fin_g

    def _option_value(self, net: np.ndarray, fin: np.ndarray, onboard: np.ndarray
                      ) -> np.ndarray:
        """Greedy's worth of each option (E, N) (`greedy_score.option_value`): the best human
        by net value (first on ties), or onboard."""
        best = net.argmax(-1)
        # the best human's entries by flat takes (cheaper than take_along_axis; ravel is a view
        # of these freshly computed arrays)
        at = np.arange(best.size) * net.shape[-1] + best.ravel()
        return greedy_score.option_value(net.ravel().take(at).reshape(best.shape),
                                         fin.ravel().take(at).reshape(best.shape),
                                         self.horizon, onboard)

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

    @_quiet
    def poi_inputs(self) -> StepInputs:
        """Which POI next: features relative to the robot free first (the greedy robot). They
        are computed for the legal (episode, POI) pairs alone: those left that some robot
        reaches by the horizon and that greedy's prior ranks on the episode's shortlist (its
        `SHORTLIST` best); the others' logits are masked, and their features are zero."""
        E, P, s, e = self.E, self.P, self.s, self.e
        free = np.where(self.robot_done, np.inf, self.robot_free)
        r_ff = free.argmin(axis=1)
        self.r_ff = r_ff
        lb, lp = np.nonzero(self.left)
        travel, arr = self._legs_to(lb, lp)                                 # (n, R)
        reach = (arr <= self.horizon) & ~self.robot_done[lb]
        ok = reach.any(axis=1)
        ce, cp, travel, arr, reach = lb[ok], lp[ok], travel[ok], arr[ok], reach[ok]
        mask = np.zeros((E, P), bool)
        mask[ce, cp] = True
        feats = np.zeros((E, P, POI_FEATURES), np.float32)
        prior = np.full((E, P), -1.0)
        if ce.size == 0:
            return StepInputs(feats, mask, prior, mask.any(axis=1))
        c, rf = np.arange(ce.size), r_ff[ce]
        t_ff = self.robot_free[e, r_ff][ce]
        arr_ff = arr[c, rf]
        rtype = self.start.robot_type[ce, rf]
        kind, d, pts = self.start.kind[ce, cp], self.start.diff[ce, cp], self.points[ce, cp]
        q_auto = tables.QUALITY[rtype, kind, 1]
        q_nav = tables.QUALITY[rtype, kind, 2]
        ev_auto = tables.expected_points(pts, tables.P_RC[q_auto, d])
        ev_navq = tables.expected_points(pts, tables.P_RC[q_nav, d])
        # the first free highly skilled navigator, as greedy
        hf = np.where(self.high, self.human_free, np.inf)
        hn = hf.argmin(axis=1)
        has_nav = np.isfinite(hf[e, hn])[ce]
        depart = np.maximum(self.robot_free[e, r_ff], hf[e, hn])[ce]
        leg_nav = travel[c, rf] / tables.SKILL_SPEED[2] + self.capture_s
        arr_nav = np.where(has_nav, depart + leg_nav, np.inf)
        # greedy's prior: the rate of net points per robot second, for both options at once
        # (the last axis: autonomous, navigated)
        arr_o = np.stack([arr_ff, arr_nav], 1)                              # (n, 2)
        q_o = np.stack([q_auto, q_nav], 1)
        cost = np.stack([np.zeros_like(leg_nav), s.human_time_cost * leg_nav], 1)
        at = np.minimum(arr_o, 1e12)
        ev_on = np.stack([ev_auto, ev_navq], 1)
        value = self._option_value(*self._greedy_net(q_o, d[:, None], pts[:, None], at, t_ff,
                                                     rows=ce), ev_on) - cost
        rate = greedy_score.rate(value, arr_o - t_ff[:, None], s.rate_offset_s)
        rates = np.where(arr_o <= self.horizon, rate, -np.inf)
        rate_ff = np.maximum(rates[:, 0], rates[:, 1])
        prior[ce, cp] = np.where(np.isfinite(rate_ff), rate_ff, -1.0)
        if P > SHORTLIST:
            # the shortlist: the legal POIs the prior ranks among the SHORTLIST best of their
            # episode (ties included), a function of the episode's own row
            kth = -np.partition(-prior, SHORTLIST - 1, axis=1)[:, SHORTLIST - 1]
            sel = np.flatnonzero(prior[ce, cp] >= kth[ce])
            if sel.size < ce.size:
                mask[ce, cp] = False
                (ce, cp, rf, t_ff, arr_ff, arr_nav, ev_auto, ev_navq, rates, q_o, at, arr, reach,
                 kind, d, pts) = (x[sel] for x in (ce, cp, rf, t_ff, arr_ff, arr_nav, ev_auto,
                                                   ev_navq, rates, q_o, at, arr, reach, kind, d,
                                                   pts))
                mask[ce, cp] = True
                c = np.arange(ce.size)
        # the learned features: the best human with workload and fatigue projected
        p_h, fin_h, _, _, _, _ = self.load.classification(q_o, d[:, None], at, rows=ce)
        ev_h = np.where(fin_h <= self.horizon,
                        tables.expected_points(pts[:, None, None], p_h), -np.inf)
        hum_best = np.maximum(ev_h.max(-1), -MAX_POINTS)
        # competition: how much sooner, and how much better onboard, another robot gets there
        others = reach
        others[c, rf] = False
        other_arr = np.where(others, arr, np.inf).min(axis=1)
        ev_all = np.where(others, self._ev_onboard[ce, :, cp], -MAX_POINTS).max(axis=1)
        hz = self.horizon
        left_share = self.left.sum(1)[ce] / max(P, 1)
        prev_feats = np.zeros((ce.size, 3))
        if self.previous is not None:
            prev_feats[:, 0] = self.previous.robot[ce, cp] == rf
            prev_feats[:, 1] = self.prev_valid[ce, cp]
            prev_feats[:, 2] = self.previous.classifier[ce, cp] >= 0
        feats[ce, cp] = _fill(np.empty((ce.size, POI_FEATURES), np.float32), [
            np.clip((arr_ff - self.now) / hz, 0, 2), np.clip((arr_nav - self.now) / hz, 0, 2),
            ev_auto / MAX_POINTS, ev_navq / MAX_POINTS, hum_best[:, 0] / MAX_POINTS,
            hum_best[:, 1] / MAX_POINTS,
            np.clip(np.where(np.isfinite(rates[:, 0]), rates[:, 0], -0.1) * 20, -2, 2),
            np.clip(np.where(np.isfinite(rates[:, 1]), rates[:, 1], -0.1) * 20, -2, 2),
            np.clip((other_arr - arr_ff) / hz, -2, 2), (ev_all - ev_auto) / MAX_POINTS,
            pts / MAX_POINTS, kind, d / 2.0, np.clip((hz - t_ff) / hz, 0, 1), left_share,
            prev_feats])
        return StepInputs(feats, mask, prior, mask.any(axis=1))

    @_quiet
    def robot_inputs(self, p: np.ndarray) -> StepInputs:
        """Which robot for POI p."""
        E, R, e = self.E, self.R, self.e
        travel_p, arr_p = self._legs_to(e, p)                               # (E, R)
        mask = ~self.robot_done & (arr_p <= self.horizon)
        q = tables.QUALITY[self.start.robot_type, self.start.kind[e, p][:, None], 1]
        d = self.start.diff[e, p][:, None]
        ev = tables.expected_points(self.points[e, p][:, None], tables.P_RC[q, d])
        is_ff = np.arange(R)[None, :] == self.r_ff[:, None]
        hz = self.horizon
        prev_r = np.zeros((E, R))
        if self.previous is not None:
            prev_r = (np.arange(R)[None, :] == self.previous.robot[e, p][:, None]).astype(float)
        feats = _fill(np.empty((E, R, ROBOT_FEATURES), np.float32), [
            np.clip((arr_p - self.now) / hz, 0, 2),
            np.clip((np.where(self.robot_done, hz, self.robot_free) - self.now) / hz, 0, 2),
            travel_p / hz, ev / MAX_POINTS, is_ff, self.n_assigned / max(self.P, 1), prev_r,
            self.start.robot_type, np.eye(4)[q]])
        prior = is_ff.astype(float)
        return StepInputs(feats, mask, prior, mask.any(1))

    @_quiet
    def nav_inputs(self, p: np.ndarray, r: np.ndarray) -> StepInputs:
        """Who drives robot r to POI p: autonomous, or one highly skilled human (index h + 1)."""
        E, H, s, e = self.E, self.H, self.s, self.e
        tr = self._distance(e, p, r) / np.maximum(self.start.speed[e, r], 1e-9)   # (E,)
        t_r = self.robot_free[e, r]
        rtype = self.start.robot_type[e, r]
        kind, d = self.start.kind[e, p], self.start.diff[e, p]
        pts = self.points[e, p]
        skill = np.concatenate([np.ones((E, 1), np.int64), self.start.skill], 1)  # auto: 1
        speed_f = np.where(np.arange(H + 1)[None, :] == 0, 1.0, tables.SKILL_SPEED[skill])
        leg = tr[:, None] / speed_f + self.capture_s
        free = np.concatenate([t_r[:, None], np.maximum(t_r[:, None], self.human_free)], 1)
        arrive = free + leg
        q = tables.QUALITY[rtype[:, None], kind[:, None], skill]
        ev_on = tables.expected_points(pts[:, None], tables.P_RC[q, d[:, None]])
        # greedy's rate for each option (F_w = 1; the best human classifier at that quality)
        human = np.arange(H + 1)[None, :] > 0
        value = self._option_value(*self._greedy_net(
            q, np.broadcast_to(d[:, None], q.shape), pts[:, None], arrive, t_r), ev_on) \
            - np.where(human, s.human_time_cost * leg, 0.0)
        rate = greedy_score.rate(value, arrive - t_r[:, None], s.rate_offset_s)
        mask = np.concatenate([np.ones((E, 1), bool), self.high], 1) & (arrive <= self.horizon)
        mask[:, 0] = True
        hz = self.horizon
        util = np.concatenate([np.zeros((E, 1)),
                               self.load.utilisation_at(free[:, None, 1:])[:, 0]], 1)
        prev_n = np.zeros((E, H + 1))
        if self.previous is not None:
            prev_n = (np.arange(H + 1)[None, :] == self.previous.navigator[e, p][:, None] + 1)
        feats = _fill(np.empty((E, H + 1, NAV_FEATURES), np.float32), [
            np.clip((arrive - self.now) / hz, 0, 2), np.clip((free - t_r[:, None]) / hz, 0, 2),
            np.where(human, leg / hz, 0.0), ev_on / MAX_POINTS, np.clip(rate * 20, -2, 2), util,
            prev_n, human[0], np.eye(4)[q]])
        prior = np.where(mask, rate, -1.0)
        return StepInputs(feats, mask, prior, np.ones(E, bool))

    @_quiet
    def cls_inputs(self, p: np.ndarray, r: np.ndarray, n: np.ndarray) -> StepInputs:
        """Who classifies POI p's image: onboard (index 0) or a human (h + 1)."""
        E, H, s, e = self.E, self.H, self.s, self.e
        arrive, q = self._arrival(p, r, n)
        d = self.start.diff[e, p]
        pts = self.points[e, p]
        # the navigator is busy until the capture: for it the item starts then at the earliest
        p_h, fin, begin, u, f_w, f_f = (x[:, 0] for x in self.load.classification(
            q[:, None], d[:, None], arrive[:, None]))
        ev_h = np.where(fin <= self.horizon, tables.expected_points(pts[:, None], p_h), 0.0)
        net_g, fin_g = (x[:, 0] for x in self._greedy_net(q[:, None], d[:, None], pts[:, None],
                                                          arrive[:, None], self.robot_free[e, r]))
        net_g = np.where(fin_g <= self.horizon, net_g, 0.0)
        t_bar = tables.T_BAR[q, d]
        p_on = tables.P_RC[q, d]
        ev_on = tables.expected_points(pts, p_on)
        hz = self.horizon
        prev_c = np.zeros((E, H + 1))
        rebrief = np.zeros((E, H))
        if self.previous is not None:
            prev_c = (np.arange(H + 1)[None, :] == self.previous.classifier[e, p][:, None] + 1)
            moved = self.previous.classifier[e, p][:, None] != np.arange(H)[None, :]
            rebrief = (moved & ~self.touched).astype(float) * (s.rebrief_s > 0)
        # candidate 0 onboard, then the humans, `own` columns each; the last three: whether the
        # candidate classifies in the allocation in force, and the image quality's first two
        # one-hot columns
        own = CLS_FEATURES - 3
        feats = np.empty((E, H + 1, CLS_FEATURES), np.float32)
        _fill(feats[:, 0, :own], [ev_on / MAX_POINTS, p_on, np.clip((arrive - self.now) / hz, 0, 2),
                                  0.0, 0.0, 1.0, 1.0, 0.0, ev_on / MAX_POINTS, 0.0, 0.0])
        _fill(feats[:, 1:, :own], [ev_h / MAX_POINTS, p_h, np.clip((fin - self.now) / hz, 0, 2),
                                   np.clip((begin - arrive[:, None]) / hz, 0, 2), u, f_w, f_f,
                                   t_bar[:, None] / hz, net_g / MAX_POINTS, rebrief, 1.0])
        _fill(feats[..., own:], [prev_c, np.eye(4)[q][:, None, :2]])
        prior = np.concatenate([ev_on[:, None], net_g], 1)
        mask = np.ones((E, H + 1), bool)
        return StepInputs(feats, mask, prior, np.ones(E, bool))

    def _distance(self, e: np.ndarray, p: np.ndarray, r: np.ndarray) -> np.ndarray:
        """Metres from robot r's projected position to POI p, in episodes e (each (n,))."""
        gx = self.tx[e, p] - self.robot_xy[e, r, 0]
        gy = self.ty[e, p] - self.robot_xy[e, r, 1]
        return np.sqrt(gx * gx + gy * gy)

    def _route(self, e, p, r, n) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Robot r to POI p with navigator n (-1 auto), in episodes e: when it sets off (with
        its navigator free), its travel seconds and the image quality."""
        cls_ = tables.navigator_class(n[:, None], self.start.skill[e])[:, 0]
        v = self.start.speed[e, r] * np.where(n >= 0, tables.SKILL_SPEED[cls_], 1.0)
        nav_h = np.maximum(n, 0)
        depart = np.where(n >= 0, np.maximum(self.robot_free[e, r], self.human_free[e, nav_h]),
                          self.robot_free[e, r])
        q = tables.QUALITY[self.start.robot_type[e, r], self.start.kind[e, p], cls_]
        return depart, self._distance(e, p, r) / np.maximum(v, 1e-9), q

    def _arrival(self, p: np.ndarray, r: np.ndarray, n: np.ndarray
                 ) -> tuple[np.ndarray, np.ndarray]:
        """Capture time and image quality of robot r at POI p with navigator n (-1 auto)."""
        depart, travel, q = self._route(self.e, p, r, n)
        return depart + travel + self.capture_s, q

    # -- commit ----------------------------------------------------------------------------------
    def commit(self, active: np.ndarray, p: np.ndarray, r: np.ndarray, n: np.ndarray,
               c: np.ndarray) -> None:
        """Give POI p (robot r, navigator n, classifier c; -1 auto / onboard) in the active
        episodes, and update the members' projected state."""
        s = self.s
        e = self.e[active]
        p, r, n, c = p[active], r[active], n[active], c[active]
        if e.size == 0:
            return
        if self.previous is not None and s.rebrief_s > 0:
            self._charge(e, p, n, c)
        depart, travel, q = self._route(e, p, r, n)
        leg = travel + self.capture_s
        arrive = depart + leg
        depart_nav = arrive - leg
        nb = n >= 0
        if nb.any():
            self._book(e[nb], n[nb], depart_nav[nb], arrive[nb])
        cb = c >= 0
        if cb.any():
            ce, ch = e[cb], c[cb]
            begin = np.maximum(arrive[cb], self.human_free[ce, ch])
            self._book(ce, ch, begin, begin + tables.T_BAR[q[cb], self.start.diff[ce, p[cb]]])
        self.robot_free[e, r] = arrive
        self.robot_xy[e, r] = self.start.task_xy[e, p]
        self.n_assigned[e, r] += 1
        self.robot[e, p], self.nav[e, p], self.cls[e, p] = r, n, c
        self.left[e, p] = False

    def _charge(self, e, p, n, c) -> None:
        """Re-brief (in the projection) every human this choice first changes the work of."""
        prev = self.previous
        for old, new in ((prev.navigator[e, p], n), (prev.classifier[e, p], c)):
            moved = old != new
            for who in (old, new):
                hit = moved & (who >= 0)
                he, hh = e[hit], who[hit]
                fresh = ~self.touched[he, hh]
                he, hh = he[fresh], hh[fresh]
                if he.size:
                    a = np.maximum(self.human_free[he, hh], self.now)
                    self.touched[he, hh] = True
                    self._book(he, hh, a, a + self.s.rebrief_s)

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
