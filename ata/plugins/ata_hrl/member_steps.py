"""The decoder's member steps compiled: which robot, who navigates and who classifies, for the
POI (and robot, navigator) each episode chose, in one loop over the episodes
(`Decoder.robot_inputs`, `nav_inputs` and `cls_inputs` say what each feature is). The host's
formulas (`ata.model.scalar`) in the order of operations of their array twins: the same bits as
numpy's."""

from __future__ import annotations

import math

import numpy as np

from ata.model import scalar
from ata.model.scalar import jit
from ata.plugins.ata_hrl import inputs as c

INF = math.inf


@jit
def greedy_human(e, q, d, pts, t_ref, human_free, eta_lam, fat_greedy, tab, price):
    """Greedy's best human classifier (first on ties) of an image of quality q and difficulty d,
    and its net value (greedy's `human_gain` and `human_net`; the array form is
    tests/decoder_reference.py's `_greedy_net`): the same whenever the image arrives (only the
    human's finish depends on that)."""
    H = human_free.shape[1]
    tb, fd = tab.t_bar[q, d], tab.f_d[q, d]
    best_net, best_h = -INF, 0
    for h in range(H):
        delay = max(human_free[e, h] - t_ref, 0.0)
        net = scalar.human_net(scalar.human_gain(eta_lam[e, h], 1.0, fat_greedy[e, h], fd, pts),
                               tb, delay, price)
        if h == 0 or net > best_net or (np.isnan(net) and not np.isnan(best_net)):
            best_net, best_h = net, h
    return best_h, best_net


@jit
def _greedy_best(e, q, d, pts, arrive, t_ref, human_free, eta_lam, fat_greedy, tab,
                 price):
    """Greedy's best human classifier of an image captured at `arrive`: its net value and
    finish."""
    h, net = greedy_human(e, q, d, pts, t_ref, human_free, eta_lam, fat_greedy, tab,
                          price)
    return net, max(arrive, human_free[e, h]) + tab.t_bar[q, d]


@jit
def robot_step(p, robot_free, robot_done, robot_xy, speed, tx, ty, robot_type, kind, diff, points,
               r_ff, n_assigned, has_prev, prev_robot, n_pois, now, horizon, capture_s, max_points,
               tab, feats, mask, prior):
    """Fill feats (E, R, F), mask (E, R) and prior (E, R) of the robot step."""
    E, R = robot_free.shape
    for e in range(E):
        robot_episode(e, p, robot_free, robot_done, robot_xy, speed, tx, ty, robot_type, kind, diff,
                      points, r_ff, n_assigned, has_prev, prev_robot, n_pois, now, horizon,
                      capture_s, max_points, tab, feats, mask, prior)


@jit
def robot_episode(e, p, robot_free, robot_done, robot_xy, speed, tx, ty, robot_type, kind, diff,
                  points, r_ff, n_assigned, has_prev, prev_robot, n_pois, now, horizon, capture_s,
                  max_points, tab, feats, mask, prior):
    """`robot_step` of episode e alone."""
    E, R = robot_free.shape
    pe = p[e]
    k, d, pts = kind[e, pe], diff[e, pe], points[e, pe]
    for r in range(R):
        gx = tx[e, pe] - robot_xy[e, r, 0]
        gy = ty[e, pe] - robot_xy[e, r, 1]
        travel = math.sqrt(gx * gx + gy * gy) / max(speed[e, r], 1e-9)
        arr = robot_free[e, r] + travel + capture_s
        mask[e, r] = not robot_done[e, r] and arr <= horizon
        q = tab.quality[robot_type[e, r], k, 1]
        ev = scalar.expected_points(pts, tab.p_rc[q, d])
        is_ff = 1.0 if r == r_ff[e] else 0.0
        free = horizon if robot_done[e, r] else robot_free[e, r]
        f = feats[e, r]
        f[c.ROBOT_ARRIVE] = min(max((arr - now) / horizon, 0.0), 2.0)
        f[c.ROBOT_FREE] = min(max((free - now) / horizon, 0.0), 2.0)
        f[c.ROBOT_TRAVEL] = travel / horizon
        f[c.ROBOT_ONBOARD] = ev / max_points
        f[c.ROBOT_FREE_FIRST] = is_ff
        f[c.ROBOT_ASSIGNED] = n_assigned[e, r] / max(n_pois, 1)
        f[c.ROBOT_HOLDS] = 1.0 if has_prev and prev_robot[e, pe] == r else 0.0
        f[c.ROBOT_TYPE] = robot_type[e, r]
        for j in range(4):
            f[c.ROBOT_QUALITY + j] = 1.0 if q == j else 0.0
        prior[e, r] = is_ff


