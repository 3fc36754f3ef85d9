"""What a decentralised agent of the team observes and how the agents' joint action becomes an
allocation: the partial observations and action resolution of TR-POMDP's agents (Wu et al.,
ICRA 2022), public so that the PettingZoo environment (``ata.gym.decentralised``) and the
TR-POMDP plugin read one definition.

Every team member is an agent that, at each decision epoch, acts on its own partial
observation. An agent's observation holds only

- its own row of the (noisy, delayed) observed state and of the inherent information, plus its
  own load in the allocation in force;
- public information: the clock, and K candidate POIs (their inherent attributes, their
  observed status, and who holds them in the allocation in force, which every member is told).

It never holds another member's private state (another human's fatigue or workload, another
robot's position or health). Actions, per agent (action 0 keeps everything as it is):

- a robot: claim one of its K nearest reallocatable POIs that it does not hold;
- a human: take the classification of one of K candidate POIs, take its navigation (highly
  skilled humans only), or release one of up to K roles it holds.

Claims on one POI (and role) by several agents are resolved by the highest Q-value; releases
apply before takes. Everything is computed for the whole batch and every agent at once.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from ata.core.state import Allocation, DecisionContext
from ata.model.tables import MAX_POINTS
from ata.model.team import UAV_SPEED

ROBOT_OWN, ROBOT_CAND = 10, 12
HUMAN_OWN, HUMAN_NEW, HUMAN_HELD = 12, 11, 11


@dataclass(frozen=True)
class AgentConfig:
    """Architecture of the agents' Q-networks (stored in checkpoints)."""

    k: int = 4            # candidate POIs per agent (and roles a human may release)
    hidden: int = 64

    def as_dict(self) -> dict[str, int]:
        return asdict(self)

    @property
    def robot_dim(self) -> int:
        return ROBOT_OWN + self.k * ROBOT_CAND

    @property
    def human_dim(self) -> int:
        return HUMAN_OWN + self.k * (HUMAN_NEW + HUMAN_HELD)

    @property
    def robot_actions(self) -> int:
        return 1 + self.k

    @property
    def human_actions(self) -> int:
        return 1 + 3 * self.k


def _onehot3(x: np.ndarray) -> np.ndarray:
    return np.eye(3)[np.clip(np.rint(x).astype(np.int64), 0, 2)]


def _gather(a: np.ndarray, idx: np.ndarray) -> np.ndarray:
    """a (B, P, ...) gathered at idx (B, N, K) -> (B, N, K, ...)."""
    b = np.arange(a.shape[0])[:, None, None]
    return a[b, idx]


def _top_k(score: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray]:
    """Indices of the k highest finite scores along the last axis, best first, and validity."""
    order = np.argsort(-score, axis=-1, kind="stable")[..., :k]
    valid = np.isfinite(np.take_along_axis(score, order, axis=-1))
    if order.shape[-1] < k:                                   # fewer POIs than slots
        pad = k - order.shape[-1]
        order = np.concatenate([order, np.zeros(order.shape[:-1] + (pad,), np.int64)], -1)
        valid = np.concatenate([valid, np.zeros(valid.shape[:-1] + (pad,), bool)], -1)
    return order, valid


@dataclass
class AgentInputs:
    """Observations, legal actions and the POIs each action refers to, for one epoch."""

    robot_obs: np.ndarray      # (B, R, Dr)
    robot_legal: np.ndarray    # (B, R, 1 + K)
    robot_cand: np.ndarray     # (B, R, K) POI of each claim action
    human_obs: np.ndarray      # (B, H, Dh)
    human_legal: np.ndarray    # (B, H, 1 + 3K)
    human_new: np.ndarray      # (B, H, K) POIs a human may take
    human_held: np.ndarray     # (B, H, K) POIs on which it holds a role
    human_load: np.ndarray     # (B, H) utilisation 1 - idleness (own, observed)
    robot_load: np.ndarray     # (B, R) open POIs held, relative to a fair share


