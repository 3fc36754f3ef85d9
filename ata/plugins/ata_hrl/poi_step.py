"""The decoder's POI step compiled: for every episode, the legal POIs, greedy's prior of each
and the learned features of those on the shortlist, in one loop over (episode, POI) pairs
(`Decoder.poi_inputs` says what each is). The candidate's scores are the host's formulas
(`ata.model.scalar`), in the order of operations of their array twins, so the step gives the
bits numpy's would."""

from __future__ import annotations

import math

import numpy as np

from ata.model import scalar
from ata.model.scalar import jit
from ata.plugins.ata_hrl import inputs as c
from ata.plugins.ata_hrl.member_steps import greedy_human

INF = math.inf


@jit
def poi_step(left, robot_free, robot_done, robot_xy, speed, tx, ty, robot_type, kind, diff,
             points, human_free, high, fat_greedy, fat_now, eta_lam, cum, n_edges, last_edge,
             bin_s, ev_onboard, has_prev, prev_robot, prev_cls, prev_valid, now, horizon,
             capture_s, window_s, price, offset_s, nav_speed, shortlist, max_points,
             tab, feats, mask, prior, r_ff):
    """Fill feats (E, P, F) (zeros on entry), mask (E, P) (False), prior (E, P) (-1) and r_ff
    (E,) for the decoder's POI step; `tab` the model's tables (`ata.model.tables.TABLES`)."""
    (travel, arr, reach, rates, arr_o, q_o, ev_on, cost, hum, row, memo_pts, memo_h,
     memo_net) = poi_scratch(robot_free.shape[1], left.shape[1], tab)
    for e in range(left.shape[0]):
        poi_episode(e, left, robot_free, robot_done, robot_xy, speed, tx, ty, robot_type, kind,
                    diff, points, human_free, high, fat_greedy, fat_now, eta_lam, cum, n_edges,
                    last_edge, bin_s, ev_onboard, has_prev, prev_robot, prev_cls, prev_valid,
                    now, horizon, capture_s, window_s, price, offset_s, nav_speed, shortlist,
                    max_points, tab, feats, mask, prior, r_ff, travel, arr, reach, rates,
                    arr_o, q_o, ev_on, cost, hum, row, memo_pts, memo_h, memo_net)


@jit
def poi_scratch(R, P, tab):
    """The working arrays of `poi_episode` for R robots and P POIs."""
    n_q, n_d = tab.t_bar.shape
    return (np.empty(R), np.empty(R), np.empty(R, np.bool_), np.empty(2), np.empty(2),
            np.empty(2, np.int64), np.empty(2), np.empty(2), np.empty(2), np.empty(P),
            np.empty((n_q, n_d)), np.empty((n_q, n_d), np.int64), np.empty((n_q, n_d)))


