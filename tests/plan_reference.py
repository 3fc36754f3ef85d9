"""`ata.model.plan.project` written with numpy arrays, one POI of every scenario a step, as
the host computed it before its loop was compiled: the reference tests/test_compiled_steps.py
holds the compiled projection to, bit for bit."""

from __future__ import annotations

import numpy as np

from ata.core.state import Allocation
from ata.model import tables
from ata.model.plan import PlanStart, Projection, _per_poi


def project(start: PlanStart, alloc: Allocation, tasks: np.ndarray | None = None, *,
            human_delay: np.ndarray | None = None,
            robot_delay: np.ndarray | None = None) -> Projection:
    """Expected outcome of `alloc` for the POIs in `tasks` (default: the open ones).

    The robot free first (among those with POIs left) goes to its nearest POI left; its
    navigator, if any, is busy for the leg from when both are free; its classifier, if human,
    from the capture or when free, whichever is later. ``human_delay`` / ``robot_delay`` (B, H)
    / (B, R) seconds hold members before their first item (a re-brief, a re-plan). The
    capture time and the fatigue belief are the start's.
    """
    capture_s, belief = start.capture_s, start.belief
    B, P = start.points.shape
    H = start.eta.shape[1]
    left = (start.open if tasks is None else tasks & start.open).copy()
    robot_free = start.robot_free.copy()
    if robot_delay is not None:
        robot_free = robot_free + robot_delay
    rx, ry = start.robot_xy[..., 0].copy(), start.robot_xy[..., 1].copy()
    human_free = start.human_free.copy()
    if human_delay is not None:
        human_free = human_free + human_delay
    busy = np.zeros((B, H))
    expected = np.zeros((B, P))
    arrival = np.full((B, P), np.inf)
    finish = np.full((B, P), np.inf)
    owner = alloc.robot
    left &= np.isfinite(np.take_along_axis(robot_free, owner, axis=1))
    b_all = np.arange(B)
    R = robot_free.shape[1]
    count, mine = _robot_lists(left, owner, R)
    mine_left = mine >= 0
    np.maximum(mine, 0, out=mine)
    mine += (np.arange(B) * P).repeat(R)[:, None]                       # flat: b P + p
    task_x, task_y = start.task_xy[..., 0].ravel(), start.task_xy[..., 1].ravel()
    # read through flat indices (b P + p, b R + r: 1-D takes are far cheaper than 2-D indexing)
    speed, quality = _per_poi(start, alloc)
    navigator, classifier = alloc.navigator.ravel(), alloc.classifier.ravel()
    difficulty, points = start.diff.ravel(), start.points.ravel()
    robot_free_at, rx_at, ry_at = robot_free.ravel(), rx.ravel(), ry.ravel()    # views
    expected_at, arrival_at, finish_at = expected.ravel(), arrival.ravel(), finish.ravel()
    for _ in range(P):
        has = count > 0
        if not has.any():
            break
        free = np.where(has, robot_free, np.inf)
        rs = free.argmin(axis=1)
        act = has.any(axis=1)
        b, rr = b_all[act], rs[act]
        br = b * R + rr
        cand = mine[br]                                                      # (A, K)
        gap_x = task_x[cand] - rx_at[br][:, None]
        gap_y = task_y[cand] - ry_at[br][:, None]
        dist = np.where(mine_left[br], np.hypot(gap_x, gap_y), np.inf)
        k = dist.argmin(axis=1)
        a_all = np.arange(b.size)
        bp, d = cand[a_all, k], dist[a_all, k]
        nav = navigator[bp]
        navigated = nav >= 0
        nav_h = np.maximum(nav, 0)
        leg = d / np.maximum(speed[bp], 1e-9) + capture_s
        depart = np.where(navigated, np.maximum(robot_free_at[br], human_free[b, nav_h]),
                          robot_free_at[br])
        arr = depart + leg
        in_time = arr <= start.horizon
        # a navigator is booked for the leg only if it can start it in time
        nb = navigated & (depart < start.horizon)
        human_free[b[nb], nav_h[nb]] = arr[nb]
        busy[b[nb], nav_h[nb]] += leg[nb]
        q, dd, cls = quality[bp], difficulty[bp], classifier[bp]
        by_human = (cls >= 0) & in_time
        ch = np.maximum(cls, 0)
        begin = np.maximum(arr, human_free[b, ch])
        t_bar = tables.T_BAR[q, dd]
        done = np.where(by_human, begin + t_bar, arr)
        # fatigue at the start: the belief at the working hours now, plus the human busy
        # until then; read for the POIs a human classifies alone (elementwise: the same
        # numbers), the others' success the robot's own
        p_ok = tables.P_RC[q, dd]
        hc = np.nonzero(cls >= 0)[0]
        if hc.size:
            kb, kh = b[hc], ch[hc]
            f_f = belief.ahead(start.hours[kb, kh], human_free[kb, kh], start.now, rows=(kb, kh))
            p_ok[hc] = (0.5 + start.eta[kb, kh] * f_f * start.lam[kb, kh]
                        * tables.F_D[q[hc], dd[hc]])
        counted = in_time & (done <= start.horizon)
        expected_at[bp] = np.where(counted, tables.expected_points(points[bp], p_ok), 0.0)
        arrival_at[bp] = np.where(in_time, arr, np.inf)
        finish_at[bp] = np.where(counted, done, np.inf)
        hb = by_human & (begin < start.horizon)
        human_free[b[hb], ch[hb]] = done[hb]
        busy[b[hb], ch[hb]] += t_bar[hb]
        robot_free_at[br] = np.where(in_time, arr, np.inf)
        rx_at[br], ry_at[br] = task_x[bp], task_y[bp]
        mine_left[br, k] = False
        count[b, rr] -= 1
        # a robot whose next leg overruns the horizon is done
        mine_left[br[~in_time]] = False
        count[b[~in_time], rr[~in_time]] = 0
    return Projection(value=expected.sum(axis=1), human_busy_s=busy.sum(axis=1),
                      expected=expected, arrival=arrival, finish=finish,
                      robot_free=robot_free, robot_xy=np.stack([rx, ry], axis=-1),
                      human_free=human_free)


def _robot_lists(left: np.ndarray, owner: np.ndarray, R: int) -> tuple[np.ndarray, np.ndarray]:
    """The POIs left per robot (B, R), and each robot's list of them in POI order, padded with
    -1 (B R, K), K the most any robot has: a projection step measures the chosen robot's
    distance to these only, and argmin keeps POI order, so ties go to the same POI as over
    all P."""
    B = left.shape[0]
    lb, lp = np.nonzero(left)                                  # by scenario, then POI order
    lr = owner[lb, lp]
    count = np.zeros((B, R), dtype=np.int64)
    np.add.at(count, (lb, lr), 1)
    key = lb * R + lr
    by_robot = np.argsort(key, kind="stable")
    slot = np.arange(lb.size) - (np.cumsum(count.ravel()) - count.ravel())[key[by_robot]]
    mine = np.full((B * R, max(int(count.max()) if count.size else 0, 1)), -1, dtype=np.int64)
    mine[key[by_robot], slot] = lp[by_robot]
    return count, mine


