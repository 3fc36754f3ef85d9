"""The greedy planner: list scheduling on expected points, the ``greedy`` policy's allocation and
the prior of the learned methods that build on it (a public host module, so that no policy
imports another's). The score of a candidate is `ata.model.greedy_score`'s.

The robot that is free first (by the plan so far) takes the open POI with the best rate of net
expected points per second of its time. For each POI it weighs driving autonomously against
being navigated by the free-first highly skilled human (faster, one image quality level up, but
the human is busy for the leg), and classifying onboard against the best human classifier for
that image quality and difficulty. Human time has a price in points per second, so humans go
where they add the most; classifications that could not finish by the horizon are worth 0.
Everything it reads is observable: I, S as the reconstructors give it (`ata.model.plan.seen`),
each human's fatigue belief (`ata.model.plan.fatigue_belief`: with ``identity``, the noisy
fatigue observed now moved along the population line), and the constants the team models
publish (`ata.model.team`).

Reallocation prices the re-tasking cost of docs/model.md (`ata.model.retask`). Where it
is not zero, the planner weighs three candidates by their projected value in expectation
(`ata.model.plan`) net of that cost and of the human time they book: keeping the allocation in
force, repairing it (re-planning only the POIs of robots seen down and the POIs whose kind or
difficulty changed since they were planned, after the work the rest keeps), and the full
re-plan; it keeps the allocation unless a change gains more than it costs.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ata.core.settings import param
from ata.core.state import Allocation, DecisionContext
from ata.model import greedy_score, tables
from ata.model.plan import as_seen, fatigue_belief, plan_start, project, seen, task_attributes
from ata.model.retask import RetaskCost, retask_cost, worth_many
from ata.model.team import RobotConstants

HUMAN_TIME_COST = 0.04
"""The price of a human second in points, greedy's default."""
RATE_OFFSET_S = 300.0
"""Added to robot seconds in greedy's rate (favours value over nearness), its default."""


@dataclass
class GreedySettings:
    """The planner's settings (the ``[greedy]`` table of the ``greedy`` policy)."""

    human_time_cost: float = param(HUMAN_TIME_COST, min=0.0,
                                   help="price of a human second, points")
    rate_offset_s: float = param(RATE_OFFSET_S, min=0.0,
                                 help="added to robot seconds in the rate (favours value over "
                                      "nearness)")
    human_navigators: bool = param(True, help="consider highly skilled human navigators")
    retask_cost: bool = param(True, help="weigh re-tasking costs when reallocating (keep, "
                              "repair or re-plan); false: always re-plan in full")
    replan_in_full: bool = param(True, help="with retask_cost: count the full re-plan "
                                 "among the candidates (false: keep or repair only)")


class GreedyPlanner:
    """Greedy list scheduling, with the memory its reallocation needs: the attributes each POI
    was planned with."""

    def __init__(self, settings: GreedySettings):
        self.s = settings
        self.planned_attrs: np.ndarray | None = None   # (B, P, 2) kind, difficulty planned with
        self.choices = np.zeros(3, dtype=np.int64)      # keep / repair / re-plan, for reports

    def initial(self, ctx: DecisionContext) -> Allocation:
        """The initial allocation of every POI."""
        self.planned_attrs = task_attributes(ctx)
        return plan(ctx, self.s, np.ones(ctx.reallocatable.shape, dtype=bool))

    def reallocate(self, ctx: DecisionContext, active: np.ndarray) -> Allocation:
        """The reallocation of the `active` (B,) scenarios: the full re-plan when re-tasking is
        free (or ignored), else the best of keeping, repairing and re-planning net of its cost."""
        ctx = as_seen(ctx)
        open_ = ctx.reallocatable & active[:, None]
        cost = retask_cost(ctx)
        if not self.s.retask_cost or cost.free or self.planned_attrs is None:
            return plan(ctx, self.s, open_)
        # weigh the scenarios with something to reallocate; the others keep their allocation
        rows = np.nonzero(open_.any(axis=1))[0]
        out = ctx.previous.copy()
        self.choices[0] += open_.shape[0] - rows.size
        if rows.size:
            sub, self.planned_attrs[rows] = self._cheapest(ctx.take(rows), open_[rows], cost,
                                                           self.planned_attrs[rows])
            out.robot[rows], out.navigator[rows], out.classifier[rows] = \
                sub.robot, sub.navigator, sub.classifier
        return out

    def _cheapest(self, ctx: DecisionContext, open_: np.ndarray, cost: RetaskCost,
                  planned_attrs: np.ndarray) -> tuple[Allocation, np.ndarray]:
        """Keep, repair or re-plan in full (if `replan_in_full`), whichever is worth most net
        of its cost; and the attributes each POI is now planned with."""
        prev, S = ctx.previous, seen(ctx)
        attrs = task_attributes(ctx)
        working = S["robots"].col("working") > 0.5
        lost = ~np.take_along_axis(working, prev.robot, axis=1)
        affected = open_ & (lost | (attrs != planned_attrs).any(axis=-1))
        start = plan_start(ctx)
        repair = prev.copy()
        rows = np.nonzero(affected.any(axis=1))[0]
        if rows.size:
            kept = project(start.take(rows), prev.take(rows), (open_ & ~affected)[rows])
            after = dict(robot_free=kept.robot_free, robot_xy=kept.robot_xy,
                         human_free=kept.human_free)
            sub = _plan(ctx.take(rows), self.s, affected[rows], after=after)
            for field in ("robot", "navigator", "classifier"):
                getattr(repair, field)[rows] = np.where(affected[rows], getattr(sub, field),
                                                        getattr(prev, field)[rows])
        candidates = (prev, repair) + ((plan(ctx, self.s, open_),) if self.s.replan_in_full
                                       else ())
        value = worth_many(ctx, start, candidates, open_, cost, self.s.human_time_cost)
        best = np.zeros(value.shape[0], dtype=np.int64)
        # a change must gain more than it costs: keep wins ties
        for i in range(1, len(candidates)):
            best = np.where(value[:, i] > value[np.arange(best.size), best] + 1e-9, i, best)
        self.choices += np.bincount(best, minlength=3)
        out = prev.copy()
        for i, cand in enumerate(candidates):
            rows_i = best == i
            for field in ("robot", "navigator", "classifier"):
                getattr(out, field)[rows_i] = getattr(cand, field)[rows_i]
        replanned = np.where((best == 2)[:, None], open_, np.where((best == 1)[:, None],
                                                                  affected, False))
        return out, np.where(replanned[..., None], attrs, planned_attrs)


