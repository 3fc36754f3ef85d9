"""The MILP of ITA-MILP (the `milp` policy, ata/plugins/policies/milp.py), for one scenario:
its inputs (`ScenarioData`), settings, options, objective and rows (`build_model`), our own check
of a solution and the assignment of robots to the POIs of each chosen type. The model is in
docs/milp.md; the solve, the cache and the policy are in milp.py."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy import sparse

from ata.core.settings import param
from ata.model import tables
from ata.model.team import CAPTURE_S, FATIGUE_FLOOR

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
    chunk_size: int = param(16, min=1, max=100_000,
                            help="scenarios per worker task (at most batch_size's bound)")


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
        hum = tables.human_success(d.eta[ch], d.lam[ch], f_f, f_w,
                                   tables.F_D[quality, difficulty])
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
