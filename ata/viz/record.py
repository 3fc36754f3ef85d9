"""Recording one scenario: a passive component attached to a `Simulation` only when a trace is
wanted, and the `Episode` it yields.

Off, nothing of this module runs: no component is registered, no hook is called, `sim.trace`
stays None, and the kernel and the team models do exactly what they do in `ata run`. On
(`replay`), the simulation keeps its event trace (`sim.trace`: work items, re-briefs, captures,
failures, re-plans, allocations) and the `Recorder` adds, from hooks that run after every other
component's (``trylast``):

* each tick, every human's true working time, utilisation over the trailing window and SA, as
  the human model would report them in S at that moment, and the robots that start waiting for a
  navigator;
* at a reallocation, the waiting robots whose request it withdrew;
* each epoch, the observed human state after the injectors;
* at the end of the episode, the team models' arrays.

`Episode.build` turns these into legs, waits and work items with exact times. A robot's leg is
rebuilt from its capture (or failure) time, its origin (the base or its previous capture) and its
speed, as the robot model computed it: start = end - distance / speed - capture time. The
recorder reads the groups the team models declare (``tasks``, ``humans``, ``robots``, with the
fields of the built-in models' states) and the constants they publish (`HumanConstants`,
`RobotConstants`), through the domain library's formulas; it writes nothing to the simulation,
so a recorded scenario's results are those of the same scenario run without it.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ata import hookimpl
from ata.core.kernel import Simulation
from ata.core.mission import Mission
from ata.core.registry import Register
from ata.core.state import Allocation, Observation, SimState
from ata.model import fatigue, tables
from ata.model.team import HumanConstants, RobotConstants

RIGHT, WRONG, UNCLASSIFIED, UNVISITED = 0, 1, 2, 3
OUTCOMES = ("right", "wrong", "captured, not classified", "not visited")
"""A POI's outcome by the horizon, by code."""


class Recorder:
    """What the event trace does not hold, recorded for every scenario of a batch.

    Created by `Recorder.attach`, which registers it into the simulation's plugin manager; every
    hook runs after those of the mission's components and only reads the state.
    """

    def __init__(self, simulation: Simulation):
        self.humans: HumanConstants | None = None    # what the team models published
        self.robots: RobotConstants | None = None
        self.times: list[float] = []            # tick boundaries, s
        self.hours: list[np.ndarray] = []       # (B, H) working time at each, h
        self.util: list[np.ndarray] = []        # (B, H) utilisation over the trailing window
        self.sa: list[np.ndarray] = []          # (B, H) situational awareness
        self.seen: list[np.ndarray] = []        # (B, H, F) observed human state at each epoch
        self.seen_names: tuple[str, ...] = ()
        self.waits: list[tuple[int, int, int, int, float]] = []   # (b, robot, poi, human, since)
        self.withdrawn: list[tuple[int, int, float]] = []         # (b, robot, time)
        self.final: dict[str, dict[str, Any]] = {}
        self._ready: np.ndarray | None = None   # robots.nav_ready at the last look

    @classmethod
    def attach(cls, simulation: Simulation) -> "Recorder":
        """A recorder registered into `simulation` (before it runs); `simulation.sim.trace` must
        be on."""
        if simulation.sim.trace is None:
            raise ValueError("the recorder needs the simulation's trace: "
                             "Simulation(..., trace=True)")
        recorder = cls(simulation)
        simulation.pm.register(recorder, name="recorder")
        return recorder

    def _sample(self, sim: SimState, time: float) -> None:
        """The humans' true working time, utilisation and SA at a tick boundary."""
        h, s, tick = sim.group("humans"), self.humans, sim.clock.tick_s
        self.times.append(time)
        self.hours.append(tables.working_hours(h.t0_h, h.busy_ticks, time, tick))
        self.util.append(tables.utilisation(h.busy_ticks, time, tick, s.window_s))
        self.sa.append(tables.awareness(h.sa, h.sa_time, time, s.sa_recovery_per_min))

    @hookimpl(trylast=True)
    def ata_setup(self, sim: SimState) -> None:
        self.humans = sim.published(HumanConstants)
        self.robots = sim.published(RobotConstants)
        self._ready = np.full((sim.batch_size, sim.sizes.robots), np.inf)
        self._sample(sim, 0.0)

    @hookimpl(trylast=True)
    def ata_inject(self, sim: SimState, obs: Observation) -> None:
        table = obs["humans"]
        self.seen_names = table.names
        self.seen.append(table.features.copy())

    @hookimpl(trylast=True)
    def ata_allocation_changed(self, sim: SimState, changed: np.ndarray,
                               previous: Allocation | None) -> None:
        ready = sim.group("robots").nav_ready
        for b, rr in zip(*np.nonzero(np.isfinite(self._ready) & ~np.isfinite(ready))):
            self.withdrawn.append((int(b), int(rr), float(sim.now)))
        self._ready = ready.copy()

    @hookimpl(trylast=True)
    def ata_advance(self, sim: SimState, t0: float, t1: float) -> None:
        # A robot asks for its navigator in the robot phase of a tick, and the human phase of a
        # later tick takes it: every wait is open at the end of the tick it began in.
        r = sim.group("robots")
        new = np.isfinite(r.nav_ready) & (r.nav_ready != self._ready)
        for b, rr in zip(*np.nonzero(new)):
            self.waits.append((int(b), int(rr), int(r.target[b, rr]), int(r.leg_nav[b, rr]),
                               float(r.nav_ready[b, rr])))
        self._ready = r.nav_ready.copy()
        self._sample(sim, t1)

    @hookimpl(trylast=True)
    def ata_episode_end(self, sim: SimState) -> None:
        self.final = {name: {k: np.array(v, copy=True)
                             for k, v in sim.group(name).as_dict().items()}
                      for name in ("tasks", "robots", "humans")}


