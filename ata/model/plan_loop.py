"""`ata.model.plan.project`'s loop compiled: each scenario's robots visit their POIs, the robot
free first going to its nearest POI left, one POI a step, with the members' free times, the
humans' booked seconds and the expected points of every POI. The order of operations is the
array formulation's, step for step (and numpy's pairwise sum where the fatigue belief weighs
its curves), so the projection gives the same bits (tests/test_compiled_steps.py). The
formulas are the host's own (`ata.model.scalar`): the fatigue curve, P_hc, the expected
points."""

from __future__ import annotations

import math

import numpy as np

from ata.model import scalar
from ata.model.scalar import jit

INF = math.inf


@jit
def _pairwise_block(a: np.ndarray, lo: int, n: int) -> float:
    """numpy's pairwise sum of a[lo:lo + n], n at most 128: sequential below eight, else
    eight running sums combined pairwise, then the rest."""
    if n < 8:
        res = 0.0
        for i in range(n):
            res += a[lo + i]
        return res
    r = a[lo:lo + 8].copy()
    i = 8
    while i < n - n % 8:
        for j in range(8):
            r[j] += a[lo + i + j]
        i += 8
    res = ((r[0] + r[1]) + (r[2] + r[3])) + ((r[4] + r[5]) + (r[6] + r[7]))
    while i < n:
        res += a[lo + i]
        i += 1
    return res


@jit
def _pairwise(a: np.ndarray, n: int) -> float:
    """numpy's sum of a[:n] (contiguous), operation for operation: a block of at most 128
    values summed as `_pairwise_block`, a longer one halved (at a multiple of eight) and the
    halves' sums added; numpy's recursion, walked with a stack of (start, length, stage)."""
    if n <= 128:
        return _pairwise_block(a, 0, n)
    los = np.zeros(64, np.int64)
    ns = np.zeros(64, np.int64)
    stage = np.zeros(64, np.int64)
    left = np.zeros(64)
    top, ret = 0, 0.0
    ns[0] = n
    while top >= 0:
        lo, m = los[top], ns[top]
        if m <= 128:
            ret = _pairwise_block(a, lo, m)
            top -= 1
            continue
        n2 = m // 2
        n2 -= n2 % 8
        if stage[top] == 0:                  # the left half first
            stage[top] = 1
            top += 1
            los[top], ns[top], stage[top] = lo, n2, 0
        elif stage[top] == 1:                # its sum is back: the right half
            left[top] = ret
            stage[top] = 2
            top += 1
            los[top], ns[top], stage[top] = lo + n2, m - n2, 0
        else:                                # both back: their sum, to the caller
            ret = left[top] + ret
            top -= 1
    return ret


@jit
def belief_ahead(onset, slope, weight, offset, floor, hours, free, now, b, h, scratch):
    """`FatigueBelief.ahead` of human h of scenario b: the estimate of F_f at the working
    hours now plus the time booked until `free`."""
    t = hours + max(free - now, 0.0) / 3600.0
    K = weight.shape[2]
    if K == 1:
        f = scalar.individual(t, onset[b, h, 0], slope[b, h, 0], floor)
    else:
        for k in range(K):
            scratch[k] = weight[b, h, k] * scalar.individual(t, onset[b, h, k], slope[b, h, k],
                                                              floor)
        f = _pairwise(scratch, K)
    return min(max(f + offset[b, h], floor), 1.0)


@jit
def project_loop(left, owner, robot_free, rx, ry, human_free, task_x, task_y, speed, quality,
                 navigator, classifier, diff, points, hours, eta, lam, onset, slope, weight,
                 offset, floor, now, horizon, capture_s, tab, busy, expected,
                 arrival, finish):
    """Project every scenario's allocation (`ata.model.plan.project`); robot_free, rx, ry and
    human_free are updated in place, busy, expected, arrival and finish filled (zeros, zeros,
    inf, inf on entry). `left` (B, P): the POIs to project, each robot able to start."""
    B, P = left.shape
    R = robot_free.shape[1]
    count = np.zeros(R, np.int64)
    mine = np.empty(P, np.bool_)
    scratch = np.empty(max(weight.shape[2], 1))
    for b in range(B):
        count[:] = 0
        for p in range(P):
            mine[p] = left[b, p]
            if mine[p]:
                count[owner[b, p]] += 1
        while True:
            # the robot free first among those with POIs left (the first on ties)
            rr, best, any_left = 0, INF, False
            for r in range(R):
                if count[r] > 0:
                    if not any_left or robot_free[b, r] < best:
                        best, rr = robot_free[b, r], r
                    any_left = True
            if not any_left:
                break
            # its nearest POI left (the first in POI order on ties)
            bp, d = -1, INF
            for p in range(P):
                if mine[p] and owner[b, p] == rr:
                    dist = math.hypot(task_x[b, p] - rx[b, rr], task_y[b, p] - ry[b, rr])
                    if bp < 0 or dist < d:
                        bp, d = p, dist
            nav = navigator[b, bp]
            leg = d / max(speed[b, bp], 1e-9) + capture_s
            depart = max(robot_free[b, rr], human_free[b, nav]) if nav >= 0 else robot_free[b, rr]
            arr = depart + leg
            in_time = arr <= horizon
            # a navigator is booked for the leg only if it can start it in time
            if nav >= 0 and depart < horizon:
                human_free[b, nav] = arr
                busy[b, nav] += leg
            q, dd, cls = quality[b, bp], diff[b, bp], classifier[b, bp]
            by_human = cls >= 0 and in_time
            ch = max(cls, 0)
            begin = max(arr, human_free[b, ch])
            tb = tab.t_bar[q, dd]
            done = begin + tb if by_human else arr
            p_ok = tab.p_rc[q, dd]
            if cls >= 0:
                f_f = belief_ahead(onset, slope, weight, offset, floor, hours[b, ch],
                                   human_free[b, ch], now, b, ch, scratch)
                p_ok = scalar.human_success(eta[b, ch], lam[b, ch], f_f, 1.0, tab.f_d[q, dd])
            counted = in_time and done <= horizon
            expected[b, bp] = scalar.expected_points(points[b, bp], p_ok) if counted else 0.0
            arrival[b, bp] = arr if in_time else INF
            finish[b, bp] = done if counted else INF
            if by_human and begin < horizon:
                human_free[b, ch] = done
                busy[b, ch] += tb
            robot_free[b, rr] = arr if in_time else INF
            rx[b, rr], ry[b, rr] = task_x[b, bp], task_y[b, bp]
            mine[bp] = False
            count[rr] -= 1
            if not in_time:
                # a robot whose next leg overruns the horizon is done
                for p in range(P):
                    if owner[b, p] == rr:
                        mine[p] = False
                count[rr] = 0
