"""The decoder's commit compiled: give each active episode's chosen POI its robot, navigator and
classifier, and move the members' projected state on (`Decoder.commit` says what), one episode
after the other. The host's booking (`ata.model.scalar.book`, `HumanLoad.book`'s formula) in the
order of operations of the array form: the same bits as numpy's (tests/test_compiled_steps.py)."""

from __future__ import annotations

import math

import numpy as np

from ata.model import scalar
from ata.model.scalar import jit


@jit
def _rebrief(e, old, new, now, rebrief_s, touched, cum, booked, free, edges):
    """Where this choice changes who does a POI's work (old to new, -1 nobody), re-brief each
    of the two the first time this plan changes their work; whether anyone was booked."""
    hit = False
    if old != new:
        for h in (old, new):
            if h >= 0 and not touched[e, h]:
                a = max(free[e, h], now)
                touched[e, h] = True
                scalar.book(cum, booked, free, edges, e, h, a, a + rebrief_s)
                hit = True
    return hit


@jit
def commit_step(active, p, r, n, c, robot_free, robot_xy, n_assigned, robot, nav, cls, left,
                touched, prev_nav, prev_cls, charge, now, rebrief_s, capture_s, speed, skill,
                robot_type, kind, diff, task_xy, tab, cum, booked, free, edges):
    """Commit (p, r, n, c) in every active episode; whether anyone's work was booked."""
    booked_any = False
    for e in range(active.shape[0]):
        if active[e]:
            booked_any |= commit_episode(e, p, r, n, c, robot_free, robot_xy, n_assigned, robot,
                                         nav, cls, left, touched, prev_nav, prev_cls, charge, now,
                                         rebrief_s, capture_s, speed, skill, robot_type, kind, diff,
                                         task_xy, tab, cum, booked, free, edges)
    return booked_any


@jit
def commit_episode(e, p, r, n, c, robot_free, robot_xy, n_assigned, robot, nav, cls, left, touched,
                   prev_nav, prev_cls, charge, now, rebrief_s, capture_s, speed, skill, robot_type,
                   kind, diff, task_xy, tab, cum, booked, free, edges):
    """Commit (p[e], r[e], n[e], c[e]) in episode e; whether anyone's work was booked."""
    booked_any = False
    pe, re, ne, ce = p[e], r[e], n[e], c[e]
    if charge:          # re-briefs: the navigator's change first, then the classifier's
        booked_any |= _rebrief(e, prev_nav[e, pe], ne, now, rebrief_s, touched, cum,
                               booked, free, edges)
        booked_any |= _rebrief(e, prev_cls[e, pe], ce, now, rebrief_s, touched, cum,
                               booked, free, edges)
    # the route: when the robot sets off (its navigator free), its travel, the quality
    nav_class = skill[e, ne] if ne >= 0 else 1
    v = speed[e, re] * (tab.skill_speed[nav_class] if ne >= 0 else 1.0)
    depart = max(robot_free[e, re], free[e, ne]) if ne >= 0 else robot_free[e, re]
    q = tab.quality[robot_type[e, re], kind[e, pe], nav_class]
    gx = task_xy[e, pe, 0] - robot_xy[e, re, 0]
    gy = task_xy[e, pe, 1] - robot_xy[e, re, 1]
    travel = math.sqrt(gx * gx + gy * gy) / max(v, 1e-9)
    leg = travel + capture_s
    arrive = depart + leg
    if ne >= 0:
        scalar.book(cum, booked, free, edges, e, ne, arrive - leg, arrive)
        booked_any = True
    if ce >= 0:
        begin = max(arrive, free[e, ce])
        scalar.book(cum, booked, free, edges, e, ce, begin,
                    begin + tab.t_bar[q, diff[e, pe]])
        booked_any = True
    robot_free[e, re] = arrive
    robot_xy[e, re, 0] = task_xy[e, pe, 0]
    robot_xy[e, re, 1] = task_xy[e, pe, 1]
    n_assigned[e, re] += 1
    robot[e, pe], nav[e, pe], cls[e, pe] = re, ne, ce
    left[e, pe] = False
    return booked_any


@jit
def _first_min(values, ok):
    """numpy's argmin of `values` where `ok`, inf elsewhere: the first minimum, a nan first."""
    best, top = 0, values[0] if ok[0] else math.inf
    if top != top:
        return 0
    for i in range(1, values.shape[0]):
        v = values[i] if ok[i] else math.inf
        if v != v:
            return i
        if v < top:
            best, top = i, v
    return best


@jit
def replay_step(todo, owner, nav_b, cls_b, tx, ty, p, r, n, c, left, robot_free, robot_xy,
                n_assigned, robot, nav, cls, touched, prev_nav, prev_cls, charge, now, rebrief_s,
                capture_s, speed, skill, robot_type, kind, diff, task_xy, tab, cum, booked, free,
                edges):
    """`Decoder.replay`'s loop, one episode after the other: commit the POIs in `todo` (E, P)
    with their triples (owner, nav_b, cls_b), the robot free first (of those holding one) going
    to its nearest, at most P rounds (`commit_episode`, the rest its arguments); p, r, n and c
    (E,) working arrays. Whether anyone's work was booked."""
    E, P = todo.shape
    R = robot_free.shape[1]
    has = np.empty(R, np.bool_)
    near = np.empty(P, np.bool_)
    dist = np.empty(P)
    booked_any = False
    for e in range(E):
        for _ in range(P):
            has[:] = False
            for q in range(P):
                if todo[e, q]:
                    has[owner[e, q]] = True
            if not has.any():
                break
            rs = _first_min(robot_free[e], has)
            for q in range(P):
                gx = tx[e, q] - robot_xy[e, rs, 0]
                gy = ty[e, q] - robot_xy[e, rs, 1]
                dist[q] = gx * gx + gy * gy
                near[q] = todo[e, q] and owner[e, q] == rs
            pe = _first_min(dist, near)
            p[e], r[e], n[e], c[e] = pe, rs, nav_b[e, pe], cls_b[e, pe]
            booked_any |= commit_episode(e, p, r, n, c, robot_free, robot_xy, n_assigned, robot,
                                         nav, cls, left, touched, prev_nav, prev_cls, charge,
                                         now, rebrief_s, capture_s, speed, skill, robot_type,
                                         kind, diff, task_xy, tab, cum, booked, free, edges)
            todo[e, pe] = False
    return booked_any
