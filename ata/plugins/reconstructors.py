"""The identity reconstructor: passes the observed state on unchanged (the w/o.AUX ablation); the
arrivals reconstructor: captures that the latency hides, read from the robot rows; the oracle:
the true state, a reference (docs/methods.md's value of information), never a method."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ata import hookimpl
from ata.core.settings import param
from ata.core.state import DecisionView, Observation
from ata.model import fatigue
from ata.model.team import HumanConstants


class IdentityReconstructor:
    """Writes each observed group's features under its own name."""

    def __init__(self, settings: None, mission: object):
        pass

    @hookimpl
    def ata_reconstruct(self, sim: DecisionView, obs: Observation, inherent: Observation,
                        out: dict[str, np.ndarray]) -> None:
        for group, table in obs.items():
            out.setdefault(group, table.features)


class ArrivalReconstructor:
    """Captures the latency hides, read from the robot rows: a POI whose observed row is as it
    was an epoch before (so it may be stale) and shows it unvisited, although the robot that
    headed for it, still allocated to it and seen fresh and working now, heads for another POI
    or for none. A robot leaves its target only once it has captured it (docs/model.md: "Robots"),
    unless a reallocation took the POI away, which the allocation in force shows. The guess goes
    under ``captured_guess`` (B, P, 1); `plan_start` takes such POIs as captured, for every
    policy that plans from it (greedy and ATA-HRL alike). Uses the observed S, its previous
    epoch and the allocation in force only."""

    def __init__(self, settings: None, mission: object):
        self.prev_robots: np.ndarray | None = None
        self.prev_tasks: np.ndarray | None = None

    @hookimpl
    def ata_reconstruct(self, sim: DecisionView, obs: Observation, inherent: Observation,
                        out: dict[str, np.ndarray]) -> None:
        rob, tasks = obs["robots"], obs["tasks"]
        guess = np.zeros(tasks.features.shape[:2], dtype=bool)
        if self.prev_robots is not None and sim.allocation is not None:
            t_col = rob.index("target")
            target = rob.features[..., t_col].astype(np.int64)
            before = self.prev_robots[..., t_col].astype(np.int64)
            fresh = (rob.features != self.prev_robots).any(-1) & (rob.col("working") > 0.5)
            moved_on = fresh & (before >= 0) & (target != before)
            b, r = np.nonzero(moved_on)
            p = before[b, r]
            still_its = sim.allocation.robot[b, p] == r
            guess[b[still_its], p[still_its]] = True
            maybe_stale = (tasks.features == self.prev_tasks).all(-1)
            guess &= maybe_stale & (tasks.col("unvisited") > 0.5)
        self.prev_robots = rob.features.copy()
        self.prev_tasks = tasks.features.copy()
        out["captured_guess"] = guess[..., None].astype(float)


ORACLE_GROUPS = {"fatigue": "humans", "robots": "robots", "tasks": "tasks"}
"""The oracle's channels and the group of S each one makes true."""


class OracleReconstructor:
    """A reference: the true rows of S, for the channels of its settings, written over what the
    reconstructors before it wrote (``out[group]``); for ``fatigue`` also each human's true
    curve as an exact `FatigueBelief` (`ata.model.fatigue.BELIEF_KEYS`, K = 1); for
    ``robots`` and ``tasks`` also ``committed_guess`` (B, P, 1), the tasks S shows open that
    the true rows of those groups hold (a leg under way, a capture), which the planners then
    leave alone (`ata.model.plan.as_seen`). The rows of S a channel leaves out stay as
    observed. What it yields minus what the same policy yields with ``identity`` is the value
    of that information (docs/model.md: "Uncertainty")."""

    reference = True
    """The kernel hands it the true state, and labels its results a reference."""

    @dataclass
    class Settings:
        channels: list[str] = param(list(ORACLE_GROUPS), choices=tuple(ORACLE_GROUPS),
                                    help="what it makes true: fatigue (the human rows and "
                                         "curves), robots and tasks (their rows)")

    def __init__(self, settings: "OracleReconstructor.Settings", mission: object):
        self.channels = list(dict.fromkeys((settings or self.Settings()).channels))

    @hookimpl
    def ata_reconstruct_reference(self, sim: DecisionView, truth: Observation,
                                  obs: Observation, inherent: Observation,
                                  out: dict[str, np.ndarray]) -> None:
        for channel in self.channels:
            out[ORACLE_GROUPS[channel]] = truth[ORACLE_GROUPS[channel]].features
        held = [truth[g].holds for g in ("robots", "tasks")
                if g in self.channels and truth[g].holds is not None]
        if held:
            shown = obs.reallocatable
            committed = np.zeros(truth["tasks"].features.shape[:2], dtype=bool)
            for holds in held:
                b, n = np.nonzero(holds >= 0)
                committed[b, holds[b, n]] = True
            if shown is not None:
                committed &= shown
            out["committed_guess"] = committed[..., None].astype(float)
        # a human model without individual curves hides none: the true F_f now is all there is
        if "fatigue" in self.channels and all(k in truth.hidden for k in fatigue.CURVE_KEYS):
            onset, slope = (truth.hidden[k] for k in fatigue.CURVE_KEYS)
            floor = sim.published(HumanConstants).fatigue_floor
            exact = fatigue.FatigueBelief.exact(onset, slope, floor)
            for key, value in zip(fatigue.BELIEF_KEYS, (exact.onset, exact.slope, exact.weight)):
                out[key] = value


@hookimpl
def ata_register_components(register) -> None:
    register("reconstructor", "identity", IdentityReconstructor)
    register("reconstructor", "arrivals", ArrivalReconstructor)
    register("reconstructor", "oracle", OracleReconstructor)
