"""ITA-MILP: a robust initial allocation by mixed-integer linear programming (HiGHS through
scipy.optimize.milp), in the manner of Fu et al. (T-RO 2022), with humans as one more kind of
agent. It allocates once, at t = 0, and never reallocates. The model is in docs/milp.md.

One binary variable per *option* of a POI: (robot type, navigator, classifier). Robots of one
type are interchangeable in the model (the same speed, the same image quality, the same route
time estimate per POI), so the MILP chooses types and a per-robot count cap bounds each type;
our own code then gives each POI a robot of its type, in sweeps around the base so that routes
stay compact, respecting every robot's count. Options that fail the capability redundancy
requirement are left out of the model; so are dominated navigators (a low or medium skill human
navigates no faster and images no better than the robot alone). The model itself is
`milp_model`; this module solves it (`solve_scenario`), keeps solutions in the cache and is the
policy.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import os
import time
import warnings
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np
from scipy.optimize import Bounds, LinearConstraint, milp

from ata import hookimpl
from ata.core.errors import MissionError
from ata.core.state import Allocation, DecisionContext, EpisodeOutcome
from ata.runtime.cache import cache_dir
from ata.runtime.executors import ProcessExecutor
from ata.model import tables
from ata.model.greedy_planner import GreedySettings, plan
from ata.model.plan import believed, fatigue_belief, seen
from ata.model.team import HumanConstants, RobotConstants
from ata.plugins.policies import milp_model
from ata.plugins.policies.milp_model import (
    STATUS_TEXT, MilpSettings, Model, ScenarioData, Solution, assign_robots, build_model,
    check_choice)


def solve_scenario(d: ScenarioData, s: MilpSettings) -> Solution:
    """Build, solve and check one scenario's MILP. When the redundancy requirement makes the
    model infeasible, its margins are relaxed (scaled by each of `RELAX_STEPS` in turn); the
    solution records the scale it needed."""
    t0 = time.perf_counter()
    sol = None
    for scale in RELAX_STEPS:
        sol = _solve_once(d, s, scale, t0)
        sol.margin_scale = scale
        if sol.status != 2:          # anything but infeasible ends the ladder
            break
    return sol


RELAX_STEPS = (1.0, 0.5, 0.0)
"""Scales of the redundancy margins tried in turn when the model is infeasible."""

RESTRICTED_GAP = 1e-3
"""The relative gap the restricted MILP of `_solve_model`'s second solve stops at."""
BY_LP_BOUND = ("optimal within the gap of the LP relaxation's bound (the restricted MILP's "
               "solution)")
"""The message of an answer of `_solve_model`'s first two solves (no branch and bound)."""


class _Result(NamedTuple):
    x: np.ndarray | None
    status: int
    objective: float
    bound: float
    gap: float
    message: str


def _solve_model(model: Model, s: MilpSettings, t0: float) -> _Result:
    """Solve the MILP to the relative gap `s.mip_rel_gap` with HiGHS, in up to three solves:

    1. its LP relaxation, whose optimum bounds the MILP's optimum. In an optimal basic solution
       every POI but a few (no more than the capacity rows) takes one option whole;
    2. the MILP restricted to the POIs the LP leaves fractional, every other POI keeping its
       LP option, solved to `RESTRICTED_GAP`: a solution of the whole MILP. When its objective
       is within `s.mip_rel_gap` of the LP bound, that bound proves the gap, and it is the
       answer;
    3. otherwise, or when the first two found nothing, the whole MILP by branch and bound.
    """
    n = model.value.size
    rows = [LinearConstraint(model.A, model.lb, model.ub)]

    def left() -> float:
        return max(s.time_limit_s - (time.perf_counter() - t0), 0.01)

    lp = milp(-model.value, integrality=np.zeros(n), bounds=(0, 1), constraints=rows,
              options={"time_limit": left(), "presolve": True})
    if lp.status == 2:           # no fractional solution, so no integral one either
        return _Result(None, 2, np.nan, np.nan, np.nan, lp.message)
    if lp.status == 0:
        whole = lp.x > 1 - 1e-9
        decided = np.zeros(model.required.size, bool)
        decided[model.task[whole]] = True
        keep = Bounds(whole.astype(float), np.where(decided[model.task] & ~whole, 0.0, 1.0))
        sub = milp(-model.value, integrality=np.ones(n), bounds=keep, constraints=rows,
                   options={"time_limit": left(), "node_limit": s.node_limit,
                            "mip_rel_gap": RESTRICTED_GAP, "presolve": True})
        if sub.x is not None:
            x = np.round(sub.x)
            value, bound = float(model.value @ x), float(-lp.fun)
            gap = max(bound - value, 0.0) / max(abs(value), 1e-9)
            if gap <= s.mip_rel_gap:
                return _Result(x, 0, value, bound, gap, BY_LP_BOUND)
    res = milp(-model.value, integrality=np.ones(n), bounds=(0, 1), constraints=rows,
               options={"time_limit": left(), "node_limit": s.node_limit,
                        "mip_rel_gap": s.mip_rel_gap, "presolve": True})
    bound = -res.mip_dual_bound if res.mip_dual_bound is not None else np.nan
    gap = res.mip_gap if res.mip_gap is not None else np.nan
    objective = float(-res.fun) if res.x is not None else np.nan
    return _Result(res.x, res.status, objective, float(bound), float(gap), res.message)


