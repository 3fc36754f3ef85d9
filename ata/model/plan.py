"""Plans in expectation: where a plan starts from at a decision epoch, and what a fixed
allocation is expected to earn from there (the projection model of the allocation policies).

Everything here reads what a policy may read: the inherent information I, the state S as the
reconstructors give it (`seen`: each group's rows from ``ctx.reconstructed[group]`` where a
reconstructor wrote them, else the observed S), their estimates, and the model's tables; nothing
reads the scenario's random streams. The projection is the model *in expectation on those
estimates*: robots visit their POIs in nearest-neighbour order at their nominal speeds, humans
take work first come first served, workload is taken as 1, and a classification that cannot end
by the horizon earns nothing. Fatigue is each human's `FatigueBelief` (`fatigue_belief`) read at
the working hours the plan has booked: a reconstructor's estimate of the human's curve where one
gave it (``fatigue.BELIEF_KEYS``), else the fatigue of S now moved along the population line
(with ``identity``, the raw noisy observation: the model hides the individual curves).
The capture time and the fatigue floor are the ones the team models publish (`ata.model.team`).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from ata.core.state import Allocation, DecisionContext, EntityTable, Observation
from ata.model import fatigue, tables
from ata.model.fatigue import FatigueBelief
from ata.model.plan_loop import project_loop
from ata.model.team import CAPTURE_S, FATIGUE_FLOOR, HumanConstants, RobotConstants


@dataclass
class PlanStart:
    """The state a plan starts from, per scenario (B) and member or POI, and the team's
    constants a projection from it assumes. Times in seconds, positions in metres;
    ``robot_free`` is inf for a robot observed down."""

    now: float
    horizon: float
    task_xy: np.ndarray        # (B, P, 2)
    kind: np.ndarray           # (B, P) current estimate
    diff: np.ndarray           # (B, P) current estimate
    points: np.ndarray         # (B, P)
    open: np.ndarray           # (B, P) not captured and no leg under way to it
    eta: np.ndarray            # (B, H)
    lam: np.ndarray            # (B, H)
    skill: np.ndarray          # (B, H) int
    hours: np.ndarray          # (B, H) working hours now
    human_free: np.ndarray     # (B, H)
    robot_type: np.ndarray     # (B, R) int
    speed: np.ndarray          # (B, R)
    robot_free: np.ndarray     # (B, R)
    robot_xy: np.ndarray       # (B, R, 2) where each robot will be free
    robot_at: np.ndarray       # (B, R) the POI a committed leg ends at (-1: none)
    capture_s: float = CAPTURE_S
    fatigue_floor: float = FATIGUE_FLOOR
    belief: FatigueBelief | None = None
    """What the plan believes of each human's fatigue curve; None: the population line."""

    def __post_init__(self) -> None:
        if self.belief is None:
            shape = self.hours.shape
            self.belief = FatigueBelief.exact(np.full(shape, fatigue.ONSET_H),
                                              np.full(shape, fatigue.SLOPE_PER_H),
                                              self.fatigue_floor)

    @property
    def batch(self) -> int:
        return self.points.shape[0]

    def take(self, rows: np.ndarray) -> "PlanStart":
        """The start of a sub-batch of scenarios, or of several plans per scenario (`rows` may
        repeat): every per-scenario field taken at `rows`."""
        return dataclasses.replace(self, **{
            f.name: v[rows] if isinstance(v, np.ndarray) else v.take(rows)
            for f in dataclasses.fields(self)
            if not isinstance(v := getattr(self, f.name), (int, float))})


def seen(ctx: DecisionContext) -> Observation | None:
    """S as the planners see it: each group's rows from ``ctx.reconstructed[group]`` where a
    reconstructor wrote them (``identity`` the observed rows, the ``oracle`` the true ones),
    else the observed table's. The observed S itself when no reconstructor wrote a group."""
    S, rec = ctx.observed, ctx.reconstructed
    if S is None or not any(g in rec for g in S):
        return S
    tables_ = {}
    for group, table in S.items():
        rows = rec.get(group)
        if rows is not None and np.shape(rows) != table.features.shape:
            raise ValueError(f"reconstructed[{group!r}] has shape {np.shape(rows)}, where S's "
                             f"table has {table.features.shape}: a reconstructor that writes a "
                             "group's name writes that group's rows")
        tables_[group] = table if rows is None else EntityTable(
            table.names, np.asarray(rows), table.mask, table.holds)
    out = Observation(tables_)
    out.extras, out.allowed, out.n_tasks = S.extras, S.allowed, S.n_tasks
    return out