def peak_bytes(batch: int, humans: int, robots: int, tasks: int) -> int:
    """An estimate of the planner's peak working memory for a batch of `batch` scenarios, in
    bytes: linear in the POIs, its (batch, robots or humans, POIs) arrays dominate (those of
    `ata.model.plan.project` included, which projects the candidates of a reallocation in one
    batch of up to three plans per scenario), its (batch, POIs) ones come next. Measured with
    tracemalloc at 1040 POIs: about 1.6 KB per scenario and POI on the (a) team (this gives
    2.3), 1.8 KB on the (b) team (this gives 4.1)."""
    per_scenario = 16 * (robots + humans) * tasks + 64 * tasks
    return 8 * batch * per_scenario


def plan(ctx: DecisionContext, s: GreedySettings, open_: np.ndarray) -> Allocation:
    """Plan the triples of the `open_` (B, P) tasks; the others keep their previous triple."""
    rows = np.nonzero(open_.any(axis=1))[0]
    if ctx.previous is not None and rows.size < open_.shape[0]:
        # plan only the scenarios with something to plan; the rest keep their allocation
        out = ctx.previous.copy()
        if rows.size:
            sub = _plan(ctx.take(rows), s, open_[rows])
            out.robot[rows], out.navigator[rows], out.classifier[rows] = \
                sub.robot, sub.navigator, sub.classifier
        return out
    return _plan(ctx, s, open_)


