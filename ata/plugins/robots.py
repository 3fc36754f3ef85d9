"""The robot model: UAV and UGV motion, image quality (Table I), capture, onboard classification
(P_rc), and the hand-over of navigation legs and classifications to humans (docs/model.md).

It owns group ``robots`` (`RobotState`). Work leaves it through queues: a capture to
``tasks.captured`` (``b, p, time, quality, robot, classifier``), a leg that needs its human
navigator to ``humans.navigate`` (``b, r, ready, human, duration, deadline``; ``ready = inf``
withdraws it). A navigator starting the leg comes back through ``robots.leg_started`` (``b, r,
begin, end``), a failure drawn at set-up through ``robots.failure`` (``b, r, time``).

A robot is idle, waiting for its navigator, or on a leg (travel then the capture). A leg's
times are exact; the kernel tick only decides when the next event is looked at.

A robot out on its route (on a leg, or waiting for its navigator to start one) whose next target
a reallocation changes holds for ``replan_s`` before it moves on (docs/model.md): after the
capture in hand (``replan_hold``), or at once when the leg it waited for is withdrawn.
``replans`` counts them.

The order in which a robot visits its POIs is its ``routing`` setting, one of `ROUTINGS`. At
set-up it publishes its constants for the policies, a `RobotConstants` (``sim.publish``).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Callable

import numpy as np

from ata import hookimpl
from ata.core.errors import MissionError
from ata.core.settings import param
from ata.core.queues import run_starts, scatter
from ata.core.state import Allocation, Observation, SimState
from ata.model import tables, team
from ata.model.team import RobotConstants


# -- routing: the order in which a robot visits its POIs. Each routing is a function
# (sim, free) -> (B, R) int: each free robot's next POI, -1 for none.

def nearest(sim: SimState, free: np.ndarray) -> np.ndarray:
    """docs/model.md: a free robot goes to its closest assigned, not yet visited POI that no
    other robot is heading for, from where it is."""
    r, t = sim.group("robots"), sim.group("tasks")
    out = np.full(free.shape, -1, dtype=np.int64)
    fb, fr = np.nonzero(free)
    if fb.size == 0:
        return out
    # open: assigned to this robot, not captured, and no other robot heading there
    open_ = ~r.visited[fb] & (sim.allocation.robot[fb] == fr[:, None])
    tb, tr = np.nonzero(r.target >= 0)
    heading = np.zeros(r.visited.shape, dtype=bool)
    heading[tb, r.target[tb, tr]] = True
    open_ &= ~heading[fb]
    # distances of the open (robot, POI) pairs only, row by row in POI order; the nearest of
    # each row, the first in POI order on ties (as an argmin over the row)
    ei, ep = np.nonzero(open_)
    if ei.size == 0:
        return out
    eb = fb[ei]
    diff = t.pos[eb, ep] - r.pos[eb, fr[ei]]                                   # (m, 2)
    dist = np.hypot(diff[:, 0], diff[:, 1])
    new_row = run_starts(ei)
    starts = np.flatnonzero(new_row)
    nearest_d = np.minimum.reduceat(dist, starts)[np.cumsum(new_row) - 1]
    best = np.minimum.reduceat(np.where(dist == nearest_d, ep, open_.shape[1]), starts)
    out[eb[starts], fr[ei[starts]]] = best
    return out


ROUTINGS: dict[str, Callable[[SimState, np.ndarray], np.ndarray]] = {"nearest": nearest}
"""The routings the robot model's ``routing`` setting may name."""

ROBOT_INHERENT = ("uav", "ugv", "speed")
ROBOT_STATE = ("x", "y", "idleness", "working", "target")