def fatigue_belief(ctx: DecisionContext, S: Observation | None = None) -> FatigueBelief:
    """Each human's fatigue belief at this epoch: a reconstructor's (``ctx.reconstructed``
    under ``fatigue.BELIEF_KEYS``), else the fatigue column of `S` (default `seen`) moved ahead
    along the population line from the working hours S shows."""
    S = seen(ctx) if S is None else S
    floor = ctx.published(HumanConstants).fatigue_floor
    if S is None:                 # no S yet: fresh humans on the population line
        B, H = ctx.reallocatable.shape[0], ctx.sizes.humans
        return fatigue.belief_from(ctx.reconstructed, np.ones((B, H)), np.zeros((B, H)), floor)
    humans = S["humans"]
    return fatigue.belief_from(ctx.reconstructed, humans.col("fatigue"),
                               humans.col("working_time"), floor)


def believed(ctx: DecisionContext) -> bool:
    """Whether a reconstructor handed the planners a belief of the fatigue curves (else they
    move the fatigue of S along the population line)."""
    return fatigue.has_belief(ctx.reconstructed)


def as_seen(ctx: DecisionContext) -> DecisionContext:
    """`ctx` as the policy sees it with a reconstructor's guesses: POIs guessed committed (a
    robot on its way; ``committed_guess`` in ``ctx.reconstructed``) are not reallocatable. The
    same `ctx` when no reconstructor guesses any."""
    guess = ctx.reconstructed.get("committed_guess")
    if guess is None:
        return ctx
    return dataclasses.replace(ctx, reallocatable=ctx.reallocatable & ~(guess[..., 0] > 0.5))


def task_attributes(ctx: DecisionContext) -> np.ndarray:
    """(B, P, 2) the POIs' kind and difficulty as currently seen (as estimated in I at t = 0)."""
    S = seen(ctx)
    src = S["tasks"] if S is not None else ctx.inherent["tasks"]
    return np.stack([src.col("kind"), src.col("difficulty")], axis=-1)


def plan_start(ctx: DecisionContext) -> PlanStart:
    """The plan's starting state at this epoch, from I, S as the planners see it (`seen`), the
    fatigue belief (`fatigue_belief`) and the constants the team models published
    (`HumanConstants`, `RobotConstants`).

    A robot on a leg is free at the end of it (remaining distance at its nominal speed plus the
    capture), at its target; a captured image waiting for a human classifier books that human
    for t_bar at Medium quality (the image's quality is not observed). A POI a reconstructor
    guesses captured (``captured_guess`` in ``ctx.reconstructed``, from ``arrivals`` or the
    ``aux`` status head) counts as captured: not open, its image waiting; one it guesses
    committed (``committed_guess``) as not reallocatable (`as_seen`).
    """
    ctx = as_seen(ctx)
    capture_s = ctx.published(RobotConstants).capture_s
    fatigue_floor = ctx.published(HumanConstants).fatigue_floor
    I, S = ctx.inherent, seen(ctx)
    B, P = ctx.reallocatable.shape
    H, R = ctx.sizes.humans, ctx.sizes.robots
    now = float(ctx.time)
    area = I.extras["area_m"][:, None]
    h, r, t = I["humans"], I["robots"], I["tasks"]
    task_xy = np.stack([t.col("x"), t.col("y")], axis=-1) * area[..., None]
    src = S["tasks"] if S is not None else t
    kind = src.col("kind").astype(np.int64)
    diff = src.col("difficulty").astype(np.int64)
    robot_type = np.where(r.col("uav") > 0.5, tables.UAV, tables.UGV)
    speed = r.col("speed").astype(float)
    robot_free = np.full((B, R), now)
    robot_at = np.full((B, R), -1, dtype=np.int64)
    human_free = np.full((B, H), now)
    if S is None:
        hours = np.zeros((B, H))
        robot_xy = np.full((B, R, 2), 0.5) * area[..., None]
        open_ = np.ones((B, P), dtype=bool)
    else:
        hours = S["humans"].col("working_time").astype(float)
        robot_xy = np.stack([S["robots"].col("x"), S["robots"].col("y")], -1) * area[..., None]
        working = S["robots"].col("working") > 0.5
        robot_free[~working] = np.inf
        target = S["robots"].col("target").astype(np.int64)
        committed = working & (target >= 0) & ~np.take_along_axis(
            ctx.reallocatable, np.maximum(target, 0), axis=1)
        if committed.any():
            cb, cr = np.nonzero(committed)
            dest = task_xy[cb, target[cb, cr]]
            dist = np.linalg.norm(dest - robot_xy[cb, cr], axis=-1)
            robot_free[cb, cr] = now + dist / np.maximum(speed[cb, cr], 1e-9) + capture_s
            robot_xy[cb, cr] = dest
            robot_at[cb, cr] = target[cb, cr]
        # a reconstructor's guess of captures the latency hides (``arrivals``), if any
        guess = ctx.reconstructed.get("captured_guess")
        hidden = guess[..., 0] > 0.5 if guess is not None else np.zeros((B, P), dtype=bool)
        open_ = (S["tasks"].col("unvisited") > 0.5) & ctx.reallocatable & ~hidden
        if ctx.previous is not None:
            waiting = (((S["tasks"].col("captured") > 0.5) | hidden)
                       & (ctx.previous.classifier >= 0))
            wb, wp = np.nonzero(waiting)
            np.add.at(human_free, (wb, ctx.previous.classifier[wb, wp]),
                      tables.T_BAR[1, diff[wb, wp]])
    return PlanStart(now=now, horizon=float(ctx.clock.horizon_s), task_xy=task_xy, kind=kind,
                     diff=diff, points=tables.POINTS[diff], open=open_,
                     eta=h.col("cognitive").astype(float), lam=h.col("expertise").astype(float),
                     skill=h.col("skill").astype(np.int64), hours=hours, human_free=human_free,
                     robot_type=robot_type, speed=speed, robot_free=robot_free,
                     robot_xy=robot_xy, robot_at=robot_at, capture_s=capture_s,
                     fatigue_floor=fatigue_floor, belief=fatigue_belief(ctx, S))


