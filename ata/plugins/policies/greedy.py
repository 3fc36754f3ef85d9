"""The greedy allocation: a list-scheduling heuristic on expected points, the bar that every
learned method must clear.

The robot that is free first (by the plan so far) takes the open POI with the best rate of net
expected points per second of its time. For each POI it weighs driving autonomously against
being navigated by the free-first highly skilled human (faster, one image quality level up, but
the human is busy for the leg), and classifying onboard against the best human classifier for
that image quality and difficulty. Human time has a price in points per second, so humans go
where they add the most; classifications that could not finish by the horizon are worth 0.
Everything it reads is observable: I, and the observed S (fatigue is predicted from the
noise-free working time).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ata import hookimpl
from ata.core.settings import param
from ata.core.state import Allocation, DecisionContext
from ata.plugins import tables


class GreedyPolicy:
    """Greedy list scheduling; serves the initial and the reallocation slot."""

    @dataclass
    class Settings:
        human_time_cost: float = param(0.04, min=0.0, help="price of a human second, points")
        rate_offset_s: float = param(20.0, min=0.0,
                                     help="added to robot seconds in the rate (favours value "
                                          "over nearness)")
        human_navigators: bool = param(True, help="consider highly skilled human navigators")
        capture_s: float = param(3.0, min=0.0, help="capture time assumed by the plan")
        fatigue_floor: float = param(0.4, min=0.0, max=1.0, help="fatigue floor assumed")

    def __init__(self, settings: "GreedyPolicy.Settings", mission: object):
        self.s = settings

    @hookimpl
    def ata_initial_allocation(self, ctx: DecisionContext) -> Allocation:
        return plan(ctx, self.s, np.ones(ctx.reallocatable.shape, dtype=bool))

    @hookimpl
    def ata_reallocate(self, ctx: DecisionContext, active: np.ndarray) -> Allocation:
        return plan(ctx, self.s, ctx.reallocatable & active[:, None])


def plan(ctx: DecisionContext, s: "GreedyPolicy.Settings", open_: np.ndarray) -> Allocation:
    """Plan the triples of the `open_` (B, P) tasks; the others keep their previous triple."""
    I, S = ctx.inherent, ctx.observed
    B, P = open_.shape
    H, R = ctx.sizes.humans, ctx.sizes.robots
    horizon, now = ctx.clock.horizon_s, ctx.time
    eta, lam = I["humans"].col("cognitive"), I["humans"].col("expertise")
    skill = I["humans"].col("skill").astype(np.int64)
    r_uav = I["robots"].col("uav") > 0.5
    r_type = np.where(r_uav, tables.UAV, tables.UGV)
    speed = I["robots"].col("speed")
    t_xy = np.stack([I["tasks"].col("x"), I["tasks"].col("y")], axis=-1)
    kind = S["tasks"].col("kind").astype(np.int64) if S is not None else \
        I["tasks"].col("kind").astype(np.int64)
    diff = S["tasks"].col("difficulty").astype(np.int64) if S is not None else \
        I["tasks"].col("difficulty").astype(np.int64)
    points = tables.POINTS[diff]
    area = I.extras["area_m"][:, None]          # positions in I and S are shares of the side

    b_all = np.arange(B)
    robot_free = np.full((B, R), now)
    robot_xy = (np.stack([S["robots"].col("x"), S["robots"].col("y")], -1) if S is not None
                else np.full((B, R, 2), 0.5))
    human_free = np.full((B, H), now)
    hours = S["humans"].col("working_time").copy() if S is not None else np.zeros((B, H))
    prev = ctx.previous
    if S is not None:
        working = S["robots"].col("working") > 0.5
        robot_free[~working] = np.inf
        target = S["robots"].col("target").astype(np.int64)
        committed = (target >= 0) & ~np.take_along_axis(ctx.reallocatable, np.maximum(target, 0),
                                                        axis=1) & working
        if committed.any():
            cb, cr = np.nonzero(committed)
            dest = t_xy[cb, target[cb, cr]]
            d = np.linalg.norm(dest - robot_xy[cb, cr], axis=-1) * area[cb, 0]
            robot_free[cb, cr] = now + d / np.maximum(speed[cb, cr], 1e-9) + s.capture_s
            robot_xy[cb, cr] = dest
        if prev is not None:
            waiting = S["tasks"].col("captured") > 0.5
            wb, wp = np.nonzero(waiting & (prev.classifier >= 0))
            np.add.at(human_free, (wb, prev.classifier[wb, wp]), tables.T_BAR[1, diff[wb, wp]])

    robot = prev.robot.copy() if prev is not None else np.zeros((B, P), np.int64)
    navigator = prev.navigator.copy() if prev is not None else np.full((B, P), -1, np.int64)
    classifier = prev.classifier.copy() if prev is not None else np.full((B, P), -1, np.int64)
    remaining = open_.copy()
    high = skill == 2
    q_idx, d_idx = np.arange(4)[:, None], np.arange(3)[None, :]

    for _ in range(P):
        active = remaining.any(axis=1) & np.isfinite(robot_free.min(axis=1))
        if not active.any():
            break
        rs = robot_free.argmin(axis=1)
        t_free = robot_free[b_all, rs]
        r_xy = robot_xy[b_all, rs]
        dist = np.linalg.norm(t_xy - r_xy[:, None, :], axis=-1) * area          # (B, P)
        v = speed[b_all, rs][:, None]
        rtype = r_type[b_all, rs][:, None]

        # best human classifier for each (quality, difficulty), given the plan so far
        f_f = tables.fatigue(hours + np.maximum(human_free - now, 0) / 3600.0, s.fatigue_floor)
        p_h = 0.5 + (eta * f_f * lam)[:, :, None, None] * tables.F_D[None, None]  # (B,H,4,3)
        delay = np.maximum(human_free - t_free[:, None], 0.0)[:, :, None, None]
        net_h = (tables.POINTS[d_idx] * (2 * p_h - 1) - s.human_time_cost
                 * (tables.T_BAR[None, None] + delay))
        best_c = net_h.argmax(axis=1)                                          # (B, 4, 3)
        best_net = np.take_along_axis(net_h, best_c[:, None], axis=1)[:, 0]   # (B, 4, 3)

        options = []
        # option 0: autonomous driving
        arrive = t_free[:, None] + dist / np.maximum(v, 1e-9) + s.capture_s
        q = tables.QUALITY[rtype, kind, 1]
        options.append((arrive, q, np.full(B, -1), np.zeros((B, P))))
        # option 1: the first free highly skilled human navigates
        if s.human_navigators and H > 0:
            hf = np.where(high, human_free, np.inf)
            hn = hf.argmin(axis=1)
            has = np.isfinite(hf[b_all, hn])
            start = np.maximum(t_free, hf[b_all, hn])[:, None]
            leg = dist / np.maximum(v * tables.SKILL_SPEED[2], 1e-9) + s.capture_s
            arrive_h = np.where(has[:, None], start + leg, np.inf)
            options.append((arrive_h, tables.QUALITY[rtype, kind, 2], np.where(has, hn, -1),
                            s.human_time_cost * leg))

        best_score = np.full((B, P), -np.inf)
        choice = {}
        for o, (arr, qq, nav_h, nav_cost) in enumerate(options):
            ev_on = points * (2 * tables.P_RC[qq, diff] - 1)
            c = best_c[b_all[:, None], qq, diff]
            hum_net = best_net[b_all[:, None], qq, diff]
            finish = np.maximum(arr, human_free[b_all[:, None], c]) + tables.T_BAR[qq, diff]
            hum_net = np.where(finish <= horizon, hum_net, 0.0)
            use_h = hum_net > ev_on
            value = np.maximum(hum_net, ev_on) - nav_cost
            feasible = remaining & (arr <= horizon)
            with np.errstate(invalid="ignore"):   # inf - inf for robots that are done
                rate = value / (arr - t_free[:, None] + s.rate_offset_s)
            score = np.where(feasible, rate, -np.inf)
            better = score > best_score
            best_score = np.where(better, score, best_score)
            choice[o] = (better, np.where(use_h, c, -1), arr, qq)
        p_star = best_score.argmax(axis=1)
        ok = active & np.isfinite(best_score[b_all, p_star])
        # a robot with nothing it can reach in time is done
        robot_free[b_all[active & ~ok], rs[active & ~ok]] = np.inf
        if not ok.any():
            continue
        o_star = np.zeros(B, dtype=np.int64)
        for o in range(1, len(options)):
            o_star = np.where(choice[o][0][b_all, p_star], o, o_star)
        b = b_all[ok]
        p = p_star[ok]
        o_b = o_star[ok]
        cls = np.select([o_b == o for o in choice], [choice[o][1][b, p] for o in choice])
        arr = np.select([o_b == o for o in choice], [choice[o][2][b, p] for o in choice])
        qq = np.select([o_b == o for o in choice], [choice[o][3][b, p] for o in choice])
        nav = np.where(o_b == 1, options[-1][2][b] if len(options) > 1 else -1, -1)
        robot[b, p] = rs[b]
        navigator[b, p] = nav
        classifier[b, p] = cls
        remaining[b, p] = False
        robot_free[b, rs[b]] = arr
        robot_xy[b, rs[b]] = t_xy[b, p]
        hn_b = nav >= 0
        human_free[b[hn_b], nav[hn_b]] = arr[hn_b]
        hc = cls >= 0
        human_free[b[hc], cls[hc]] = (np.maximum(arr[hc], human_free[b[hc], cls[hc]])
                                      + tables.T_BAR[qq[hc], diff[b[hc], p[hc]]])

    if remaining.any():
        # left over: give each to the robot whose plan ends first, driving itself, classified
        # by the least loaded human (a POI nobody reaches scores 0 either way)
        lb, lp = np.nonzero(remaining)
        finite = np.where(np.isfinite(robot_free), robot_free, np.inf)
        fallback = np.where(np.isfinite(finite).any(axis=1), finite.argmin(axis=1), 0)
        robot[lb, lp] = fallback[lb]
        navigator[lb, lp] = -1
        classifier[lb, lp] = human_free.argmin(axis=1)[lb] if H > 0 else -1
    return Allocation(robot, navigator, classifier)


@hookimpl
def ata_register_components(register) -> None:
    register("policy", "greedy", GreedyPolicy)