def _plan(ctx: DecisionContext, s: GreedySettings, open_: np.ndarray,
          after: dict[str, np.ndarray] | None = None) -> Allocation:
    """Greedy list scheduling of the `open_` tasks. `after` (robot_free, robot_xy in metres,
    human_free) replaces the starting state: the plan then follows work already planned."""
    I, S = ctx.inherent, seen(ctx)
    B, P = open_.shape
    H, R = ctx.sizes.humans, ctx.sizes.robots
    horizon, now = ctx.clock.horizon_s, ctx.time
    capture_s = ctx.published(RobotConstants).capture_s
    belief = fatigue_belief(ctx, S)
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
            robot_free[cb, cr] = now + d / np.maximum(speed[cb, cr], 1e-9) + capture_s
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
    # flat lookups: (quality, difficulty) -> q * 3 + d; a scenario's row b of an (B, K) array
    # is at b * K in the flattened array (1-D takes are far cheaper than 2-D fancy indexing)
    p_rc, t_bar, quality = tables.P_RC.ravel(), tables.T_BAR.ravel(), tables.QUALITY.ravel()
    kind3 = kind * 3
    points12 = np.tile(tables.POINTS, 4)
    f_d, h_weight = tables.F_D.ravel(), np.arange(H, 0, -1, dtype=np.int16)[:, None, None]
    tx, ty = t_xy[..., 0] * area, t_xy[..., 1] * area
    # where each robot is when free, in metres: a committed robot at its target (the same
    # floats as that task's tx, ty); distances are measured on demand, one (B, P) row a step
    # (no (B, P, P) array, so memory stays linear in P)
    rx, ry = robot_xy[..., 0] * area, robot_xy[..., 1] * area
    if after is not None:
        robot_free = after["robot_free"].copy()
        human_free = after["human_free"].copy()
        rx, ry = after["robot_xy"][..., 0], after["robot_xy"][..., 1]

    # per (robot type, navigator class auto / high skill): each task's (quality, difficulty)
    # index into the 12 flattened combinations and the expected points onboard; rows are
    # picked per step by the chosen robot's type
    combos = [(rt, nc) for rt in (tables.UAV, tables.UGV) for nc in (1, 2)]
    qd_base = np.stack([quality[rt * 6 + kind3 + nc] * 3 + diff for rt, nc in combos], 1)
    ev_onboard = np.stack([tables.expected_points(points, p_rc[qd_base[:, i]])
                           for i in range(len(combos))], axis=1)                # (B, 4, P)
    tbar_task = np.stack([t_bar[qd_base[:, i]] for i in range(len(combos))], axis=1)
    n_opt = 2 if (s.human_navigators and H > 0) else 1
    options = np.arange(n_opt)

    # The loop works on the scenarios still planning (`rows`) and, in each, on its tasks still
    # open (`cols`, (A, C), open ones first in task order): a finished scenario changes nothing
    # and a task no longer open scores -inf, so dropping them changes no choice, ties included.
    # The working set is re-taken when a quarter of it has finished. The per-scenario state
    # below is that of `rows`; `robot_free_all` and `human_free_all` receive it as rows leave.
    robot_free_all, human_free_all, remaining_all = robot_free, human_free, remaining
    rows = np.arange(B)
    cols = np.broadcast_to(np.arange(P), (B, P))
    n_left = remaining.sum(axis=1)
    A, C = B, P
    gain = None      # (H, A, 12) each human's expected points per combination (human_gain)
    touched_b = touched_h = np.zeros(0, dtype=np.int64)   # humans whose time changed since
    for step in range(P):
        active = (n_left > 0) & np.isfinite(robot_free.min(axis=1))
        n_act = int(active.sum())
        if n_act == 0:
            break
        width = int(np.max(n_left, where=active, initial=0))
        if step == 0 or n_act <= 0.75 * A or width <= 0.75 * C:
            gone = rows[~active]
            robot_free_all[gone], human_free_all[gone] = robot_free[~active], human_free[~active]
            keep = np.nonzero(active)[0]
            order = np.argsort(~remaining[keep], axis=1, kind="stable")[:, :width]
            per_row = [x[keep] for x in (robot_free, human_free, hours, eta, lam, high, speed,
                                         r_type, rx, ry, n_left)]
            at = (keep * C)[:, None] + order                  # flat positions of what stays
            per_task = [x.ravel()[at] for x in (remaining, cols, tx, ty)]
            at = (keep * 4 * C)[:, None, None] + (np.arange(4) * C)[:, None] + order[:, None, :]
            per_combo = [x.ravel()[at] for x in (qd_base, ev_onboard, tbar_task)]
            rows, belief = rows[keep], belief.take(keep)
            (robot_free, human_free, hours, eta, lam, high, speed, r_type, rx, ry,
             n_left) = per_row
            remaining, cols, tx, ty = per_task
            qd_base, ev_onboard, tbar_task = per_combo
            if gain is not None:
                gain = gain[:, keep]
                local, stays = np.cumsum(active) - 1, active[touched_b]
                touched_b, touched_h = local[touched_b[stays]], touched_h[stays]
            A, C = rows.size, width
            active = np.ones(A, dtype=bool)
            b_all = np.arange(A)
            # a scenario's row b of an (A, 12) array is at b * 12 in the flattened array
            row12, row_h = (b_all * 12)[:, None], (b_all * H)[:, None]
            qd_flat = qd_base + row12[:, :, None]
        rs = robot_free.argmin(axis=1)
        t_free = robot_free[b_all, rs]
        gap_x = rx[b_all, rs][:, None] - tx
        gap_y = ry[b_all, rs][:, None] - ty
        dist = np.sqrt(gap_x * gap_x + gap_y * gap_y)                          # (A, C)
        v = np.maximum(speed[b_all, rs], 1e-9)[:, None]
        combo0 = r_type[b_all, rs] * 2

        # best human classifier for each (quality, difficulty), given the plan so far
        # (H, A, 12): the humans first, so that the choice among them is an elementwise max
        # over H contiguous slices (argmax along a short axis is several times slower); on
        # ties the first human, as argmax: the largest H - h where net_h is the best. A
        # human's fatigue and expected points per combination change only when the human's
        # time does: after the first step, only those humans' are computed (elementwise, the
        # same numbers as over all)
        if gain is None:
            f_f = belief.ahead(hours, human_free, now)
            gain = greedy_score.human_gain(eta.T[..., None], lam.T[..., None],
                                           f_f.T[..., None], f_d, points12)
        elif touched_b.size:
            tb, th = touched_b, touched_h
            f_f = belief.ahead(hours[tb, th], human_free[tb, th], now, rows=(tb, th))
            gain[th, tb] = greedy_score.human_gain(eta[tb, th, None], lam[tb, th, None],
                                                   f_f[:, None], f_d, points12)
        delay = np.maximum(human_free - t_free[:, None], 0.0).T[:, :, None]
        net_h = greedy_score.human_net(gain, t_bar, delay, s.human_time_cost)
        best = np.maximum.reduce(net_h, axis=0)                                 # (A, 12)
        best_c = H - np.maximum.reduce((net_h == best) * h_weight, axis=0)
        best_net = best.ravel()
        best_free = human_free.ravel()[best_c + row_h].ravel()

        # option 0: the robot drives itself; option 1: the first free highly skilled human
        # navigates (faster, one quality level up, the human busy for the leg); both options
        # at once, (A, O, C)
        arrival = np.empty((A, n_opt, C))
        np.divide(dist, v, out=arrival[:, 0])
        arrival[:, 0] += t_free[:, None]
        arrival[:, 0] += capture_s
        if n_opt == 2:
            hf = np.where(high, human_free, np.inf)
            hn = hf.argmin(axis=1)
            start = np.maximum(t_free, hf[b_all, hn])[:, None]
            leg = arrival[:, 1]
            np.divide(dist, v * tables.SKILL_SPEED[2], out=leg)
            leg += capture_s
            nav_cost = s.human_time_cost * leg
            leg += start                          # inf where no highly skilled human exists
        combo = combo0[:, None] + options                                      # (A, O)
        qd = qd_flat[b_all[:, None], combo]
        finish = np.maximum(arrival, best_free[qd]) + tbar_task[b_all[:, None], combo]
        cost = np.zeros((A, n_opt, C))
        if n_opt == 2:
            cost[:, 1] = nav_cost
        with np.errstate(invalid="ignore"):       # inf - inf for robots that are done
            rate = greedy_score.option_rate(best_net[qd], finish, horizon,
                                            ev_onboard[b_all[:, None], combo], cost,
                                            arrival - t_free[:, None, None], s.rate_offset_s)
        score = np.where(remaining[:, None, :] & (arrival <= horizon), rate,
                         -np.inf).reshape(A, -1)                                # (A, O * C)
        flat = score.argmax(axis=1)
        o_star, p_star = np.divmod(flat, C)
        ok = active & np.isfinite(score[b_all, flat])
        # a robot with nothing it can reach in time is done
        robot_free[b_all[active & ~ok], rs[active & ~ok]] = np.inf
        if not ok.any():
            continue
        # the chosen option's details, for the chosen task only
        b, p, o_b = b_all[ok], p_star[ok], o_star[ok]
        combo = combo0[b] + o_b
        qd = qd_flat[b, combo, p]
        qq = (qd - row12[b, 0]) // 3
        arr = arrival[b, o_b, p]
        c = best_c.ravel()[qd]
        finish = np.maximum(arr, best_free[qd]) + tbar_task[b, combo, p]
        # a human classifier also when none can finish in time but onboard expects a loss:
        # an unclassified POI scores 0
        use_h = np.where(finish <= horizon, best_net[qd], 0.0) > ev_onboard[b, combo, p]
        cls = np.where(use_h, c, -1)
        nav = np.where(o_b == 1, hn[b] if n_opt == 2 else -1, -1)
        gb, gp = rows[b], cols[b, p]
        robot[gb, gp] = rs[b]
        navigator[gb, gp] = nav
        classifier[gb, gp] = cls
        remaining[b, p] = False
        remaining_all[gb, gp] = False
        n_left[b] -= 1
        robot_free[b, rs[b]] = arr
        rx[b, rs[b]], ry[b, rs[b]] = tx[b, p], ty[b, p]
        hn_b = nav >= 0
        human_free[b[hn_b], nav[hn_b]] = arr[hn_b]
        hc = cls >= 0
        human_free[b[hc], cls[hc]] = (np.maximum(arr[hc], human_free[b[hc], cls[hc]])
                                      + tables.T_BAR[qq[hc], diff[gb[hc], gp[hc]]])
        touched_b = np.concatenate([b[hn_b], b[hc]])
        touched_h = np.concatenate([nav[hn_b], cls[hc]])
    robot_free_all[rows], human_free_all[rows] = robot_free, human_free
    robot_free, human_free, remaining = robot_free_all, human_free_all, remaining_all

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
