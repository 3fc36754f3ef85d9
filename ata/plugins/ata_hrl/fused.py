"""A decode by the mode, compiled whole: every episode decoded to its end in one compiled loop,
its four steps, their logits, each choice and its commit one after the other.

`decode.decode` takes this path where it takes the mode and records nothing (evaluation): the
same steps as its step-by-step loop, in the same order of operations on the same values, so the
same allocation to the bit. An episode's decode reads and writes its own rows alone, so decoding
each episode to its end in turn makes the choices the step-by-step loop makes over all the
episodes at once; and where the step-by-step loop calls the compiled steps once per step and
sub-decision from Python, with the inputs of every episode as arrays between them, here nothing
returns to Python until the decode is over. What the loop computes once per step beside the
compiled steps is computed here as it does: the inputs' cleaning (`decode._clean`), the mode
(numpy's argmax), and the fatigue projections after a booking (`HumanLoad.fatigue_at`,
`fatigue_greedy`: the belief's one curve, read at the hours booked; a belief of several curves
takes the step-by-step loop).
"""

from __future__ import annotations

import math

import numpy as np

from ata.model import scalar, tables
from ata.model.load import BIN_S
from ata.model.scalar import jit
from ata.model.tables import MAX_POINTS
from ata.plugins.ata_hrl.commit_step import commit_episode
from ata.plugins.ata_hrl.decoder import SHORTLIST, Decoder
from ata.plugins.ata_hrl.inputs import CLS_FEATURES, NAV_FEATURES, POI_FEATURES, ROBOT_FEATURES
from ata.plugins.ata_hrl.member_steps import cls_episode, nav_episode, robot_episode
from ata.plugins.ata_hrl.poi_step import poi_episode, poi_scratch
from ata.plugins.ata_hrl.scorer_loop import logits_row

INF = math.inf


def fits(dec: Decoder) -> bool:
    """Whether this decoder's fatigue projections are the compiled loop's (one curve each)."""
    return dec.load.start.belief.weight.shape[-1] == 1


def decode_mode(dec: Decoder, weights: dict, tasks: np.ndarray, robots: np.ndarray,
                cand_hidden: dict, residual: bool) -> None:
    """Decode every POI left in `dec` by the mode of the scorers (`weights`, the candidates'
    projections `cand_hidden`, the tokens `tasks` and `robots`, as `decode._Steps` holds them),
    writing the allocation and the members' projected state into `dec` (then `dec.finish()`)."""
    s, st, load, prev = dec.s, dec.start, dec.load, dec.previous
    belief = load.start.belief
    charge = prev is not None and s.rebrief_s > 0
    dummy = dec._dummy
    _decode(dec.left, dec.robot_free, dec.robot_done, dec.robot_xy, st.speed, dec.tx, dec.ty,
            st.robot_type, st.kind, st.diff, dec.points, dec.human_free, dec.high, st.skill,
            load.eta_lam, load.cum, load.booked, load.edges, BIN_S, dec._ev_onboard,
            prev is not None, dummy if prev is None else prev.robot,
            dummy if prev is None else prev.navigator,
            dummy if prev is None else prev.classifier, dec.prev_valid, dec.n_assigned,
            dec.robot, dec.nav, dec.cls, dec.touched, st.task_xy, charge,
            prev.navigator if charge else dummy, prev.classifier if charge else dummy,
            s.rebrief_s > 0, float(dec.now), float(dec.horizon), float(dec.capture_s),
            s.window_s, s.human_time_cost, s.rate_offset_s, float(s.rebrief_s),
            float(tables.SKILL_SPEED[2]), SHORTLIST, MAX_POINTS, tables.TABLES,
            load.start.hours, float(load.start.now), belief.onset[..., 0],
            belief.slope[..., 0], belief.offset, belief.floor,
            load.fatigue_at().copy(), load.fatigue_greedy().copy(), tasks, robots, residual,
            weights["poi"], weights["robot"], weights["nav"], weights["cls"],
            cand_hidden["poi"], cand_hidden["robot"], cand_hidden["nav"], cand_hidden["cls"])
    load.forget()       # its fatigue projections are of the bookings before the decode