def observe(ctx: DecisionContext, cfg: AgentConfig) -> AgentInputs:
    """Every agent's partial observation at this epoch."""
    I, S, prev, K = ctx.inherent, ctx.observed, ctx.previous, cfg.k
    B, P = prev.robot.shape
    H, R = ctx.sizes.humans, ctx.sizes.robots
    rem = max(0.0, 1.0 - ctx.time / ctx.clock.horizon_s)
    movable = ctx.reallocatable
    ti, ts = I["tasks"], S["tasks"]
    open_ = ts.col("classified") < 0.5
    points = ti.col("points") / MAX_POINTS
    # public per-POI facts: inherent attributes, observed status, who holds it
    diff = ts.col("difficulty")
    uav_of = np.take_along_axis(I["robots"].col("uav"), prev.robot, axis=1)
    public = np.concatenate([ts.col("kind")[..., None], _onehot3(diff), points[..., None],
                             ts.col("unvisited")[..., None], ts.col("captured")[..., None],
                             (prev.classifier >= 0)[..., None], (prev.navigator >= 0)[..., None],
                             uav_of[..., None]], -1)              # (B, P, 10)

    # robots: own row, own load; the K nearest movable POIs it does not hold
    ri, rs = I["robots"], S["robots"]
    rx, ry = rs.col("x"), rs.col("y")
    working = rs.col("working") > 0.5
    mine = prev.robot[:, None, :] == np.arange(R)[None, :, None]            # (B, R, P)
    held = (mine & open_[:, None, :]).sum(-1)
    fair = max(1.0, 1.5 * P / max(R, 1) * rem)
    robot_load = held / fair
    dx = ti.col("x")[:, None, :] - rx[..., None]
    dy = ti.col("y")[:, None, :] - ry[..., None]
    dist = np.hypot(dx, dy)
    score = np.where(movable[:, None, :] & ~mine, -dist, -np.inf)
    cand, cvalid = _top_k(score, K)
    cpub = _gather(public, cand.reshape(B, R * K)[:, :, None]).reshape(B, R, K, -1)
    cfeat = np.concatenate([cvalid[..., None],
                            np.take_along_axis(dx, cand, -1)[..., None],
                            np.take_along_axis(dy, cand, -1)[..., None], cpub[..., :-1]], -1)
    cfeat = cfeat * cvalid[..., None]
    own = np.stack([ri.col("uav"), ri.col("ugv"), ri.col("speed") / UAV_SPEED, rx, ry,
                    rs.col("idleness"), rs.col("working"), (rs.col("target") >= 0),
                    held / 10.0, np.full((B, R), rem)], -1)
    robot_obs = np.concatenate([own, cfeat.reshape(B, R, K * ROBOT_CAND)], -1)
    robot_legal = np.concatenate([np.ones((B, R, 1), bool), cvalid & working[..., None]], -1)

    # humans: own row, own roles; K candidate POIs to take, K held roles to release
    hi, hs = I["humans"], S["humans"]
    hid = np.arange(H)[None, :, None]
    cls_mine = prev.classifier[:, None, :] == hid                           # (B, H, P)
    nav_mine = prev.navigator[:, None, :] == hid
    role = (cls_mine | nav_mine) & movable[:, None, :]
    priority = (3.0 * (prev.classifier < 0) + diff + points)[:, None, :]   # public ordering
    new, nvalid = _top_k(np.where(movable[:, None, :] & ~(cls_mine | nav_mine), priority,
                                  -np.inf), K)
    held_idx, hvalid = _top_k(np.where(role, -np.arange(P)[None, None, :].astype(float),
                                       -np.inf), K)
    npub = _gather(public, new.reshape(B, H * K)[:, :, None]).reshape(B, H, K, -1)
    hpub = _gather(public, held_idx.reshape(B, H * K)[:, :, None]).reshape(B, H, K, -1)
    i_cls = np.take_along_axis(cls_mine, held_idx, -1)
    i_nav = np.take_along_axis(nav_mine, held_idx, -1)
    nfeat = np.concatenate([nvalid[..., None], npub], -1) * nvalid[..., None]
    hfeat = np.concatenate([hvalid[..., None], hpub[..., :6], i_cls[..., None],
                            i_nav[..., None], hpub[..., 9:10], hpub[..., 6:7]], -1)
    hfeat = hfeat * hvalid[..., None]
    util = 1.0 - hs.col("idleness")
    own_h = np.concatenate([hi.col("cognitive")[..., None], hi.col("expertise")[..., None],
                            _onehot3(hi.col("skill")),
                            np.stack([hs.col("working_time") / 3.0, hs.col("fatigue"),
                                      hs.col("idleness"), hs.col("sa"),
                                      (cls_mine & open_[:, None, :]).sum(-1) / 10.0,
                                      (nav_mine & open_[:, None, :]).sum(-1) / 10.0,
                                      np.full((B, H), rem)], -1)], -1)
    human_obs = np.concatenate([own_h, nfeat.reshape(B, H, K * HUMAN_NEW),
                                hfeat.reshape(B, H, K * HUMAN_HELD)], -1)
    can_nav = (hi.col("skill") > 1.5)[..., None]
    human_legal = np.concatenate([np.ones((B, H, 1), bool), nvalid, nvalid & can_nav, hvalid],
                                 -1)
    return AgentInputs(robot_obs.astype(np.float32), robot_legal, cand,
                       human_obs.astype(np.float32), human_legal, new, held_idx,
                       util, robot_load)