@dataclass
class RobotState:
    """Per scenario and robot, (B, R) unless said."""

    area_m: float
    type: np.ndarray              # tables.UAV / tables.UGV
    speed: np.ndarray             # autonomous speed, m/s
    pos: np.ndarray               # (B, R, 2) m, where the robot stands (or left from)
    failed: np.ndarray
    fail_time: np.ndarray         # inf: never fails
    target: np.ndarray            # the POI it heads for or waits to head for (-1: none)
    leg_start: np.ndarray         # inf when no leg is under way
    leg_end: np.ndarray
    leg_from: np.ndarray          # (B, R, 2)
    leg_nav: np.ndarray           # the leg's navigator (-1: autonomous)
    nav_ready: np.ndarray         # a leg waiting for its human navigator (leg_nav) since
    free_at: np.ndarray           # when it may take its next POI
    parked: np.ndarray            # nothing left to visit
    moved_s: np.ndarray           # seconds of finished legs
    moved_at_epoch: np.ndarray
    idleness: np.ndarray
    replan_hold: np.ndarray       # hold after the capture in hand (docs/model.md)
    replans: np.ndarray
    visited: np.ndarray           # (B, P) bool: POIs captured


class RobotModel:
    """Robots start at the base in the centre; half of them UAVs."""

    @dataclass
    class Settings:
        uav_speed: float = param(team.UAV_SPEED, min=0.0, help="UAV autonomous speed, m/s")
        ugv_speed: float = param(team.UGV_SPEED, min=0.0, help="UGV autonomous speed, m/s")
        uav_fraction: float = param(0.5, min=0.0, max=1.0, help="share of UAVs in the team")
        capture_s: float = param(team.CAPTURE_S, min=0.0,
                                 help="time to capture the image at a POI, s")
        skill_speed: list[float] = param(list(team.SKILL_SPEED), min=0.0,
                                         help="speed factor under a low/medium/high navigator")
        replan_s: float = param(team.REPLAN_S, min=0.0, max=3600.0,
                                help="hold of a robot whose next target a reallocation changes "
                                     "while it is out on its route, s (0: no cost)")
        routing: str = param("nearest", choices=tuple(ROUTINGS),
                             help="order in which a robot visits its POIs")

        def __post_init__(self) -> None:
            # checked with the table, so that the error names the mission file (or --set)
            if len(self.skill_speed) != 3:
                raise MissionError("[robot]", "skill_speed", "needs exactly three factors "
                                   "(low, medium, high skill)")

    def __init__(self, settings: "RobotModel.Settings", mission: object):
        self.settings = settings
        self.skill_speed = np.asarray(settings.skill_speed, dtype=float)
        self.next_targets = ROUTINGS[settings.routing]
        self.constants = RobotConstants(capture_s=settings.capture_s, replan_s=settings.replan_s,
                                        skill_speed=tuple(settings.skill_speed))

    @hookimpl
    def ata_setup(self, sim: SimState) -> None:
        B, R, s = sim.batch_size, sim.sizes.robots, self.settings
        sim.publish(self.constants)
        n_uav = int(round(R * s.uav_fraction))
        kind = np.broadcast_to(np.where(np.arange(R) < n_uav, tables.UAV, tables.UGV),
                               (B, R)).astype(np.int64)
        area = sim.group("tasks").area_m
        pos = np.full((B, R, 2), area / 2.0)
        self.state = sim.own("robots", RobotState(
            area_m=area, type=kind,
            speed=np.where(kind == tables.UAV, s.uav_speed, s.ugv_speed).astype(float),
            pos=pos, failed=np.zeros((B, R), dtype=bool), fail_time=np.full((B, R), np.inf),
            target=np.full((B, R), -1, dtype=np.int64),
            leg_start=np.full((B, R), np.inf),
            leg_end=np.full((B, R), np.inf), leg_from=pos.copy(),
            leg_nav=np.full((B, R), -1, dtype=np.int64),
            nav_ready=np.full((B, R), np.inf), free_at=np.zeros((B, R)),
            parked=np.zeros((B, R), dtype=bool), moved_s=np.zeros((B, R)),
            moved_at_epoch=np.zeros((B, R)), idleness=np.ones((B, R)),
            replan_hold=np.zeros((B, R)), replans=np.zeros((B, R)),
            visited=np.zeros((B, sim.sizes.tasks), dtype=bool)))

    def _take_work(self, sim: SimState) -> None:
        """Apply what the queues hold: failures drawn at set-up, legs a navigator started."""
        r = self.state
        failures = sim.queue("robots.failure").take()
        if failures is not None:
            scatter(r, failures, ("b", "r"), {"fail_time": "time"})
        started = sim.queue("robots.leg_started").take()
        if started is not None:
            scatter(r, started, ("b", "r"), {"leg_start": "begin", "leg_end": "end"})
            r.nav_ready[started["b"], started["r"]] = np.inf

    def _ask_navigator(self, sim: SimState, b: np.ndarray, rr: np.ndarray, ready: Any,
                       human: Any, duration: Any) -> None:
        """Tell the human model of robot rr's leg waiting for its navigator from `ready`
        (``ready = inf``: the leg is withdrawn)."""
        if b.size:
            sim.queue("humans.navigate").put(b=b, r=rr, ready=ready, human=human,
                                             duration=duration,
                                             deadline=self.state.fail_time[b, rr])

    def _withdraw_navigation(self, sim: SimState, waiting: np.ndarray) -> None:
        """Withdraw the legs of the robots in `waiting` ((B, R) bool) from their navigators."""
        b, rr = np.nonzero(waiting)
        self.state.nav_ready[b, rr] = np.inf
        self._ask_navigator(sim, b, rr, np.inf, -1, 0.0)

    @hookimpl
    def ata_inherent(self, sim: SimState, inherent: Observation) -> None:
        self._take_work(sim)
        r = self.state
        feats = np.stack([r.type == tables.UAV, r.type == tables.UGV, r.speed], axis=-1)
        inherent.add("robots", ROBOT_INHERENT, feats.astype(np.float64))

    def position(self, sim: SimState, now: float) -> np.ndarray:
        """True positions at `now`, interpolated along legs under way, (B, R, 2)."""
        r, t = self.state, sim.group("tasks")
        moving = np.isfinite(r.leg_start) & (r.target >= 0)
        if not moving.any():
            return r.pos.copy()
        with np.errstate(invalid="ignore"):   # inf - inf where no leg is under way
            travel = np.maximum(r.leg_end - self.settings.capture_s - r.leg_start, 1e-9)
            frac = np.where(moving, np.clip((now - r.leg_start) / travel, 0.0, 1.0), 0.0)
        dest = np.take_along_axis(t.pos, np.maximum(r.target, 0)[..., None], axis=1)
        return np.where(moving[..., None], r.leg_from + frac[..., None] * (dest - r.leg_from),
                        r.pos)

    def moved_until(self, sim: SimState, now: float) -> np.ndarray:
        """Seconds spent on legs up to `now`, (B, R)."""
        r = self.state
        under_way = np.isfinite(r.leg_start)
        with np.errstate(invalid="ignore"):   # inf - inf where no leg is under way
            partial = np.where(under_way, np.clip(now - r.leg_start, 0.0,
                                                  r.leg_end - r.leg_start), 0.0)
        return r.moved_s + partial

    @hookimpl
    def ata_observe(self, sim: SimState, obs: Observation) -> None:
        r, now = self.state, sim.now
        pos = self.position(sim, now) / r.area_m
        feats = np.stack([pos[..., 0], pos[..., 1], r.idleness, ~r.failed, r.target], axis=-1)
        obs.add("robots", ROBOT_STATE, feats.astype(np.float64))
        # a POI whose leg is under way stays with its robot until captured: the robot's row
        # holds it (a stale row, what it held when last observed)
        on_leg = np.isfinite(r.leg_start) & (r.target >= 0)
        obs.hold("robots", np.where(on_leg, r.target, -1), sim.sizes.tasks)

    @hookimpl
    def ata_allocation_changed(self, sim: SimState, changed: np.ndarray,
                               previous: Allocation | None) -> None:
        r = self.state
        charge = previous is not None and self.settings.replan_s > 0
        out = ~r.failed & (r.target >= 0)          # on a leg, or waiting for its navigator
        on_leg = out & np.isfinite(r.leg_start)
        if charge and out.any():
            before = np.where(on_leg, self._next_after_leg(sim, on_leg, previous), r.target)
        waiting = (r.target >= 0) & ~np.isfinite(r.leg_start)   # for its navigator, or to go
        cancel = waiting & np.take_along_axis(changed, np.maximum(r.target, 0), axis=1)
        r.target[cancel] = -1
        self._withdraw_navigation(sim, cancel & np.isfinite(r.nav_ready))
        r.free_at = np.where(cancel, np.maximum(r.free_at, sim.now), r.free_at)
        r.parked &= ~changed.any(axis=1)[:, None]
        if not (charge and out.any()):
            return
        after = np.where(on_leg, self._next_after_leg(sim, on_leg, sim.allocation), r.target)
        if cancel.any():
            after = np.where(cancel, self.next_targets(sim, cancel), after)
        replan = out & (before != after)
        hold = self.settings.replan_s
        r.replan_hold[replan & on_leg] += hold
        r.free_at = np.where(replan & ~on_leg, r.free_at + hold, r.free_at)
        r.replans += replan
        for b, rr in zip(*np.nonzero(replan)) if sim.trace is not None else ():
            sim.log("replan", float(sim.now), int(b), int(rr), int(before[b, rr]),
                    int(after[b, rr]))

    def _next_after_leg(self, sim: SimState, on_leg: np.ndarray, alloc: Allocation) -> np.ndarray:
        """The routing's choice for each robot on a leg once it has captured, under
        `alloc`: asked as if the robot stood at its target already (its target is excluded, as
        every POI a robot heads for is)."""
        r, t = self.state, sim.group("tasks")
        saved_pos, saved_alloc = r.pos, sim.allocation
        dest = np.take_along_axis(t.pos, np.maximum(r.target, 0)[..., None], axis=1)
        r.pos = np.where(on_leg[..., None], dest, r.pos)
        sim.allocation = alloc
        try:
            return self.next_targets(sim, on_leg).copy()
        finally:
            r.pos, sim.allocation = saved_pos, saved_alloc

    @hookimpl
    def ata_advance(self, sim: SimState, t0: float, t1: float) -> None:
        self._take_work(sim)
        r = self.state
        # Events in time order within the tick: captures due before a failure, dispatches of
        # robots free before they fail, then failures (which abort the legs under way).
        for _ in range(64):
            progressed = False
            done = (r.leg_end <= t1) & (r.leg_end <= r.fail_time)
            if done.any():
                self._capture(sim, *np.nonzero(done))
                progressed = True
            free = (~r.failed & (r.target < 0) & ~r.parked
                    & (r.free_at < np.minimum(t1, r.fail_time)))
            if free.any():
                progressed |= self._dispatch(sim, free, t0)
            newly = ~r.failed & (r.fail_time < t1) & ~((r.leg_end <= t1)
                                                       & (r.leg_end <= r.fail_time))
            if newly.any():
                self._fail(sim, *np.nonzero(newly))
                progressed = True
            if not progressed:
                break

    def _fail(self, sim: SimState, b: np.ndarray, rr: np.ndarray) -> None:
        r = self.state
        ft = r.fail_time[b, rr]
        on_leg = np.isfinite(r.leg_start[b, rr]) & (r.leg_start[b, rr] <= ft)
        with np.errstate(invalid="ignore"):   # inf - inf for robots not on a leg
            travel = np.maximum(r.leg_end[b, rr] - self.settings.capture_s - r.leg_start[b, rr],
                                1e-9)
            frac = np.where(on_leg, np.clip((ft - r.leg_start[b, rr]) / travel, 0, 1), 0.0)
        dest = sim.group("tasks").pos[b, np.maximum(r.target[b, rr], 0)]
        moved_pos = r.leg_from[b, rr] + frac[:, None] * (dest - r.leg_from[b, rr])
        r.pos[b, rr] = np.where(on_leg[:, None], moved_pos, r.pos[b, rr])
        r.moved_s[b, rr] += np.where(on_leg, ft - np.where(on_leg, r.leg_start[b, rr], 0.0), 0.0)
        r.failed[b, rr] = True
        r.target[b, rr] = -1
        r.leg_start[b, rr] = np.inf
        r.leg_end[b, rr] = np.inf
        waiting = np.zeros(r.nav_ready.shape, dtype=bool)
        waiting[b, rr] = np.isfinite(r.nav_ready[b, rr])
        self._withdraw_navigation(sim, waiting)
        for i in range(b.size if sim.trace is not None else 0):
            sim.log("fail", float(ft[i]), int(b[i]), int(rr[i]))

    def _capture(self, sim: SimState, b: np.ndarray, rr: np.ndarray) -> None:
        r, t, h = self.state, sim.group("tasks"), sim.group("humans")
        p = r.target[b, rr]
        te = r.leg_end[b, rr]
        r.moved_s[b, rr] += te - r.leg_start[b, rr]
        r.pos[b, rr] = t.pos[b, p]
        nav = r.leg_nav[b, rr]
        nav_class = np.where(nav < 0, 1, h.skill[b, np.maximum(nav, 0)])
        q = tables.QUALITY[r.type[b, rr], t.true_kind[b, p], nav_class]
        r.visited[b, p] = True
        sim.queue("tasks.captured").put(b=b, p=p, time=te, quality=q, robot=rr,
                                        classifier=sim.allocation.classifier[b, p])
        r.target[b, rr] = -1
        r.leg_start[b, rr] = np.inf
        r.leg_end[b, rr] = np.inf
        r.leg_nav[b, rr] = -1
        r.free_at[b, rr] = te + r.replan_hold[b, rr]
        r.replan_hold[b, rr] = 0.0
        for i in range(b.size if sim.trace is not None else 0):
            sim.log("capture", float(te[i]), int(b[i]), int(rr[i]), int(p[i]), int(q[i]))

    def _dispatch(self, sim: SimState, free: np.ndarray, t0: float) -> bool:
        """Give each free robot its next POI from the routing; start or queue legs."""
        r, t, h = self.state, sim.group("tasks"), sim.group("humans")
        nxt = self.next_targets(sim, free)
        got = free & (nxt >= 0)
        r.parked |= free & (nxt < 0)
        if not got.any():
            return False
        b, rr = np.nonzero(got)
        p = nxt[b, rr]
        nav = sim.allocation.navigator[b, p]
        human = nav >= 0
        factor = np.where(human, self.skill_speed[h.skill[b, np.maximum(nav, 0)]], 1.0)
        dist = np.linalg.norm(t.pos[b, p] - r.pos[b, rr], axis=-1)
        speed = r.speed[b, rr] * factor
        travel = np.where(speed > 0, dist / np.maximum(speed, 1e-12), np.inf)
        duration = travel + self.settings.capture_s
        start = np.maximum(r.free_at[b, rr], t0)
        r.target[b, rr] = p
        r.leg_from[b, rr] = r.pos[b, rr]
        r.leg_nav[b, rr] = nav
        r.leg_start[b, rr] = np.where(human, np.inf, start)
        r.leg_end[b, rr] = np.where(human, np.inf, start + duration)
        r.nav_ready[b, rr] = np.where(human, start, np.inf)
        self._ask_navigator(sim, b[human], rr[human], start[human], nav[human], duration[human])
        return True

    @hookimpl
    def ata_epoch_end(self, sim: SimState, epoch: int) -> None:
        r = self.state
        moved = self.moved_until(sim, sim.now + sim.clock.epoch_s)
        r.idleness = 1.0 - np.clip((moved - r.moved_at_epoch) / sim.clock.epoch_s, 0.0, 1.0)
        r.moved_at_epoch = moved

    @hookimpl
    def ata_episode_end(self, sim: SimState) -> None:
        r = self.state
        sim.record.metrics["robot_failures"] = r.failed.sum(axis=1).astype(float)
        sim.record.metrics["replans"] = r.replans.sum(axis=1)


@hookimpl
def ata_register_components(register) -> None:
    register("robot_model", "robot", RobotModel)