@jit
def _clip(x, lo, hi):
    """np.clip of a number (nan stays nan)."""
    if x < lo:
        return lo
    if x > hi:
        return hi
    return x


@jit
def _fatigue_row(e, hours, booked, free, now, onset, slope, offset, floor, fat_at, fat_greedy):
    """Episode e's rows of `HumanLoad.fatigue_at` and `fatigue_greedy` (`FatigueBelief.at` of one
    curve, and `ahead`) after its bookings."""
    for h in range(hours.shape[1]):
        t = hours[e, h] + booked[e, h] / 3600.0
        fat_at[e, h] = _clip(scalar.individual(t, onset[e, h], slope[e, h], floor)
                             + offset[e, h], floor, 1.0)
        wait = free[e, h] - now
        wait = 0.0 if wait < 0.0 else wait          # np.maximum(wait, 0)
        t = hours[e, h] + wait / 3600.0
        fat_greedy[e, h] = _clip(scalar.individual(t, onset[e, h], slope[e, h], floor)
                                 + offset[e, h], floor, 1.0)


@jit
def _pick(context, feats, prior, mask, cand_h, tasks, robots, robot, task, residual, w, out,
          prior32, ctx, ctx_h, pre, hid):
    """One episode's choice of a sub-decision: its inputs cleaned as `decode._clean` cleans
    them (feats in place), the logits (`scorer_loop.logits_row`) and their first maximum."""
    N, F = feats.shape
    for n in range(N):
        for i in range(F):
            v = feats[n, i]
            if v != v:
                feats[n, i] = 0.0
            elif v == INF:
                feats[n, i] = 10.0
            elif v == -INF:
                feats[n, i] = -10.0
        p = prior[n]
        if p != p:
            p = -1.0
        elif p == INF:
            p = 1e3
        elif p == -INF:
            p = -1e3
        prior32[n] = np.float32(p)
    logits_row(context, feats, prior32[:N], mask, cand_h[:N], tasks, robots, robot, task,
               residual, w.feat_w, w.feat_b, w.ctx_w, w.hid_w, w.hid_b, w.out_w, w.out_b,
               w.lin_w, w.lin_b, w.scale, out[:N], ctx, ctx_h, pre, hid)
    best, top = 0, out[0]                 # numpy's argmax: the first maximum, a nan first
    if top != top:
        return 0
    for n in range(1, N):
        v = out[n]
        if v != v:
            return n
        if v > top:
            best, top = n, v
    return best