def _winners(b: np.ndarray, p: np.ndarray, who: np.ndarray, q: np.ndarray, P: int):
    """Of several claims on one (scenario, POI), keep the one with the highest Q."""
    if b.size == 0:
        return b, p, who
    order = np.lexsort((-q, b * P + p))             # by POI, best Q first
    key = (b * P + p)[order]
    first = np.ones(key.size, bool)
    first[1:] = key[1:] != key[:-1]
    keep = order[first]
    return b[keep], p[keep], who[keep]


def apply_actions(prev: Allocation, inputs: AgentInputs, robot_a: np.ndarray,
                  robot_q: np.ndarray, human_a: np.ndarray, human_q: np.ndarray,
                  k: int) -> Allocation:
    """The allocation after every agent's action (illegal actions must have been masked)."""
    robot, nav, cls = prev.robot.copy(), prev.navigator.copy(), prev.classifier.copy()
    P = robot.shape[1]
    # robots claim POIs
    b, r = np.nonzero(robot_a > 0)
    p = inputs.robot_cand[b, r, robot_a[b, r] - 1]
    b, p, r = _winners(b, p, r, robot_q[b, r], P)
    robot[b, p] = r
    # humans release roles first
    b, h = np.nonzero(human_a > 2 * k)
    p = inputs.human_held[b, h, human_a[b, h] - 2 * k - 1]
    cls[b, p] = np.where(cls[b, p] == h, -1, cls[b, p])
    nav[b, p] = np.where(nav[b, p] == h, -1, nav[b, p])
    # then take classifications and navigations
    for lo, target in ((1, cls), (k + 1, nav)):
        b, h = np.nonzero((human_a >= lo) & (human_a < lo + k))
        p = inputs.human_new[b, h, human_a[b, h] - lo]
        b, p, h = _winners(b, p, h, human_q[b, h], P)
        target[b, p] = h
    return Allocation(robot, nav, cls)


def load_terms(inputs: AgentInputs, human_cap: float) -> tuple[np.ndarray, np.ndarray]:
    """Overload of each agent: humans busier than the cap, robots holding more than 1.5 fair
    shares of the open POIs (per unit of excess)."""
    return (np.maximum(0.0, inputs.robot_load - 1.0),
            np.maximum(0.0, inputs.human_load - human_cap) / max(1e-6, 1.0 - human_cap))