@dataclass(frozen=True)
class Leg:
    """A robot's trip to a POI (travel, then the capture), or its part before the robot failed."""

    robot: int
    poi: int                         # -1 for a leg cut short by a failure
    navigator: int                   # a human, or -1: autonomous
    start: float                     # s
    end: float                       # s: the capture's end, or the failure
    origin: tuple[float, float]      # m
    dest: tuple[float, float]        # m: the POI, or where the robot failed
    captured: bool


@dataclass(frozen=True)
class Wait:
    """A robot waiting, idle, for its human navigator to take a leg."""

    robot: int
    poi: int
    navigator: int
    start: float
    end: float
    how: str                         # "taken", "withdrawn" (a reallocation), "failed", "horizon"


@dataclass(frozen=True)
class Work:
    """A human's busy interval: a navigation leg, a classification, or a re-brief.

    [start, begin) is the SA switch cost paid before the item (empty when there is none)."""

    human: int
    kind: str                        # "nav", "classify", "rebrief"
    start: float
    begin: float
    end: float
    robot: int                       # the robot navigated, or whose image it is; -1: re-brief
    poi: int                         # the POI classified; -1 otherwise


@dataclass
class Episode:
    """One scenario, replayed: what each member did and when, and how it scored. Times in s,
    positions in m; kinds, difficulties, qualities, robot types and skills coded as in
    `ata.model.tables`."""

    mission: str
    seed: int | str               # the root seed, or the hash of a secret one
    scenario: int
    setting: str
    uncertainty: str
    horizon_s: float
    epoch_s: float
    area_m: float
    base: tuple[float, float]
    score: float
    upper_bound: float
    r_perf: np.ndarray               # (T,) points per epoch
    # POIs (P,)
    poi_pos: np.ndarray              # (P, 2)
    est_kind: np.ndarray
    est_diff: np.ndarray
    true_kind: np.ndarray
    true_diff: np.ndarray
    reveal_time: np.ndarray          # when a changed attribute shows (inf: unchanged)
    capture_time: np.ndarray         # inf: not captured
    quality: np.ndarray              # -1: not captured
    classified_at: np.ndarray        # inf: not classified by the horizon
    classifier: np.ndarray           # the human who classified it, -1: onboard or nobody
    gain: np.ndarray                 # points won (+) or lost (-); 0 when not classified
    # robots (R,)
    robot_type: np.ndarray
    fail_time: np.ndarray            # inf: never fails
    legs: list[Leg]
    waits: list[Wait]
    replans: list[tuple[float, int]]  # (time, robot)
    # humans (H,)
    skill: np.ndarray
    work: list[Work]
    times: np.ndarray                # (n_ticks + 1,) tick boundaries
    working_h: np.ndarray            # (H, n_ticks + 1) true working time, h
    fatigue: np.ndarray              # (H, n_ticks + 1) true F_f
    utilisation: np.ndarray          # (H, n_ticks + 1) busy share of the trailing window
    sa: np.ndarray                   # (H, n_ticks + 1)
    epoch_times: np.ndarray          # (T,)
    fatigue_seen: np.ndarray         # (H, T) F_f in the observed S (after the injectors)
    window_s: float
    reallocations: list[tuple[int, int]] = field(default_factory=list)   # (epoch, POIs changed)

    @property
    def outcome(self) -> np.ndarray:
        """(P,) RIGHT, WRONG, UNCLASSIFIED (captured, not classified) or UNVISITED."""
        classified = np.isfinite(self.classified_at)
        return np.where(classified, np.where(self.gain > 0, RIGHT, WRONG),
                        np.where(np.isfinite(self.capture_time), UNCLASSIFIED, UNVISITED))

    @property
    def changed(self) -> np.ndarray:
        """(P,) bool: the POI's true kind or difficulty differs from the estimate."""
        return (self.true_kind != self.est_kind) | (self.true_diff != self.est_diff)

    @classmethod
    def build(cls, simulation: Simulation, recorder: Recorder, b: int,
              scenario: int) -> "Episode":
        """The episode of scenario `b` of a batch that has run with `recorder` attached."""
        m, sim = simulation.mission, simulation.sim
        clock, rec = sim.clock, sim.record
        t, r, h = (recorder.final[k] for k in ("tasks", "robots", "humans"))
        events = [e for e in sim.trace if _scenario_of(e) == b]
        horizon = clock.horizon_s
        classified = rec.task_epoch[b] >= 0
        # a captured POI is never reallocated: its classifier is the one in the last epoch
        classifier = rec.allocations[b, -1, :, 2].astype(np.int64)
        base = (float(t["area_m"]) / 2.0, float(t["area_m"]) / 2.0)   # robots start there
        legs = _legs(events, t, r, h, b, base, recorder.robots)
        waits = _waits(recorder, b, legs, r["fail_time"][b], horizon)
        work = _work(events, t, b, legs)
        hours = np.stack(recorder.hours)[:, b].T
        floor = recorder.humans.fatigue_floor
        seen = np.stack(recorder.seen)[:, b]
        allocs = rec.allocations[b]
        changes = [(int(k), int((allocs[k] != allocs[k - 1]).any(axis=1).sum()))
                   for k in np.flatnonzero(rec.reallocated[b])]
        return cls(
            mission=m.settings.name, seed=m.seed_label, scenario=int(scenario),
            setting=m.settings.setting, uncertainty=m.settings.uncertainty, horizon_s=horizon,
            epoch_s=clock.epoch_s, area_m=float(t["area_m"]),
            base=base,
            score=float(rec.total[b]), upper_bound=float(rec.upper_bound[b]),
            r_perf=rec.r_perf[b].copy(),
            poi_pos=t["pos"][b], est_kind=t["est_kind"][b], est_diff=t["est_diff"][b],
            true_kind=t["true_kind"][b], true_diff=t["true_diff"][b],
            reveal_time=t["reveal_time"][b], capture_time=t["capture_time"][b],
            quality=t["quality"][b],
            classified_at=np.where(classified, t["classified_at"][b], np.inf),
            classifier=np.where(classified, classifier, -1), gain=rec.task_gain[b].copy(),
            robot_type=r["type"][b], fail_time=r["fail_time"][b], legs=legs, waits=waits,
            replans=[(e[1], e[3]) for e in events if e[0] == "replan"],
            skill=h["skill"][b], work=work, times=np.asarray(recorder.times),
            working_h=hours, fatigue=fatigue.individual(
                hours, h["fatigue_onset"][b][:, None], h["fatigue_slope"][b][:, None], floor),
            utilisation=np.stack(recorder.util)[:, b].T, sa=np.stack(recorder.sa)[:, b].T,
            epoch_times=np.arange(clock.n_epochs) * clock.epoch_s,
            fatigue_seen=seen[:, :, recorder.seen_names.index("fatigue")].T,
            window_s=recorder.humans.window_s, reallocations=changes)


