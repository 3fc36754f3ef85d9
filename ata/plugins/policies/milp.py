"""ITA-MILP: a robust initial allocation by mixed-integer linear programming (HiGHS through
scipy.optimize.milp), in the manner of Fu et al. (T-RO 2022), with humans as one more kind of
agent. It allocates once, at t = 0, and never reallocates. The model is in docs/milp.md.

One binary variable per *option* of a POI: (robot type, navigator, classifier). Robots of one
type are interchangeable in the model (the same speed, the same image quality, the same route
time estimate per POI), so the MILP chooses types and a per-robot count cap bounds each type;
our own code then gives each POI a robot of its type, in sweeps around the base so that routes
stay compact, respecting every robot's count. Options that fail the capability redundancy
requirement are left out of the model; so are dominated navigators (a low or medium skill human
navigates no faster and images no better than the robot alone).
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import os
import time
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from scipy import sparse
from scipy.optimize import LinearConstraint, milp

from ata import hookimpl
from ata.core.settings import param
from ata.core.state import Allocation, DecisionContext, SimState
from ata.runtime.cache import cache_dir
from ata.runtime.executors import ProcessExecutor
from ata.model import tables
from ata.model.greedy_planner import GreedySettings, plan
from ata.model.plan import believed, fatigue_belief, seen
from ata.model.team import CAPTURE_S, FATIGUE_FLOOR, HumanConstants, RobotConstants

STATUS_TEXT = {0: "optimal", 1: "limit reached", 2: "infeasible", 3: "unbounded", 4: "error",
               -1: "not solved"}


@dataclass
class MilpSettings:
    """The ``[milp]`` table."""

    time_limit_s: float = param(20.0, min=0.01, help="solver time limit per scenario, s")
    node_limit: int = param(20000, min=1, help="branch-and-bound node limit per scenario "
                            "(deterministic, unlike the time limit)")
    mip_rel_gap: float = param(0.01, min=0.0, max=1.0, help="relative optimality gap to stop at")
    redundancy_margin: list[float] = param([0.1, 0.05, 0.0], min=0.0, max=0.5,
                                           help="per difficulty (low, medium, high): the "
                                                "pessimistic success probability must reach "
                                                "0.5 + this")
    fatigue_sigmas: float = param(1.0, min=0.0, help="fatigue noise std devs taken off F_f in "
                                  "the pessimistic case")
    pessimistic_utilisation: float = param(0.85, min=0.0, max=1.0,
                                           help="utilisation at which F_w is taken in the "
                                                "pessimistic case")
    human_utilisation_cap: float = param(0.65, min=0.01, max=1.0,
                                         help="share of the horizon a human may be booked")
    robot_utilisation_cap: float = param(0.9, min=0.01, max=1.0,
                                         help="share of the horizon a robot's route may take")
    tour_constant: float = param(0.7124, min=0.0, help="route length per POI is this times "
                                 "sqrt(area / POIs per robot) (Beardwood-Halton-Hammersley)")
    workers: int = param(1, min=1, max=256, help="worker processes solving scenarios")
    chunk_size: int = param(16, min=1, help="scenarios per worker task")


@dataclass
class ScenarioData:
    """What the MILP of one scenario is built from: I, the working hours in S at t = 0 and the
    F_f the plan's belief gives then and after a shift at the utilisation cap, the mission's
    horizon and uncertainty level, and the constants the team models publish. Plain arrays, so
    it travels to worker processes. ``fatigue_noisy``: no reconstructor gave a belief, so it is
    the noisy fatigue of S moved along the population line, and the pessimistic case takes the
    noise off too (a reconstructor's belief has the noise in it already: not twice)."""

    kind: np.ndarray          # (P,) estimated kind
    diff: np.ndarray          # (P,) estimated difficulty
    xy: np.ndarray            # (P, 2) metres
    eta: np.ndarray           # (H,)
    lam: np.ndarray           # (H,)
    skill: np.ndarray         # (H,)
    hours: np.ndarray         # (H,) working hours at t = 0
    fatigue_now: np.ndarray   # (H,) F_f now, by the belief
    fatigue_worn: np.ndarray  # (H,) F_f after a shift at the utilisation cap, by the belief
    rtype: np.ndarray         # (R,)
    speed: np.ndarray         # (R,) m/s
    area_m: float
    horizon_s: float
    event_p: float
    fatigue_sigma: float
    fatigue_floor: float = FATIGUE_FLOOR
    capture_s: float = CAPTURE_S
    fatigue_noisy: bool = True


@dataclass
class Model:
    """The MILP of one scenario: options, objective, constraints (maximise values @ x)."""

    task: np.ndarray          # (n,) POI of each option
    rtype: np.ndarray         # (n,) robot type
    nav: np.ndarray           # (n,) -1 auto, else human
    cls: np.ndarray           # (n,) -1 onboard, else human
    value: np.ndarray         # (n,) nominal expected points
    p_pess: np.ndarray        # (n,) pessimistic success probability
    required: np.ndarray      # (P,) the probability each POI's option must reach
    human_time: np.ndarray    # (H, n) seconds of human h the option books
    type_slots: np.ndarray    # (2,) POIs each robot type can take in all
    robot_slots: np.ndarray   # (R,) POIs each robot can take
    human_budget: float       # seconds each human may be booked
    A: sparse.csr_matrix = field(repr=False, default=None)
    lb: np.ndarray = field(repr=False, default=None)
    ub: np.ndarray = field(repr=False, default=None)


@dataclass
class Solution:
    triples: np.ndarray | None   # (P, 3) robot, navigator, classifier; None when it failed
    status: int
    objective: float
    bound: float
    gap: float
    seconds: float
    message: str
    problems: list[str] = field(default_factory=list)
    margin_scale: float = 1.0    # the redundancy margins' scale the model needed


def build_model(d: ScenarioData, s: MilpSettings, margin_scale: float = 1.0) -> Model:
    """Enumerate the options, apply the redundancy requirement (its margins scaled by
    `margin_scale`), and assemble the constraints."""
    P, H, R = d.kind.size, d.eta.size, d.rtype.size
    present = np.array([np.any(d.rtype == t) for t in (tables.UAV, tables.UGV)])
    type_speed = np.array([d.speed[d.rtype == t].mean() if present[t] else 1.0 for t in (0, 1)])
    nav_opts = np.concatenate([[-1], np.nonzero(d.skill == 2)[0]])          # auto, high skill
    cls_opts = np.arange(-1, H)
    p_, t_, k_, c_ = np.meshgrid(np.arange(P), np.nonzero(present)[0], nav_opts, cls_opts,
                                 indexing="ij")
    p_, t_, k_, c_ = (a.ravel() for a in (p_, t_, k_, c_))
    nav_class = np.where(k_ < 0, 1, 2)
    kind, diff = d.kind[p_], d.diff[p_]
    q = tables.QUALITY[t_, kind, nav_class]
    hard = np.minimum(diff + 1, 2)
    q_flip = tables.QUALITY[t_, 1 - kind, nav_class]
    human = c_ >= 0
    ch = np.maximum(c_, 0)

    def success(quality, difficulty, f_f, f_w):
        on = tables.P_RC[quality, difficulty]
        hum = 0.5 + d.eta[ch] * f_f * f_w * d.lam[ch] * tables.F_D[quality, difficulty]
        return np.where(human, hum, on)

    f_f_nom = d.fatigue_now[ch]
    value = tables.expected_points(tables.POINTS[diff], success(q, diff, f_f_nom, 1.0))
    # pessimistic: fatigue after a shift at the utilisation cap, less the noise the level makes
    # plausible (where the belief is the noisy observation's); a busy workload; and, with the
    # level's probability, a harder POI of either kind
    noise = s.fatigue_sigmas * d.fatigue_sigma if d.fatigue_noisy else 0.0
    f_f_pess = np.maximum(0.0, d.fatigue_worn - noise)[ch]
    f_w_pess = float(tables.workload(s.pessimistic_utilisation))
    p_same = success(q, diff, f_f_pess, f_w_pess)
    p_changed = np.minimum(success(q, hard, f_f_pess, f_w_pess),
                           success(q_flip, hard, f_f_pess, f_w_pess))
    p_pess = (1.0 - d.event_p) * p_same + d.event_p * p_changed

    # redundancy: keep the options whose pessimistic success reaches the requirement; a POI
    # that no option can reach keeps its most robust options (best effort, documented)
    required = 0.5 + np.asarray(s.redundancy_margin, dtype=float)[d.diff] * margin_scale
    best = np.full(P, -np.inf)
    np.maximum.at(best, p_, p_pess)
    required = np.minimum(required, best)
    keep = p_pess >= required[p_] - 1e-12
    p_, t_, k_, c_, value, p_pess, q, diff = (a[keep] for a in (p_, t_, k_, c_, value, p_pess,
                                                                 q, diff))
    n = p_.size

    leg_m = s.tour_constant * np.sqrt(d.area_m ** 2 * R / max(P, 1))
    per_poi_s = leg_m / type_speed + d.capture_s                        # (2,) robot seconds
    robot_slots = np.floor(s.robot_utilisation_cap * d.horizon_s / per_poi_s[d.rtype]).astype(int)
    type_slots = np.array([robot_slots[d.rtype == t].sum() for t in (0, 1)])
    nav_s = leg_m / (type_speed[t_] * tables.SKILL_SPEED[2]) + d.capture_s
    cls_s = tables.T_BAR[q, diff]
    human_time = np.zeros((H, n))
    cols = np.arange(n)
    human_time[k_[k_ >= 0], cols[k_ >= 0]] += nav_s[k_ >= 0]
    human_time[c_[c_ >= 0], cols[c_ >= 0]] += cls_s[c_ >= 0]
    human_budget = s.human_utilisation_cap * d.horizon_s

    # rows: one option per POI (P), POIs per robot type (2), seconds per human (H)
    assign = sparse.csr_matrix((np.ones(n), (p_, cols)), shape=(P, n))
    per_type = sparse.csr_matrix((np.ones(n), (t_, cols)), shape=(2, n))
    A = sparse.vstack([assign, per_type, sparse.csr_matrix(human_time)]).tocsr()
    lb = np.concatenate([np.ones(P), np.zeros(2), np.zeros(H)])
    ub = np.concatenate([np.ones(P), type_slots.astype(float), np.full(H, human_budget)])
    return Model(task=p_, rtype=t_, nav=k_, cls=c_, value=value, p_pess=p_pess,
                 required=required, human_time=human_time, type_slots=type_slots,
                 robot_slots=robot_slots, human_budget=human_budget, A=A, lb=lb, ub=ub)


def check_choice(model: Model, chosen: np.ndarray, robot: np.ndarray, d: ScenarioData) -> list[str]:
    """Our own check of a solution: one option per POI, redundancy, capacities. [] when fine."""
    problems = []
    P = model.required.size
    counts = np.bincount(model.task[chosen], minlength=P)
    if chosen.size != P or (counts != 1).any():
        problems.append("not exactly one option per POI")
        return problems
    order = np.argsort(model.task[chosen])
    chosen = chosen[order]
    if (model.p_pess[chosen] < model.required - 1e-9).any():
        problems.append("a POI's option misses the redundancy requirement")
    used = model.human_time[:, chosen].sum(axis=1)
    if (used > model.human_budget * (1 + 1e-9) + 1e-6).any():
        problems.append(f"a human is booked {used.max():.0f} s > {model.human_budget:.0f} s")
    per_robot = np.bincount(robot, minlength=d.rtype.size)
    if (per_robot > model.robot_slots).any():
        problems.append("a robot has more POIs than its route time allows")
    if (d.rtype[robot] != model.rtype[chosen]).any():
        problems.append("a POI's robot is not of the chosen type")
    return problems


def assign_robots(d: ScenarioData, types: np.ndarray, slots: np.ndarray) -> np.ndarray:
    """Give each POI a robot of its chosen type: POIs sorted by angle around the base, cut into
    consecutive runs in proportion to each robot's slots, so every robot covers a sector."""
    robot = np.full(types.size, -1, dtype=np.int64)
    base = np.full(2, d.area_m / 2.0)
    angle = np.arctan2(d.xy[:, 1] - base[1], d.xy[:, 0] - base[0])
    for t in (tables.UAV, tables.UGV):
        pois = np.nonzero(types == t)[0]
        robots = np.nonzero(d.rtype == t)[0]
        if pois.size == 0:
            continue
        pois = pois[np.argsort(angle[pois], kind="stable")]
        # an even share for each robot, never above its slots
        share = np.full(robots.size, pois.size // robots.size)
        share[: pois.size - share.sum()] += 1
        share = np.minimum(share, slots[robots])
        missing = pois.size - share.sum()
        for i in range(robots.size):           # hand what is left to robots with room
            extra = min(missing, slots[robots[i]] - share[i])
            share[i] += extra
            missing -= extra
        if missing > 0:                         # cannot happen when the type's row held
            share[-1] += missing
        robot[pois] = np.repeat(robots, share)
    return robot


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


def _solve_once(d: ScenarioData, s: MilpSettings, scale: float, t0: float) -> Solution:
    model = build_model(d, s, scale)
    n = model.value.size
    remaining = max(s.time_limit_s - (time.perf_counter() - t0), 0.01)
    try:
        res = milp(-model.value, integrality=np.ones(n), bounds=(0, 1),
                   constraints=[LinearConstraint(model.A, model.lb, model.ub)],
                   options={"time_limit": remaining, "node_limit": s.node_limit,
                            "mip_rel_gap": s.mip_rel_gap, "presolve": True})
    except Exception as exc:   # a solver crash takes the documented fallback
        return Solution(None, 4, np.nan, np.nan, np.nan, time.perf_counter() - t0, str(exc))
    seconds = time.perf_counter() - t0
    bound = -res.mip_dual_bound if res.mip_dual_bound is not None else np.nan
    gap = res.mip_gap if res.mip_gap is not None else np.nan
    if res.x is None:
        return Solution(None, res.status, np.nan, bound, gap, seconds, res.message)
    chosen = np.nonzero(res.x > 0.5)[0]
    chosen = chosen[np.argsort(model.task[chosen])]
    robot = assign_robots(d, model.rtype[chosen], model.robot_slots) if chosen.size == \
        d.kind.size else np.zeros(0, dtype=np.int64)
    problems = check_choice(model, chosen, robot, d)
    if problems:
        return Solution(None, res.status, -res.fun, bound, gap, seconds, res.message, problems)
    triples = np.stack([robot, model.nav[chosen], model.cls[chosen]], axis=1)
    return Solution(triples, res.status, float(-res.fun), float(bound), float(gap), seconds,
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
    """A hash of the code a solution depends on (this module, the model tables, scipy)."""
    global _code_hash
    if _code_hash is None:
        import scipy

        h = hashlib.sha256(f"{CACHE_FORMAT} scipy {scipy.__version__}".encode())
        for module_file in (__file__, tables.__file__):
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
            from ata.core.errors import MissionError
            raise MissionError("[milp]", "redundancy_margin", "needs three margins (low, "
                               "medium, high difficulty)", file=mission.source)
        self.s = settings
        self.mission = mission
        self.solutions: list[Solution] = []
        self.fallback: np.ndarray | None = None

    def solve_all(self, data: list[ScenarioData]) -> list[Solution]:
        """Solve every scenario (taking cached solutions when a cache is set), in worker
        processes when asked; the order is the batch's."""
        root = cache_dir()
        if root is None:
            return self._solve(data)
        keys = [cache_key(d, self.s) for d in data]
        found = [load_cached(root, k) for k in keys]
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
    def ata_episode_end(self, sim: SimState) -> None:
        if not self.solutions:
            return
        m = sim.record.metrics
        m["milp_status"] = np.array([sol.status for sol in self.solutions], dtype=float)
        m["milp_objective"] = np.array([sol.objective for sol in self.solutions])
        m["milp_bound"] = np.array([sol.bound for sol in self.solutions])
        m["milp_gap"] = np.array([sol.gap for sol in self.solutions])
        m["milp_solve_s"] = np.array([sol.seconds for sol in self.solutions])
        m["milp_fallback"] = self.fallback.astype(float)
        m["milp_margin_scale"] = np.array([sol.margin_scale for sol in self.solutions])
        if self.fallback.any():
            sim.record.warnings.append(f"milp: {int(self.fallback.sum())} scenario(s) fell back "
                                       "to the greedy allocation (see milp_status)")


@hookimpl
def ata_register_components(register) -> None:
    register("policy", "milp", MilpPolicy)