def _solve_once(d: ScenarioData, s: MilpSettings, scale: float, t0: float) -> Solution:
    model = build_model(d, s, scale)
    try:
        res = _solve_model(model, s, t0)
    except Exception as exc:   # a solver crash takes the documented fallback
        return Solution(None, 4, np.nan, np.nan, np.nan, time.perf_counter() - t0, str(exc))
    seconds = time.perf_counter() - t0
    if res.x is None:
        return Solution(None, res.status, np.nan, res.bound, res.gap, seconds, res.message)
    chosen = np.nonzero(res.x > 0.5)[0]
    chosen = chosen[np.argsort(model.task[chosen])]
    robot = assign_robots(d, model.rtype[chosen], model.robot_slots) if chosen.size == \
        d.kind.size else np.zeros(0, dtype=np.int64)
    problems = check_choice(model, chosen, robot, d)
    if problems:
        return Solution(None, res.status, res.objective, res.bound, res.gap, seconds,
                        res.message, problems)
    triples = np.stack([robot, model.nav[chosen], model.cls[chosen]], axis=1)
    return Solution(triples, res.status, res.objective, res.bound, res.gap, seconds,
                    res.message)


def _solve_chunk(args: tuple) -> list[Solution]:
    data, settings = args
    return [solve_scenario(d, settings) for d in data]


# -- the solution cache ----------------------------------------------------------------------
# A scenario's MILP depends on its ScenarioData (I, the working hours at t = 0, the horizon and
# the uncertainty level) and the [milp] settings alone, so its solution can be kept on disk and
# reused by the next evaluation: under milp/ in the run's cache folder
# (`ata.runtime.cache`), when one is set (`ata eval` sets one).

CACHE_FORMAT = 1
"""Bumped when the cached record changes shape."""
_NOT_IN_KEY = ("workers", "chunk_size")
"""[milp] settings that do not change a scenario's solution."""
_code_hash: str | None = None


def _code_version() -> str:
    """A hash of the code a solution depends on (this module, the model's, the model tables,
    scipy)."""
    global _code_hash
    if _code_hash is None:
        import scipy   # on use: scipy's version, once

        h = hashlib.sha256(f"{CACHE_FORMAT} scipy {scipy.__version__}".encode())
        for module_file in (__file__, milp_model.__file__, tables.__file__):
            h.update(Path(module_file).read_bytes())
        _code_hash = h.hexdigest()
    return _code_hash


def cache_key(d: ScenarioData, s: MilpSettings) -> str:
    """sha256 of everything a scenario's solution depends on: its data, the settings, the code."""
    h = hashlib.sha256(_code_version().encode())
    for f in dataclasses.fields(d):
        value = getattr(d, f.name)
        a = np.ascontiguousarray(value)
        h.update(f"{f.name}:{a.dtype.str}:{a.shape};".encode())
        h.update(a.tobytes())
    settings = {k: v for k, v in dataclasses.asdict(s).items() if k not in _NOT_IN_KEY}
    h.update(json.dumps(settings, sort_keys=True).encode())
    h.update(repr(RELAX_STEPS).encode())
    return h.hexdigest()


def _cache_path(root: Path, key: str) -> Path:
    return root / "milp" / key[:2] / f"{key}.json"


def load_cached(root: Path, key: str) -> Solution | None:
    """The cached solution under `key`, or None (absent or unreadable)."""
    try:
        rec = json.loads(_cache_path(root, key).read_text(encoding="utf-8"))
        if rec.get("format") != CACHE_FORMAT:
            return None
        triples = None if rec["triples"] is None else np.asarray(rec["triples"], dtype=np.int64)
        return Solution(triples=triples, status=int(rec["status"]),
                        objective=float(rec["objective"]), bound=float(rec["bound"]),
                        gap=float(rec["gap"]), seconds=float(rec["seconds"]),
                        message=str(rec["message"]), problems=list(rec["problems"]),
                        margin_scale=float(rec["margin_scale"]))
    except (OSError, ValueError, KeyError, TypeError):
        return None