@jit
def nav_step(p, r, robot_free, robot_xy, speed, tx, ty, robot_type, kind, diff, points, skill, high,
             human_free, eta_lam, fat_greedy, cum, n_edges, last_edge, bin_s, has_prev, prev_nav,
             now, horizon, capture_s, window_s, price, offset_s, max_points, tab, feats, mask,
             prior):
    """Fill feats (E, H + 1, F), mask and prior (E, H + 1) of the navigator step: autonomous
    (0), or human h (h + 1)."""
    E, H = human_free.shape
    for e in range(E):
        nav_episode(e, p, r, robot_free, robot_xy, speed, tx, ty, robot_type, kind, diff, points,
                    skill, high, human_free, eta_lam, fat_greedy, cum, n_edges, last_edge, bin_s,
                    has_prev, prev_nav, now, horizon, capture_s, window_s, price, offset_s,
                    max_points, tab, feats, mask, prior)


@jit
def nav_episode(e, p, r, robot_free, robot_xy, speed, tx, ty, robot_type, kind, diff, points, skill,
                high, human_free, eta_lam, fat_greedy, cum, n_edges, last_edge, bin_s, has_prev,
                prev_nav, now, horizon, capture_s, window_s, price, offset_s, max_points, tab,
                feats, mask, prior):
    """`nav_step` of episode e alone."""
    E, H = human_free.shape
    pe, re = p[e], r[e]
    gx = tx[e, pe] - robot_xy[e, re, 0]
    gy = ty[e, pe] - robot_xy[e, re, 1]
    tr = math.sqrt(gx * gx + gy * gy) / max(speed[e, re], 1e-9)
    t_r = robot_free[e, re]
    k, d, pts = kind[e, pe], diff[e, pe], points[e, pe]
    for j in range(H + 1):
        human = j > 0
        sk = skill[e, j - 1] if human else 1
        leg = tr / (tab.skill_speed[sk] if human else 1.0) + capture_s
        free = max(t_r, human_free[e, j - 1]) if human else t_r
        arrive = free + leg
        q = tab.quality[robot_type[e, re], k, sk]
        ev_on = scalar.expected_points(pts, tab.p_rc[q, d])
        best_net, best_fin = _greedy_best(e, q, d, pts, arrive, t_r, human_free, eta_lam,
                                          fat_greedy, tab, price)
        rt = scalar.option_rate(best_net, best_fin, horizon, ev_on,
                                price * leg if human else 0.0, arrive - t_r, offset_s)
        ok = (not human or high[e, j - 1]) and arrive <= horizon
        mask[e, j] = ok or not human
        util = 0.0
        if human:
            util = scalar.utilisation(cum, (e * H + j - 1) * n_edges, last_edge, n_edges,
                                      bin_s, window_s, free)
        f = feats[e, j]
        f[c.NAV_ARRIVE] = min(max((arrive - now) / horizon, 0.0), 2.0)
        f[c.NAV_WAIT] = min(max((free - t_r) / horizon, 0.0), 2.0)
        f[c.NAV_LEG] = leg / horizon if human else 0.0
        f[c.NAV_ONBOARD] = ev_on / max_points
        f[c.NAV_RATE] = min(max(rt * 20, -2.0), 2.0)
        f[c.NAV_UTILISATION] = util
        f[c.NAV_HOLDS] = 1.0 if has_prev and prev_nav[e, pe] + 1 == j else 0.0
        f[c.NAV_HUMAN] = 1.0 if human else 0.0
        for i in range(4):
            f[c.NAV_QUALITY + i] = 1.0 if q == i else 0.0
        prior[e, j] = rt if mask[e, j] else -1.0


@jit
def cls_step(p, r, n, robot_free, robot_xy, speed, tx, ty, robot_type, kind, diff, points, skill,
             human_free, eta_lam, fat_greedy, fat_now, touched, cum, n_edges, last_edge, bin_s,
             has_prev, prev_cls, rebrief_on, now, horizon, capture_s, window_s, price, max_points,
             tab, feats, prior):
    """Fill feats (E, H + 1, F) and prior (E, H + 1) of the classifier step: onboard (0), or
    human h (h + 1)."""
    E, H = human_free.shape
    for e in range(E):
        cls_episode(e, p, r, n, robot_free, robot_xy, speed, tx, ty, robot_type, kind, diff, points,
                    skill, human_free, eta_lam, fat_greedy, fat_now, touched, cum, n_edges,
                    last_edge, bin_s, has_prev, prev_cls, rebrief_on, now, horizon, capture_s,
                    window_s, price, max_points, tab, feats, prior)


