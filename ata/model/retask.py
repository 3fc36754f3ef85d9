"""The re-tasking cost of docs/model.md (who a reallocation re-tasks, and what that costs),
and what a candidate allocation is worth net of it: the value model greedy weighs its candidates
by, public for the policies that weigh theirs alike."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np

from ata.core.state import Allocation, DecisionContext
from ata.model.plan import PlanStart, project
from ata.model.team import HumanConstants, RobotConstants


@dataclass(frozen=True)
class RetaskCost:
    """What re-tasking costs, from the constants the human and robot models publish."""

    rebrief_s: float = 0.0
    replan_s: float = 0.0
    human_seconds: float = 0.0    # human time a re-brief costs: itself, and the SA it loses

    @property
    def free(self) -> bool:
        return self.rebrief_s <= 0 and self.replan_s <= 0

    @classmethod
    def of(cls, human: HumanConstants, robot: RobotConstants) -> "RetaskCost":
        """The cost of the team whose models published `human` and `robot`."""
        sa_cost = human.sa_drop * human.switch_cost_s if human.rebrief_s > 0 else 0.0
        return cls(rebrief_s=float(human.rebrief_s), replan_s=float(robot.replan_s),
                   human_seconds=float(human.rebrief_s + sa_cost))


def retask_cost(ctx: DecisionContext) -> RetaskCost:
    """The re-tasking cost of the team the context's models published (an error naming the
    missing type when a model published none)."""
    return RetaskCost.of(ctx.published(HumanConstants), ctx.published(RobotConstants))


def retasked_humans(previous: Allocation, current: Allocation, changed: np.ndarray,
                    n_humans: int) -> np.ndarray:
    """(B, H) bool: humans who gain or lose a navigation or classification role on a changed
    task (a robot moved between robots with the same navigator and classifier touches no one)."""
    B = changed.shape[0]
    touched = np.zeros((B, n_humans + 1), dtype=bool)     # column 0: auto / onboard
    rows = np.arange(B)[:, None]
    for old, new in ((previous.navigator, current.navigator),
                     (previous.classifier, current.classifier)):
        moved = changed & (old != new)
        touched[np.broadcast_to(rows, moved.shape)[moved], old[moved] + 1] = True
        touched[np.broadcast_to(rows, moved.shape)[moved], new[moved] + 1] = True
    return touched[:, 1:]


def retasked_robots(previous: Allocation, current: Allocation, changed: np.ndarray,
                    n_robots: int) -> np.ndarray:
    """(B, R) bool: robots that gain or lose a changed task (in expectation, each re-plans)."""
    robots = np.zeros((changed.shape[0], n_robots), dtype=bool)
    cb, cp = np.nonzero(changed)
    robots[cb, previous.robot[cb, cp]] = True
    robots[cb, current.robot[cb, cp]] = True
    return robots


def worth(ctx: DecisionContext, start: PlanStart, cand: Allocation, open_: np.ndarray,
          cost: RetaskCost, human_time_cost: float) -> np.ndarray:
    """(B,) projected points of the `open_` POIs under `cand`, less the price of the human time
    booked (`human_time_cost` points a second) and of the re-tasking that the change from the
    allocation in force costs: re-briefed humans and re-planned robots start late."""
    return worth_many(ctx, start, [cand], open_, cost, human_time_cost)[:, 0]


def worth_many(ctx: DecisionContext, start: PlanStart, cands: Sequence[Allocation],
               open_: np.ndarray, cost: RetaskCost, human_time_cost: float) -> np.ndarray:
    """(B, len(cands)): `worth` of each candidate, projected in one batch of plans. A later
    candidate's row equal to the first candidate's is worth the same, so it is not projected
    again."""
    prev, first, B = ctx.previous, cands[0], open_.shape[0]
    # the plans to project: the first candidate in every scenario, then each later one in the
    # scenarios where it differs from the first; slot: each (scenario, candidate)'s plan
    plans, scenario = [first], [np.arange(B)]
    slot = np.repeat(np.arange(B)[:, None], len(cands), axis=1)
    n = B
    for i, cand in enumerate(cands[1:], start=1):
        differs = ((cand.robot != first.robot) | (cand.navigator != first.navigator)
                   | (cand.classifier != first.classifier)).any(axis=1)
        rows = np.nonzero(differs)[0]
        slot[rows, i] = n + np.arange(rows.size)
        plans.append(cand.take(rows))
        scenario.append(rows)
        n += rows.size
    humans, robots = [], []
    for plan, rows in zip(plans, scenario):
        before = prev if rows.size == B else prev.take(rows)
        changed = open_[rows] & ((plan.robot != before.robot) | (plan.navigator != before.navigator)
                                 | (plan.classifier != before.classifier))
        humans.append(retasked_humans(before, plan, changed, ctx.sizes.humans))
        robots.append(retasked_robots(before, plan, changed, start.robot_free.shape[1]))
    at = np.concatenate(scenario)
    alloc = Allocation(*(np.concatenate([getattr(a, f) for a in plans])
                         for f in ("robot", "navigator", "classifier")))
    humans, robots = np.concatenate(humans), np.concatenate(robots)
    proj = project(start.take(at), alloc, open_[at], human_delay=humans * cost.rebrief_s,
                   robot_delay=robots * cost.replan_s)
    human_s = proj.human_busy_s + humans.sum(axis=1) * cost.human_seconds
    return (proj.value - human_time_cost * human_s)[slot]