def misfit(sol: Solution, d: ScenarioData) -> str | None:
    """Why a cached solution cannot be the allocation of scenario `d` (None when it can be):
    an entry changed on disk would otherwise reach the kernel as a contract breach."""
    if sol.triples is None:
        return None
    t = sol.triples
    P, R, H = d.kind.shape[0], d.rtype.shape[0], d.eta.shape[0]
    if t.shape != (P, 3):
        return f"holds an allocation of shape {t.shape}, not ({P}, 3)"
    for col, (n, what) in enumerate(((R, "robot"), (H, "human"), (H, "human"))):
        if t.size and not ((t[:, col] >= -1) & (t[:, col] < n)).all():
            return f"names a {what} that is not one of the scenario's {n}"
    return None


def store_cached(root: Path, key: str, sol: Solution) -> None:
    """Write a solution atomically (several processes may fill one cache at once)."""
    path = _cache_path(root, key)
    rec = {"format": CACHE_FORMAT,
           "triples": None if sol.triples is None else sol.triples.tolist(),
           "status": int(sol.status), "objective": float(sol.objective),
           "bound": float(sol.bound), "gap": float(sol.gap), "seconds": float(sol.seconds),
           "message": str(sol.message), "problems": list(sol.problems),
           "margin_scale": float(sol.margin_scale)}
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_name(f"{path.name}.{os.getpid()}.tmp")
        tmp.write_text(json.dumps(rec), encoding="utf-8")
        os.replace(tmp, path)
    except OSError as exc:        # a read-only or full cache slows the run, nothing more
        warnings.warn(f"milp: cannot write the solution cache ({exc})", RuntimeWarning,
                      stacklevel=2)


def cacheable(sol: Solution, s: MilpSettings) -> bool:
    """Only reproducible outcomes are cached: not a crash, not a solve the clock cut short
    (the time limit, unlike the node limit, depends on the machine)."""
    return sol.status != 4 and sol.seconds < 0.95 * s.time_limit_s


def scenario_data(ctx: DecisionContext, mission,
                  settings: MilpSettings | None = None) -> list[ScenarioData]:
    """Split the batch's I (and the working hours of S at t = 0, with the F_f the plan's belief
    gives then and after a shift at the `settings`' utilisation cap) into per-scenario inputs."""
    I, S = ctx.inherent, seen(ctx)
    floor = ctx.published(HumanConstants).fatigue_floor
    capture_s = ctx.published(RobotConstants).capture_s
    area = I.extras["area_m"]
    hours = S["humans"].col("working_time") if S is not None else \
        np.zeros(I["humans"].features.shape[:2])
    belief, cap = fatigue_belief(ctx, S), (settings or MilpSettings()).human_utilisation_cap
    f_now, f_worn = belief.at(hours), belief.at(hours + cap * ctx.clock.horizon_s / 3600.0)
    xy = np.stack([I["tasks"].col("x"), I["tasks"].col("y")], -1) * area[:, None, None]
    rtype = np.where(I["robots"].col("uav") > 0.5, tables.UAV, tables.UGV)
    return [ScenarioData(kind=I["tasks"].col("kind")[b].astype(np.int64),
                         diff=I["tasks"].col("difficulty")[b].astype(np.int64), xy=xy[b],
                         eta=I["humans"].col("cognitive")[b], lam=I["humans"].col("expertise")[b],
                         skill=I["humans"].col("skill")[b].astype(np.int64), hours=hours[b],
                         fatigue_now=f_now[b], fatigue_worn=f_worn[b],
                         rtype=rtype[b], speed=I["robots"].col("speed")[b],
                         area_m=float(area[b]), horizon_s=ctx.clock.horizon_s,
                         event_p=float(mission.event_probability),
                         fatigue_sigma=float(np.sqrt(mission.fatigue_variance)),
                         fatigue_floor=float(floor), capture_s=float(capture_s),
                         fatigue_noisy=not believed(ctx))
            for b in range(ctx.reallocatable.shape[0])]


