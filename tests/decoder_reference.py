"""The decoder's steps written with numpy arrays, as the decoder computed them before its steps
were compiled: the reference tests/test_compiled_steps.py holds the compiled steps to, bit for
bit. Each function takes the `Decoder` in place of ``self``."""

from __future__ import annotations

import functools

import numpy as np

from ata.model import greedy_score, tables
from ata.model.tables import MAX_POINTS
from ata.plugins.ata_hrl.decoder import SHORTLIST
from ata.plugins.ata_hrl.inputs import (CLS_FEATURES, NAV_FEATURES, POI_FEATURES,
                                        ROBOT_FEATURES, StepInputs)


def _quiet(method):
    """Numpy's warnings off: episodes whose decoding is over carry dummy choices (inf - inf)."""

    @functools.wraps(method)
    def wrapper(*args, **kwargs):
        with np.errstate(invalid="ignore", divide="ignore"):
            return method(*args, **kwargs)

    return wrapper


def _fill(out: np.ndarray, parts: list) -> np.ndarray:
    """Write `parts` side by side along `out`'s last axis and return `out` (float32): each part
    a column (broadcast to ``out.shape[:-1]``) or a block of columns (``out.ndim`` dimensions),
    cast as ``astype`` casts: the features np.stack and astype would give, without their
    intermediate arrays (the decoder builds four such arrays at each of a decode's steps)."""
    i = 0
    for part in parts:
        if np.ndim(part) == out.ndim:
            w = part.shape[-1]
            out[..., i:i + w] = part
            i += w
        else:
            out[..., i] = part
            i += 1
    assert i == out.shape[-1]
    return out