def _scenario_of(event: tuple) -> int | None:
    """The batch row an event of sim.trace is about (None for the batch-wide ones)."""
    kind = event[0]
    if kind == "start":
        return event[3]
    if kind in ("rebrief", "replan", "fail", "capture"):
        return event[2]
    return None


def _legs(events: list[tuple], t: dict, r: dict, h: dict, b: int, base: tuple[float, float],
          settings: RobotConstants) -> list[Leg]:
    """Every robot's legs, in order, from its captures and its failure."""
    skill_speed = np.asarray(settings.skill_speed, dtype=float)
    nav_end = {(e[5], e[6]): e[4] for e in events if e[0] == "start" and e[1] == "nav"}
    legs: list[Leg] = []

    def speed(robot: int, nav: int) -> float:
        factor = skill_speed[h["skill"][b, nav]] if nav >= 0 else 1.0
        return float(r["speed"][b, robot] * factor)

    for robot in range(r["type"].shape[1]):
        pos = np.asarray(base)
        for e in events:
            if e[0] == "capture" and e[3] == robot:
                end, poi = e[1], e[4]
                nav = nav_end.get((robot, end), -1)
                dest = t["pos"][b, poi]
                start = end - np.hypot(*(dest - pos)) / speed(robot, nav) - settings.capture_s
                # max: a first leg rebuilt from its end can land a rounding error before 0
                legs.append(Leg(robot, poi, nav, max(0.0, float(start)), end, _xy(pos),
                                _xy(dest), True))
                pos = dest
            elif e[0] == "fail" and e[3] == robot:
                dest = r["pos"][b, robot]
                dist = float(np.hypot(*(dest - pos)))
                if dist > 0:
                    navs = [x[4] for x in events if x[0] == "start" and x[1] == "nav"
                            and x[5] == robot and x[2] <= e[1] < x[6]]
                    nav = navs[0] if navs else -1
                    start = e[1] - dist / speed(robot, nav)
                    legs.append(Leg(robot, -1, nav, float(start), e[1], _xy(pos), _xy(dest),
                                    False))
    return legs