@jit
def _decode(left, robot_free, robot_done, robot_xy, speed, tx, ty, robot_type, kind, diff,
            points, human_free, high, skill, eta_lam, cum, booked, edges, bin_s, ev_onboard,
            has_prev, prev_robot, prev_nav, prev_cls, prev_valid, n_assigned, robot, nav, cls,
            touched, task_xy, charge, charge_nav, charge_cls, rebrief_on, now, horizon,
            capture_s, window_s, price, offset_s, rebrief_s, nav_speed, shortlist, max_points,
            tab, hours, start_now, onset, slope, offset, floor, fat_at, fat_greedy, tasks,
            robots, residual, w_poi, w_robot, w_nav, w_cls, h_poi, h_robot, h_nav, h_cls):
    E, P = left.shape
    R = robot_free.shape[1]
    H = human_free.shape[1]
    cum_flat = cum.reshape(-1)
    n_edges = edges.shape[0]
    last_edge = edges[-1]
    d, h = tasks.shape[2], w_poi.feat_b.shape[0]
    N = max(P, R, H + 1)
    feats_p = np.zeros((E, P, POI_FEATURES), np.float32)
    mask_p = np.zeros((E, P), np.bool_)
    prior_p = np.full((E, P), -1.0)
    feats_r = np.empty((E, R, ROBOT_FEATURES), np.float32)
    mask_r = np.empty((E, R), np.bool_)
    prior_r = np.empty((E, R))
    feats_n = np.empty((E, H + 1, NAV_FEATURES), np.float32)
    mask_n = np.empty((E, H + 1), np.bool_)
    prior_n = np.empty((E, H + 1))
    feats_c = np.empty((E, H + 1, CLS_FEATURES), np.float32)
    mask_c = np.ones(H + 1, np.bool_)
    prior_c = np.empty((E, H + 1))
    r_ff = np.zeros(E, np.int64)
    p = np.zeros(E, np.int64)
    r = np.zeros(E, np.int64)
    n = np.zeros(E, np.int64)
    c = np.zeros(E, np.int64)
    out = np.empty(N, np.float32)
    prior32 = np.empty(N, np.float32)
    ctx = np.empty(d, np.float32)
    ctx_h = np.empty(h, np.float32)
    pre = np.empty(h, np.float32)
    hid = np.empty(h, np.float32)
    (travel, arr, reach, rates, arr_o, q_o, ev_on, cost, hum, row, memo_pts, memo_h,
     memo_net) = poi_scratch(R, P, tab)
    for e in range(E):
        while True:
            feats_p[e] = 0.0
            mask_p[e] = False
            prior_p[e] = -1.0
            poi_episode(e, left, robot_free, robot_done, robot_xy, speed, tx, ty, robot_type,
                        kind, diff, points, human_free, high, fat_greedy, fat_at, eta_lam,
                        cum_flat, n_edges, last_edge, bin_s, ev_onboard, has_prev, prev_robot,
                        prev_cls, prev_valid, now, horizon, capture_s, window_s, price,
                        offset_s, nav_speed, shortlist, max_points, tab, feats_p, mask_p,
                        prior_p, r_ff, travel, arr, reach, rates, arr_o, q_o, ev_on, cost,
                        hum, row, memo_pts, memo_h, memo_net)
            if not mask_p[e].any():
                break
            p[e] = _pick(0, feats_p[e], prior_p[e], mask_p[e], h_poi[e], tasks[e], robots[e],
                         r_ff[e], 0, residual, w_poi, out, prior32, ctx, ctx_h, pre, hid)
            robot_episode(e, p, robot_free, robot_done, robot_xy, speed, tx, ty, robot_type,
                          kind, diff, points, r_ff, n_assigned, has_prev, prev_robot, P, now,
                          horizon, capture_s, max_points, tab, feats_r, mask_r, prior_r)
            r[e] = _pick(1, feats_r[e], prior_r[e], mask_r[e], h_robot[e], tasks[e],
                         robots[e], 0, p[e], residual, w_robot, out, prior32, ctx, ctx_h, pre,
                         hid)
            nav_episode(e, p, r, robot_free, robot_xy, speed, tx, ty, robot_type, kind, diff,
                        points, skill, high, human_free, eta_lam, fat_greedy, cum_flat,
                        n_edges, last_edge, bin_s, has_prev, prev_nav, now, horizon,
                        capture_s, window_s, price, offset_s, max_points, tab, feats_n, mask_n,
                        prior_n)
            n[e] = _pick(2, feats_n[e], prior_n[e], mask_n[e], h_nav[e], tasks[e], robots[e],
                         r[e], p[e], residual, w_nav, out, prior32, ctx, ctx_h, pre, hid) - 1
            cls_episode(e, p, r, n, robot_free, robot_xy, speed, tx, ty, robot_type, kind,
                        diff, points, skill, human_free, eta_lam, fat_greedy, fat_at, touched,
                        cum_flat, n_edges, last_edge, bin_s, has_prev, prev_cls, rebrief_on,
                        now, horizon, capture_s, window_s, price, max_points, tab, feats_c,
                        prior_c)
            c[e] = _pick(2, feats_c[e], prior_c[e], mask_c, h_cls[e], tasks[e], robots[e],
                         r[e], p[e], residual, w_cls, out, prior32, ctx, ctx_h, pre, hid) - 1
            if commit_episode(e, p, r, n, c, robot_free, robot_xy, n_assigned, robot, nav, cls,
                              left, touched, charge_nav, charge_cls, charge, now, rebrief_s,
                              capture_s, speed, skill, robot_type, kind, diff, task_xy, tab, cum,
                              booked, human_free, edges):
                _fatigue_row(e, hours, booked, human_free, start_now, onset, slope, offset,
                             floor, fat_at, fat_greedy)