class MilpPolicy:
    """ITA-MILP; as a reallocation policy it keeps the allocation (it never reallocates)."""

    Settings = MilpSettings

    def __init__(self, settings: MilpSettings, mission):
        if len(settings.redundancy_margin) != 3:
            raise MissionError("[milp]", "redundancy_margin", "needs three margins (low, "
                               "medium, high difficulty)", file=mission.source)
        self.s = settings
        self.mission = mission
        self.solutions: list[Solution] = []
        self.fallback: np.ndarray | None = None

    @hookimpl
    def ata_peak_bytes(self, mission: Any, batch: int) -> int:
        # one scenario's model at a time in each solver process, whatever the batch: its
        # options (POI x robot type x navigator x classifier, navigators at most every human)
        # in some twenty arrays of 8 bytes, and the dense (humans, options) time matrix
        s = mission.sizes
        options = s.tasks * 2 * (1 + s.humans) * (1 + s.humans)
        return max(1, min(self.s.workers, batch)) * 8 * options * (20 + s.humans)

    def solve_all(self, data: list[ScenarioData]) -> list[Solution]:
        """Solve every scenario (taking cached solutions when a cache is set), in worker
        processes when asked; the order is the batch's."""
        root = cache_dir()
        if root is None:
            return self._solve(data)
        keys = [cache_key(d, self.s) for d in data]
        found = [load_cached(root, k) for k in keys]
        for i, sol in enumerate(found):
            why = None if sol is None else misfit(sol, data[i])
            if why is not None:      # solved again (and rewritten) rather than trusted
                warnings.warn(f"milp: the cache entry {_cache_path(root, keys[i])} {why}; "
                              "solved again", RuntimeWarning, stacklevel=2)
                found[i] = None
        todo = [i for i, sol in enumerate(found) if sol is None]
        for i, sol in zip(todo, self._solve([data[i] for i in todo])):
            found[i] = sol
            if cacheable(sol, self.s):
                store_cached(root, keys[i], sol)
        return found

    def _solve(self, data: list[ScenarioData]) -> list[Solution]:
        if not data:
            return []
        if self.s.workers <= 1 or len(data) <= self.s.chunk_size:
            return [solve_scenario(d, self.s) for d in data]
        chunks = [data[i:i + self.s.chunk_size] for i in range(0, len(data), self.s.chunk_size)]
        parts: list[list[Solution]] = [[] for _ in chunks]
        with ProcessExecutor(self.s.workers) as pool:   # ata's one process pool
            for i, part in pool.run(_solve_chunk, [(c, self.s) for c in chunks]):
                parts[i] = part
        return [sol for part in parts for sol in part]

    @hookimpl
    def ata_initial_allocation(self, ctx: DecisionContext) -> Allocation:
        self.solutions = self.solve_all(scenario_data(ctx, self.mission, self.s))
        B, P = ctx.reallocatable.shape
        triples = np.zeros((B, P, 3), dtype=np.int64)
        failed = np.array([sol.triples is None for sol in self.solutions])
        for b, sol in enumerate(self.solutions):
            if sol.triples is not None:
                triples[b] = sol.triples
        alloc = Allocation.from_stack(triples)
        self.fallback = failed
        if failed.any():
            rows = np.nonzero(failed)[0]
            greedy = plan(ctx.take(rows), GreedySettings(), np.ones((rows.size, P), bool))
            alloc.robot[rows], alloc.navigator[rows], alloc.classifier[rows] = \
                greedy.robot, greedy.navigator, greedy.classifier
            first = self.solutions[rows[0]]
            warnings.warn(f"milp: {rows.size} of {B} scenarios fell back to greedy (first: "
                          f"{STATUS_TEXT.get(first.status, first.status)}; {first.message}; "
                          f"{'; '.join(first.problems)})", RuntimeWarning, stacklevel=2)
        return alloc

    @hookimpl
    def ata_episode_scored(self, episode: EpisodeOutcome) -> None:
        if not self.solutions:
            return
        m = episode.metrics
        m["milp_status"] = np.array([sol.status for sol in self.solutions], dtype=float)
        m["milp_objective"] = np.array([sol.objective for sol in self.solutions])
        m["milp_bound"] = np.array([sol.bound for sol in self.solutions])
        m["milp_gap"] = np.array([sol.gap for sol in self.solutions])
        m["milp_solve_s"] = np.array([sol.seconds for sol in self.solutions])
        m["milp_fallback"] = self.fallback.astype(float)
        m["milp_margin_scale"] = np.array([sol.margin_scale for sol in self.solutions])
        if self.fallback.any():
            episode.warnings.append(f"milp: {int(self.fallback.sum())} scenario(s) fell back "
                                       "to the greedy allocation (see milp_status)")


@hookimpl
def ata_register_components(register) -> None:
    register("policy", "milp", MilpPolicy)