@dataclass
class Projection:
    """What a fixed allocation is expected to do from a PlanStart."""

    value: np.ndarray          # (B,) expected points of the open POIs
    human_busy_s: np.ndarray   # (B,) human seconds booked by the plan (legs, classifications)
    expected: np.ndarray       # (B, P) expected points per open POI (0 if not done in time)
    arrival: np.ndarray        # (B, P) capture time (inf if never)
    finish: np.ndarray         # (B, P) classification end (inf if never)
    robot_free: np.ndarray     # (B, R) when each robot's route ends
    robot_xy: np.ndarray       # (B, R, 2) where it ends
    human_free: np.ndarray     # (B, H) when each human's work ends


def project(start: PlanStart, alloc: Allocation, tasks: np.ndarray | None = None, *,
            human_delay: np.ndarray | None = None,
            robot_delay: np.ndarray | None = None) -> Projection:
    """Expected outcome of `alloc` for the POIs in `tasks` (default: the open ones).

    The robot free first (among those with POIs left) goes to its nearest POI left; its
    navigator, if any, is busy for the leg from when both are free; its classifier, if human,
    from the capture or when free, whichever is later. ``human_delay`` / ``robot_delay`` (B, H)
    / (B, R) seconds hold members before their first item (a re-brief, a re-plan). The
    capture time and the fatigue belief are the start's. Compiled (`ata.model.plan_loop`),
    one loop per scenario.
    """
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
    left &= np.isfinite(np.take_along_axis(robot_free, alloc.robot, axis=1))
    speed, quality = (x.reshape(B, P) for x in _per_poi(start, alloc))
    belief = start.belief
    project_loop(left, alloc.robot, robot_free, rx, ry, human_free,
                 np.ascontiguousarray(start.task_xy[..., 0]),
                 np.ascontiguousarray(start.task_xy[..., 1]), speed, quality, alloc.navigator,
                 alloc.classifier, start.diff, start.points, start.hours, start.eta, start.lam,
                 belief.onset, belief.slope, belief.weight, belief.offset, float(belief.floor),
                 float(start.now), float(start.horizon), float(start.capture_s), tables.TABLES,
                 busy, expected, arrival, finish)
    return Projection(value=expected.sum(axis=1), human_busy_s=busy.sum(axis=1),
                      expected=expected, arrival=arrival, finish=finish,
                      robot_free=robot_free, robot_xy=np.stack([rx, ry], axis=-1),
                      human_free=human_free)


def _per_poi(start: PlanStart, alloc: Allocation) -> tuple[np.ndarray, np.ndarray]:
    """What each POI's leg and classification are under `alloc`, the same at every step of a
    projection, raveled (B P,): the robot's speed on the leg (its navigator's skill) and the
    image quality."""
    owner = alloc.robot
    navigated = alloc.navigator >= 0
    nav_class = np.where(navigated, np.take_along_axis(start.skill, np.maximum(
        alloc.navigator, 0), axis=1), 1)
    speed = (np.take_along_axis(start.speed, owner, axis=1)
             * np.where(navigated, tables.SKILL_SPEED[nav_class], 1.0)).ravel()
    quality = tables.QUALITY[np.take_along_axis(start.robot_type, owner, axis=1), start.kind,
                             nav_class].ravel()
    return speed, quality