def _waits(recorder: Recorder, b: int, legs: list[Leg], fail_time: np.ndarray,
           horizon: float) -> list[Wait]:
    """Each wait ends when its leg begins, when a reallocation withdraws it, when the robot
    fails, or at the horizon, whichever comes first."""
    out = []
    for wb, robot, poi, human, since in recorder.waits:
        if wb != b:
            continue
        ends = [(min([leg.start for leg in legs if leg.robot == robot and leg.start >= since
                      and leg.navigator >= 0], default=np.inf), "taken"),
                (min([w for x, rr, w in recorder.withdrawn if x == b and rr == robot
                      and w >= since], default=np.inf), "withdrawn"),
                (float(fail_time[robot]) if fail_time[robot] >= since else np.inf, "failed"),
                (horizon, "horizon")]
        end, how = min(ends, key=lambda x: x[0])
        out.append(Wait(robot, poi, human, since, float(end), how))
    return out


def _work(events: list[tuple], t: dict, b: int, legs: list[Leg]) -> list[Work]:
    """The humans' work items and re-briefs, with the SA switch cost split off."""
    navigated = {(leg.robot, leg.end): leg for leg in legs if leg.navigator >= 0}
    cut = {leg.robot: leg for leg in legs if not leg.captured}
    captured_by = {e[4]: e[3] for e in events if e[0] == "capture"}
    out = []
    for e in events:
        if e[0] == "start" and e[1] == "nav":
            _, _, start, _, human, robot, end = e
            # a leg cut short by a failure: the human stays booked to its planned end
            leg = navigated.get((robot, end)) or cut.get(robot)
            begin = leg.start if leg is not None and leg.navigator == human else start
            out.append(Work(human, "nav", start, max(start, begin), end, robot, -1))
        elif e[0] == "start" and e[1] == "classify":
            _, _, start, _, human, poi, end = e
            begin = float(end - tables.T_BAR[t["quality"][b, poi], t["true_diff"][b, poi]])
            out.append(Work(human, "classify", start, max(start, begin), end,
                            captured_by.get(poi, -1), poi))
        elif e[0] == "rebrief":
            _, start, _, human, end = e
            out.append(Work(human, "rebrief", start, start, end, -1, -1))
    return out


def _xy(p: np.ndarray) -> tuple[float, float]:
    return float(p[0]), float(p[1])


def replay(mission: Mission, registry: Register, scenario: int) -> Episode:
    """Run scenario `scenario` of `mission` alone, a batch of one, with the recorder attached.

    Scenario i's numbers depend on (seed, i) alone, so its results are those of the same
    scenario in any run of the mission."""
    simulation = Simulation(mission, registry, [scenario], trace=True)
    recorder = Recorder.attach(simulation)
    simulation.run()
    return Episode.build(simulation, recorder, 0, scenario)