@jit
def poi_episode(e, left, robot_free, robot_done, robot_xy, speed, tx, ty, robot_type, kind,
                diff, points, human_free, high, fat_greedy, fat_now, eta_lam, cum, n_edges,
                last_edge, bin_s, ev_onboard, has_prev, prev_robot, prev_cls, prev_valid, now,
                horizon, capture_s, window_s, price, offset_s, nav_speed, shortlist,
                max_points, tab, feats, mask, prior, r_ff, travel, arr, reach, rates, arr_o,
                q_o, ev_on, cost, hum, row, memo_pts, memo_h, memo_net):
    """`poi_step` of episode e alone (`poi_scratch` its working arrays)."""
    P = left.shape[1]
    R = robot_free.shape[1]
    H = human_free.shape[1]
    # greedy's best human for an image of quality q and difficulty d does not depend on when
    # the image comes (only its finish does): per call, the first POI of each (q, d) finds
    # it, the others read it
    memo_pts[:] = np.nan
    # the robot free first (greedy's), and the first free highly skilled navigator
    rf = 0
    best = INF
    for r in range(R):
        v = INF if robot_done[e, r] else robot_free[e, r]
        if v < best:
            best, rf = v, r
    r_ff[e] = rf
    hn = 0
    best = INF
    for h in range(H):
        v = human_free[e, h] if high[e, h] else INF
        if v < best:
            best, hn = v, h
    nav_free = human_free[e, hn] if high[e, hn] else INF
    has_nav = np.isfinite(nav_free)
    t_ff = robot_free[e, rf]
    depart = max(t_ff, nav_free)
    n_left = 0
    for p in range(P):
        if left[e, p]:
            n_left += 1
    kth = -INF
    for stage in range(2):
        if stage == 1:
            if P > shortlist:
                for p in range(P):
                    row[p] = prior[e, p]
                row.sort()
                kth = row[P - shortlist]
        for p in range(P):
            if not left[e, p]:
                continue
            if stage == 1 and (not mask[e, p] or prior[e, p] < kth):
                mask[e, p] = False
                continue
            # the legs: every robot's on the shortlist (the competition features), else
            # the robot free first's and, if it cannot reach the POI, any other's that can
            ok = False
            for i in range(R + 1):
                r = rf if i == 0 else i - 1
                if i > 0 and (r == rf or (stage == 0 and ok)):
                    continue
                gx = tx[e, p] - robot_xy[e, r, 0]
                gy = ty[e, p] - robot_xy[e, r, 1]
                travel[r] = math.sqrt(gx * gx + gy * gy) / max(speed[e, r], 1e-9)
                arr[r] = robot_free[e, r] + travel[r] + capture_s
                reach[r] = arr[r] <= horizon and not robot_done[e, r]
                ok = ok or reach[r]
            if not ok:
                continue
            k, d, pts = kind[e, p], diff[e, p], points[e, p]
            rtype = robot_type[e, rf]
            q_o[0] = tab.quality[rtype, k, 1]
            q_o[1] = tab.quality[rtype, k, 2]
            ev_on[0] = scalar.expected_points(pts, tab.p_rc[q_o[0], d])
            ev_on[1] = scalar.expected_points(pts, tab.p_rc[q_o[1], d])
            leg_nav = travel[rf] / nav_speed + capture_s
            arr_o[0] = arr[rf]
            arr_o[1] = depart + leg_nav if has_nav else INF
            cost[0] = 0.0
            cost[1] = price * leg_nav
            # greedy's prior: the rate of net points per robot second, both options
            for o in range(2):
                at = min(arr_o[o], 1e12)
                q = q_o[o]
                tb = tab.t_bar[q, d]
                if memo_pts[q, d] != pts:
                    memo_h[q, d], memo_net[q, d] = greedy_human(
                        e, q, d, pts, t_ff, human_free, eta_lam, fat_greedy, tab,
                        price)
                    memo_pts[q, d] = pts
                best_net = memo_net[q, d]
                best_fin = max(at, human_free[e, memo_h[q, d]]) + tb
                rt = scalar.option_rate(best_net, best_fin, horizon, ev_on[o], cost[o],
                                        arr_o[o] - t_ff, offset_s)
                rates[o] = rt if arr_o[o] <= horizon else -INF
            rate_ff = max(rates[0], rates[1])
            if stage == 0:
                mask[e, p] = True
                prior[e, p] = rate_ff if np.isfinite(rate_ff) else -1.0
                continue
            # the learned features: the best human with workload and fatigue projected
            for o in range(2):
                at = min(arr_o[o], 1e12)
                q = q_o[o]
                tb, fd = tab.t_bar[q, d], tab.f_d[q, d]
                top = -INF
                for h in range(H):
                    begin = max(at, human_free[e, h])
                    fin = begin + tb
                    base = (e * H + h) * n_edges
                    u = scalar.utilisation(cum, base, last_edge, n_edges, bin_s,
                                           window_s, begin)
                    ps = scalar.human_success(eta_lam[e, h], 1.0, fat_now[e, h],
                                              scalar.workload(u), fd)
                    ev = scalar.expected_points(pts, ps) if fin <= horizon else -INF
                    top = max(top, ev)
                hum[o] = max(top, -max_points)
            # competition: how much sooner, and how much better onboard, another robot
            other_arr, ev_all = INF, -max_points
            for r in range(R):
                if r != rf and reach[r]:
                    other_arr = min(other_arr, arr[r])
                    ev_all = max(ev_all, ev_onboard[e, r, p])
            f = feats[e, p]
            f[c.POI_ARRIVE] = min(max((arr_o[0] - now) / horizon, 0.0), 2.0)
            f[c.POI_ARRIVE + 1] = min(max((arr_o[1] - now) / horizon, 0.0), 2.0)
            f[c.POI_ONBOARD] = ev_on[0] / max_points
            f[c.POI_ONBOARD + 1] = ev_on[1] / max_points
            f[c.POI_HUMAN] = hum[0] / max_points
            f[c.POI_HUMAN + 1] = hum[1] / max_points
            for o in range(2):
                v = rates[o] if np.isfinite(rates[o]) else -0.1
                f[c.POI_RATE + o] = min(max(v * 20, -2.0), 2.0)
            f[c.POI_SOONER] = min(max((other_arr - arr_o[0]) / horizon, -2.0), 2.0)
            f[c.POI_BETTER] = (ev_all - ev_on[0]) / max_points
            f[c.POI_POINTS] = pts / max_points
            f[c.POI_KIND] = k
            f[c.POI_DIFFICULTY] = d / 2.0
            f[c.POI_TIME_LEFT] = min(max((horizon - t_ff) / horizon, 0.0), 1.0)
            f[c.POI_SHARE_LEFT] = n_left / max(P, 1)
            if has_prev:
                f[c.POI_SAME_ROBOT] = 1.0 if prev_robot[e, p] == rf else 0.0
                f[c.POI_VALID] = 1.0 if prev_valid[e, p] else 0.0
                f[c.POI_HUMAN_CLASSIFIES] = 1.0 if prev_cls[e, p] >= 0 else 0.0