def _legs_to(dec, e: np.ndarray, p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Travel seconds (n, R) at autonomous speed from each robot's position to POI p of
    plan e (each (n,)), and the autonomous arrival times."""
    gx = dec.tx[e, p][:, None] - dec.robot_xy[e, :, 0]
    gy = dec.ty[e, p][:, None] - dec.robot_xy[e, :, 1]
    travel = np.sqrt(gx * gx + gy * gy) / np.maximum(dec.start.speed[e], 1e-9)
    return travel, dec.robot_free[e] + travel + dec.capture_s

def _greedy_net(dec, q: np.ndarray, d: np.ndarray, pts: np.ndarray, arrive: np.ndarray,
                t_ref: np.ndarray, rows: np.ndarray | None = None
                ) -> tuple[np.ndarray, np.ndarray]:
    """Greedy's net value of each human classifying an image of quality q and difficulty d
    captured at `arrive` (each (E, N)), worth `pts`: its expected points less the price of
    the human's time (the item, and its wait from `t_ref` (E,)); with the finish times.
    Both (E, N, H). `rows`: the plan of each row (`HumanLoad.classification`)."""
    p_g, fin_g, _, _, _, _ = dec.load.classification(q, d, arrive, greedy=True, rows=rows)
    free = dec.human_free if rows is None else dec.human_free[rows]
    delay = np.maximum(free[:, None, :] - t_ref[:, None, None], 0.0)
    net = greedy_score.human_net(tables.expected_points(pts[..., None], p_g),
                                 tables.T_BAR[q, d][..., None], delay,
                                 dec.s.human_time_cost)
    return net, fin_g

def _option_value(dec, net: np.ndarray, fin: np.ndarray, onboard: np.ndarray
                  ) -> np.ndarray:
    """Greedy's worth of each option (E, N) (`greedy_score.option_value`): the best human
    by net value (first on ties), or onboard."""
    best = net.argmax(-1)
    # the best human's entries by flat takes (cheaper than take_along_axis; ravel is a view
    # of these freshly computed arrays)
    at = np.arange(best.size) * net.shape[-1] + best.ravel()
    return greedy_score.option_value(net.ravel().take(at).reshape(best.shape),
                                     fin.ravel().take(at).reshape(best.shape),
                                     dec.horizon, onboard)

@_quiet
def poi_inputs(dec) -> StepInputs:
    """Which POI next: features relative to the robot free first (the greedy robot). They
    are computed for the legal (episode, POI) pairs alone: those left that some robot
    reaches by the horizon and that greedy's prior ranks on the episode's shortlist (its
    `SHORTLIST` best); the others' logits are masked, and their features are zero."""
    E, P, s, e = dec.E, dec.P, dec.s, dec.e
    free = np.where(dec.robot_done, np.inf, dec.robot_free)
    r_ff = free.argmin(axis=1)
    dec.r_ff = r_ff
    lb, lp = np.nonzero(dec.left)
    travel, arr = _legs_to(dec, lb, lp)                                 # (n, R)
    reach = (arr <= dec.horizon) & ~dec.robot_done[lb]
    ok = reach.any(axis=1)
    ce, cp, travel, arr, reach = lb[ok], lp[ok], travel[ok], arr[ok], reach[ok]
    mask = np.zeros((E, P), bool)
    mask[ce, cp] = True
    feats = np.zeros((E, P, POI_FEATURES), np.float32)
    prior = np.full((E, P), -1.0)
    if ce.size == 0:
        return StepInputs(feats, mask, prior, mask.any(axis=1))
    c, rf = np.arange(ce.size), r_ff[ce]
    t_ff = dec.robot_free[e, r_ff][ce]
    arr_ff = arr[c, rf]
    rtype = dec.start.robot_type[ce, rf]
    kind, d, pts = dec.start.kind[ce, cp], dec.start.diff[ce, cp], dec.points[ce, cp]
    q_auto = tables.QUALITY[rtype, kind, 1]
    q_nav = tables.QUALITY[rtype, kind, 2]
    ev_auto = tables.expected_points(pts, tables.P_RC[q_auto, d])
    ev_navq = tables.expected_points(pts, tables.P_RC[q_nav, d])
    # the first free highly skilled navigator, as greedy
    hf = np.where(dec.high, dec.human_free, np.inf)
    hn = hf.argmin(axis=1)
    has_nav = np.isfinite(hf[e, hn])[ce]
    depart = np.maximum(dec.robot_free[e, r_ff], hf[e, hn])[ce]
    leg_nav = travel[c, rf] / tables.SKILL_SPEED[2] + dec.capture_s
    arr_nav = np.where(has_nav, depart + leg_nav, np.inf)
    # greedy's prior: the rate of net points per robot second, for both options at once
    # (the last axis: autonomous, navigated)
    arr_o = np.stack([arr_ff, arr_nav], 1)                              # (n, 2)
    q_o = np.stack([q_auto, q_nav], 1)
    cost = np.stack([np.zeros_like(leg_nav), s.human_time_cost * leg_nav], 1)
    at = np.minimum(arr_o, 1e12)
    ev_on = np.stack([ev_auto, ev_navq], 1)
    value = _option_value(dec, *_greedy_net(dec, q_o, d[:, None], pts[:, None], at, t_ff,
                                                 rows=ce), ev_on) - cost
    rate = greedy_score.rate(value, arr_o - t_ff[:, None], s.rate_offset_s)
    rates = np.where(arr_o <= dec.horizon, rate, -np.inf)
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
    p_h, fin_h, _, _, _, _ = dec.load.classification(q_o, d[:, None], at, rows=ce)
    ev_h = np.where(fin_h <= dec.horizon,
                    tables.expected_points(pts[:, None, None], p_h), -np.inf)
    hum_best = np.maximum(ev_h.max(-1), -MAX_POINTS)
    # competition: how much sooner, and how much better onboard, another robot gets there
    others = reach
    others[c, rf] = False
    other_arr = np.where(others, arr, np.inf).min(axis=1)
    ev_all = np.where(others, dec._ev_onboard[ce, :, cp], -MAX_POINTS).max(axis=1)
    hz = dec.horizon
    left_share = dec.left.sum(1)[ce] / max(P, 1)
    prev_feats = np.zeros((ce.size, 3))
    if dec.previous is not None:
        prev_feats[:, 0] = dec.previous.robot[ce, cp] == rf
        prev_feats[:, 1] = dec.prev_valid[ce, cp]
        prev_feats[:, 2] = dec.previous.classifier[ce, cp] >= 0
    feats[ce, cp] = _fill(np.empty((ce.size, POI_FEATURES), np.float32), [
        np.clip((arr_ff - dec.now) / hz, 0, 2), np.clip((arr_nav - dec.now) / hz, 0, 2),
        ev_auto / MAX_POINTS, ev_navq / MAX_POINTS, hum_best[:, 0] / MAX_POINTS,
        hum_best[:, 1] / MAX_POINTS,
        np.clip(np.where(np.isfinite(rates[:, 0]), rates[:, 0], -0.1) * 20, -2, 2),
        np.clip(np.where(np.isfinite(rates[:, 1]), rates[:, 1], -0.1) * 20, -2, 2),
        np.clip((other_arr - arr_ff) / hz, -2, 2), (ev_all - ev_auto) / MAX_POINTS,
        pts / MAX_POINTS, kind, d / 2.0, np.clip((hz - t_ff) / hz, 0, 1), left_share,
        prev_feats])
    return StepInputs(feats, mask, prior, mask.any(axis=1))

@_quiet
def robot_inputs(dec, p: np.ndarray) -> StepInputs:
    """Which robot for POI p."""
    E, R, e = dec.E, dec.R, dec.e
    travel_p, arr_p = _legs_to(dec, e, p)                               # (E, R)
    mask = ~dec.robot_done & (arr_p <= dec.horizon)
    q = tables.QUALITY[dec.start.robot_type, dec.start.kind[e, p][:, None], 1]
    d = dec.start.diff[e, p][:, None]
    ev = tables.expected_points(dec.points[e, p][:, None], tables.P_RC[q, d])
    is_ff = np.arange(R)[None, :] == dec.r_ff[:, None]
    hz = dec.horizon
    prev_r = np.zeros((E, R))
    if dec.previous is not None:
        prev_r = (np.arange(R)[None, :] == dec.previous.robot[e, p][:, None]).astype(float)
    feats = _fill(np.empty((E, R, ROBOT_FEATURES), np.float32), [
        np.clip((arr_p - dec.now) / hz, 0, 2),
        np.clip((np.where(dec.robot_done, hz, dec.robot_free) - dec.now) / hz, 0, 2),
        travel_p / hz, ev / MAX_POINTS, is_ff, dec.n_assigned / max(dec.P, 1), prev_r,
        dec.start.robot_type, np.eye(4)[q]])
    prior = is_ff.astype(float)
    return StepInputs(feats, mask, prior, mask.any(1))

@_quiet
def nav_inputs(dec, p: np.ndarray, r: np.ndarray) -> StepInputs:
    """Who drives robot r to POI p: autonomous, or one highly skilled human (index h + 1)."""
    E, H, s, e = dec.E, dec.H, dec.s, dec.e
    tr = _distance(dec, e, p, r) / np.maximum(dec.start.speed[e, r], 1e-9)   # (E,)
    t_r = dec.robot_free[e, r]
    rtype = dec.start.robot_type[e, r]
    kind, d = dec.start.kind[e, p], dec.start.diff[e, p]
    pts = dec.points[e, p]
    skill = np.concatenate([np.ones((E, 1), np.int64), dec.start.skill], 1)  # auto: 1
    speed_f = np.where(np.arange(H + 1)[None, :] == 0, 1.0, tables.SKILL_SPEED[skill])
    leg = tr[:, None] / speed_f + dec.capture_s
    free = np.concatenate([t_r[:, None], np.maximum(t_r[:, None], dec.human_free)], 1)
    arrive = free + leg
    q = tables.QUALITY[rtype[:, None], kind[:, None], skill]
    ev_on = tables.expected_points(pts[:, None], tables.P_RC[q, d[:, None]])
    # greedy's rate for each option (F_w = 1; the best human classifier at that quality)
    human = np.arange(H + 1)[None, :] > 0
    value = _option_value(dec, *_greedy_net(dec, 
        q, np.broadcast_to(d[:, None], q.shape), pts[:, None], arrive, t_r), ev_on) \
        - np.where(human, s.human_time_cost * leg, 0.0)
    rate = greedy_score.rate(value, arrive - t_r[:, None], s.rate_offset_s)
    mask = np.concatenate([np.ones((E, 1), bool), dec.high], 1) & (arrive <= dec.horizon)
    mask[:, 0] = True
    hz = dec.horizon
    util = np.concatenate([np.zeros((E, 1)),
                           dec.load.utilisation_at(free[:, None, 1:])[:, 0]], 1)
    prev_n = np.zeros((E, H + 1))
    if dec.previous is not None:
        prev_n = (np.arange(H + 1)[None, :] == dec.previous.navigator[e, p][:, None] + 1)
    feats = _fill(np.empty((E, H + 1, NAV_FEATURES), np.float32), [
        np.clip((arrive - dec.now) / hz, 0, 2), np.clip((free - t_r[:, None]) / hz, 0, 2),
        np.where(human, leg / hz, 0.0), ev_on / MAX_POINTS, np.clip(rate * 20, -2, 2), util,
        prev_n, human[0], np.eye(4)[q]])
    prior = np.where(mask, rate, -1.0)
    return StepInputs(feats, mask, prior, np.ones(E, bool))

@_quiet
def cls_inputs(dec, p: np.ndarray, r: np.ndarray, n: np.ndarray) -> StepInputs:
    """Who classifies POI p's image: onboard (index 0) or a human (h + 1)."""
    E, H, s, e = dec.E, dec.H, dec.s, dec.e
    arrive, q = _arrival(dec, p, r, n)
    d = dec.start.diff[e, p]
    pts = dec.points[e, p]
    # the navigator is busy until the capture: for it the item starts then at the earliest
    p_h, fin, begin, u, f_w, f_f = (x[:, 0] for x in dec.load.classification(
        q[:, None], d[:, None], arrive[:, None]))
    ev_h = np.where(fin <= dec.horizon, tables.expected_points(pts[:, None], p_h), 0.0)
    net_g, fin_g = (x[:, 0] for x in _greedy_net(dec, q[:, None], d[:, None], pts[:, None],
                                                      arrive[:, None], dec.robot_free[e, r]))
    net_g = np.where(fin_g <= dec.horizon, net_g, 0.0)
    t_bar = tables.T_BAR[q, d]
    p_on = tables.P_RC[q, d]
    ev_on = tables.expected_points(pts, p_on)
    hz = dec.horizon
    prev_c = np.zeros((E, H + 1))
    rebrief = np.zeros((E, H))
    if dec.previous is not None:
        prev_c = (np.arange(H + 1)[None, :] == dec.previous.classifier[e, p][:, None] + 1)
        moved = dec.previous.classifier[e, p][:, None] != np.arange(H)[None, :]
        rebrief = (moved & ~dec.touched).astype(float) * (s.rebrief_s > 0)
    # candidate 0 onboard, then the humans, `own` columns each; the last three: whether the
    # candidate classifies in the allocation in force, and the image quality's first two
    # one-hot columns
    own = CLS_FEATURES - 3
    feats = np.empty((E, H + 1, CLS_FEATURES), np.float32)
    _fill(feats[:, 0, :own], [ev_on / MAX_POINTS, p_on, np.clip((arrive - dec.now) / hz, 0, 2),
                              0.0, 0.0, 1.0, 1.0, 0.0, ev_on / MAX_POINTS, 0.0, 0.0])
    _fill(feats[:, 1:, :own], [ev_h / MAX_POINTS, p_h, np.clip((fin - dec.now) / hz, 0, 2),
                               np.clip((begin - arrive[:, None]) / hz, 0, 2), u, f_w, f_f,
                               t_bar[:, None] / hz, net_g / MAX_POINTS, rebrief, 1.0])
    _fill(feats[..., own:], [prev_c, np.eye(4)[q][:, None, :2]])
    prior = np.concatenate([ev_on[:, None], net_g], 1)
    mask = np.ones((E, H + 1), bool)
    return StepInputs(feats, mask, prior, np.ones(E, bool))

def _arrival(dec, p: np.ndarray, r: np.ndarray, n: np.ndarray
             ) -> tuple[np.ndarray, np.ndarray]:
    """Capture time and image quality of robot r at POI p with navigator n (-1 auto)."""
    depart, travel, q = _route(dec, dec.e, p, r, n)
    return depart + travel + dec.capture_s, q



def _distance(dec, e: np.ndarray, p: np.ndarray, r: np.ndarray) -> np.ndarray:
    """Metres from robot r's projected position to POI p, in episodes e (each (n,))."""
    gx = dec.tx[e, p] - dec.robot_xy[e, r, 0]
    gy = dec.ty[e, p] - dec.robot_xy[e, r, 1]
    return np.sqrt(gx * gx + gy * gy)


def _route(dec, e, p, r, n) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Robot r to POI p with navigator n (-1 auto), in episodes e: when it sets off (with
    its navigator free), its travel seconds and the image quality."""
    cls_ = tables.navigator_class(n[:, None], dec.start.skill[e])[:, 0]
    v = dec.start.speed[e, r] * np.where(n >= 0, tables.SKILL_SPEED[cls_], 1.0)
    nav_h = np.maximum(n, 0)
    depart = np.where(n >= 0, np.maximum(dec.robot_free[e, r], dec.human_free[e, nav_h]),
                      dec.robot_free[e, r])
    q = tables.QUALITY[dec.start.robot_type[e, r], dec.start.kind[e, p], cls_]
    return depart, _distance(dec, e, p, r) / np.maximum(v, 1e-9), q


def commit(dec, active: np.ndarray, p: np.ndarray, r: np.ndarray, n: np.ndarray,
           c: np.ndarray) -> None:
    """`Decoder.commit` in array form."""
    s = dec.s
    e = dec.e[active]
    p, r, n, c = p[active], r[active], n[active], c[active]
    if e.size == 0:
        return
    if dec.previous is not None and s.rebrief_s > 0:
        _charge(dec, e, p, n, c)
    depart, travel, q = _route(dec, e, p, r, n)
    leg = travel + dec.capture_s
    arrive = depart + leg
    depart_nav = arrive - leg
    nb = n >= 0
    if nb.any():
        dec.load.book(e[nb], n[nb], depart_nav[nb], arrive[nb])
    cb = c >= 0
    if cb.any():
        ce, ch = e[cb], c[cb]
        begin = np.maximum(arrive[cb], dec.human_free[ce, ch])
        dec.load.book(ce, ch, begin, begin + tables.T_BAR[q[cb], dec.start.diff[ce, p[cb]]])
    dec.robot_free[e, r] = arrive
    dec.robot_xy[e, r] = dec.start.task_xy[e, p]
    dec.n_assigned[e, r] += 1
    dec.robot[e, p], dec.nav[e, p], dec.cls[e, p] = r, n, c
    dec.left[e, p] = False


def _charge(dec, e, p, n, c) -> None:
    """Re-brief (in the projection) every human this choice first changes the work of."""
    prev = dec.previous
    for old, new in ((prev.navigator[e, p], n), (prev.classifier[e, p], c)):
        moved = old != new
        for who in (old, new):
            hit = moved & (who >= 0)
            he, hh = e[hit], who[hit]
            fresh = ~dec.touched[he, hh]
            he, hh = he[fresh], hh[fresh]
            if he.size:
                a = np.maximum(dec.human_free[he, hh], dec.now)
                dec.touched[he, hh] = True
                dec.load.book(he, hh, a, a + dec.s.rebrief_s)