@jit
def cls_episode(e, p, r, n, robot_free, robot_xy, speed, tx, ty, robot_type, kind, diff, points,
                skill, human_free, eta_lam, fat_greedy, fat_now, touched, cum, n_edges, last_edge,
                bin_s, has_prev, prev_cls, rebrief_on, now, horizon, capture_s, window_s, price,
                max_points, tab, feats, prior):
    """`cls_step` of episode e alone."""
    E, H = human_free.shape
    pe, re, ne = p[e], r[e], n[e]
    # the capture (the array form: tests/decoder_reference.py's `_arrival`)
    cls_ = skill[e, max(ne, 0)] if ne >= 0 else 1
    v = speed[e, re] * (tab.skill_speed[cls_] if ne >= 0 else 1.0)
    depart = max(robot_free[e, re], human_free[e, max(ne, 0)]) if ne >= 0 \
        else robot_free[e, re]
    q = tab.quality[robot_type[e, re], kind[e, pe], cls_]
    gx = tx[e, pe] - robot_xy[e, re, 0]
    gy = ty[e, pe] - robot_xy[e, re, 1]
    arrive = depart + math.sqrt(gx * gx + gy * gy) / max(v, 1e-9) + capture_s
    d, pts = diff[e, pe], points[e, pe]
    tb, fd = tab.t_bar[q, d], tab.f_d[q, d]
    p_on = tab.p_rc[q, d]
    ev_on = scalar.expected_points(pts, p_on)
    t_ref = robot_free[e, re]
    prior[e, 0] = ev_on
    f = feats[e, 0]
    f[c.CLS_POINTS] = ev_on / max_points
    f[c.CLS_SUCCESS] = p_on
    f[c.CLS_FINISH] = min(max((arrive - now) / horizon, 0.0), 2.0)
    f[c.CLS_WAIT] = 0.0
    f[c.CLS_UTILISATION] = 0.0
    f[c.CLS_WORKLOAD] = 1.0
    f[c.CLS_FATIGUE] = 1.0
    f[c.CLS_ITEM] = 0.0
    f[c.CLS_NET] = ev_on / max_points
    f[c.CLS_REBRIEF] = 0.0
    f[c.CLS_HUMAN] = 0.0
    for h in range(H):
        free = human_free[e, h]
        begin = max(arrive, free)
        fin = begin + tb
        u = scalar.utilisation(cum, (e * H + h) * n_edges, last_edge, n_edges, bin_s,
                               window_s, begin)
        f_w = scalar.workload(u)
        f_f = fat_now[e, h]
        ps = scalar.human_success(eta_lam[e, h], 1.0, f_f, f_w, fd)
        ev_h = scalar.expected_points(pts, ps) if fin <= horizon else 0.0
        # greedy's net value of this human (F_w = 1, the fatigue at the free time)
        gain = scalar.human_gain(eta_lam[e, h], 1.0, fat_greedy[e, h], fd, pts)
        net = scalar.human_net(gain, tb, max(free - t_ref, 0.0), price)
        net = net if fin <= horizon else 0.0
        rebrief = 0.0
        if has_prev and rebrief_on and prev_cls[e, pe] != h and not touched[e, h]:
            rebrief = 1.0
        prior[e, h + 1] = net
        f = feats[e, h + 1]
        f[c.CLS_POINTS] = ev_h / max_points
        f[c.CLS_SUCCESS] = ps
        f[c.CLS_FINISH] = min(max((fin - now) / horizon, 0.0), 2.0)
        f[c.CLS_WAIT] = min(max((begin - arrive) / horizon, 0.0), 2.0)
        f[c.CLS_UTILISATION] = u
        f[c.CLS_WORKLOAD] = f_w
        f[c.CLS_FATIGUE] = f_f
        f[c.CLS_ITEM] = tb / horizon
        f[c.CLS_NET] = net / max_points
        f[c.CLS_REBRIEF] = rebrief
        f[c.CLS_HUMAN] = 1.0
    for j in range(H + 1):
        f = feats[e, j]
        f[c.CLS_HOLDS] = 1.0 if has_prev and prev_cls[e, pe] + 1 == j else 0.0
        f[c.CLS_QUALITY] = 1.0 if q == 0 else 0.0
        f[c.CLS_QUALITY + 1] = 1.0 if q == 1 else 0.0
