"""Episodes of a mission driven by an outside agent: the engine of the ``ata.gym`` environments.

One `Simulation` holds all B scenarios of a batch, so one kernel call steps every one of them.
Each reset builds a fresh `Simulation` (components keep state across the epochs of an episode,
never across episodes), so that a scenario's episode is the one `ata run` simulates for the same
root seed and scenario id whenever the agent decides as the mission's components would.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Sequence

import numpy as np

from ata.core.errors import MissionError
from ata.core.kernel import Simulation
from ata.core.mission import Mission
from ata.session import BASELINE_MISSION, Session, load_session
from ata.core.state import Allocation, DecisionContext, EpisodeRecord
from ata.runtime import memory

MAX_SEED = 2 ** 63 - 1
"""The largest root seed (as ``[mission] seed``)."""


def load(mission: str | Path | Session | None, overrides: Sequence[str] = ()) -> Session:
    """The session of a mission: a file (with ``--set``-style overrides), a loaded `Session`,
    or None for the greedy reference mission (setting (a), ``ata/missions/greedy.toml``)."""
    if isinstance(overrides, (str, bytes)):       # list("a.b=1") would be its characters
        raise TypeError(f"overrides is a sequence of 'table.key=value' strings, not one "
                        f"string: overrides=[{overrides!r}]")
    if isinstance(mission, Session):
        if overrides:
            raise ValueError("overrides apply to a mission file, not to a loaded Session")
        return mission
    return load_session(str(mission) if mission is not None else str(BASELINE_MISSION),
                        list(overrides))


MAX_BATCH = 100_000
"""Scenarios per episode at most (as ``[mission] batch_size``)."""


def check_batch(batch: Any) -> int:
    """A number of scenarios per episode (`num_envs`), checked: an integer from 1 to
    `MAX_BATCH`; a float, a string or a bool is refused rather than truncated or repeated."""
    if isinstance(batch, bool) or not isinstance(batch, (int, np.integer)):
        raise TypeError(f"the number of scenarios per episode (num_envs) must be an int, got "
                        f"{type(batch).__name__} {batch!r}")
    if not 1 <= int(batch) <= MAX_BATCH:
        raise ValueError(f"the number of scenarios per episode (num_envs) must lie in 1 to "
                         f"{MAX_BATCH:,}, got {batch}")
    return int(batch)


def check_seed(seed: Any) -> int:
    """A root seed given to reset, checked."""
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)):
        raise TypeError(f"seed must be an int, got {type(seed).__name__}")
    if not 0 <= int(seed) <= MAX_SEED:
        raise ValueError(f"seed must lie in [0, 2**63 - 1], got {seed}")
    return int(seed)


def check_memory(mission: Mission, batch: int) -> None:
    """Refuse (a MissionError naming the figure and the limit) `batch` scenarios stepped
    together that would not fit in memory (`ata.runtime.memory`), before any is built."""
    limit = memory.memory_limit()
    fits = memory.largest_batch(mission, batch, 1, limit)
    if fits == 0:
        raise memory.too_large(mission, 1, limit)
    if fits < batch:
        raise MissionError("num_envs", None, f"{batch} scenarios of {mission.settings.name!r} "
                           f"stepped together need about "
                           f"{memory.gib(memory.batch_peak(mission, batch))} of memory, more "
                           f"than {memory.limit_text(limit)}; give num_envs of at most {fits}")


class Episodes:
    """Successive episodes of B scenarios each, decided from outside.

    Scenario ids: the episodes after a reset with a seed (or after construction) take the ids
    ``first_scenario + e * B + i`` (episode e, scenario i of the batch), under the root seed
    given to that reset (or the mission's ``seed``); a reset may name its ids instead.
    """

    def __init__(self, session: Session, batch: int):
        batch = check_batch(batch)
        check_memory(session.mission, batch)
        self.mission: Mission = session.mission
        self.registry = session.registry
        self.batch = batch
        self.n_epochs = self.mission.clock.n_epochs
        self.seed = self.mission.settings.seed
        self.next_id = self.mission.settings.first_scenario
        self._seeded_mission = self.mission
        self.simulation: Simulation | None = None
        self.context: DecisionContext | None = None   # pending decision's (last one's when done)
        self.done = False

    def reset(self, seed: int | None = None,
              scenarios: Sequence[int] | None = None) -> DecisionContext:
        """Start an episode: a new root seed restarts the ids at ``first_scenario``; `scenarios`
        (B ids) runs those instead of the next ones. Returns the context of epoch 0."""
        if seed is not None:
            self.seed = check_seed(seed)
            self.next_id = self.mission.settings.first_scenario
            self._seeded_mission = (self.mission if self.seed == self.mission.settings.seed
                                    else self.mission.replace(seed=self.seed))
        if scenarios is None:
            ids = self.next_id + np.arange(self.batch, dtype=np.int64)
            self.next_id += self.batch
        else:
            ids = self._check_ids(scenarios)
        self.simulation = Simulation(self._seeded_mission, self.registry, ids)
        self.simulation.reset()
        self.context = self.simulation.begin_epoch()
        self.done = False
        return self.context

    def _check_ids(self, scenarios: Sequence[int]) -> np.ndarray:
        ids = np.asarray(scenarios)
        if ids.shape != (self.batch,) or not np.issubdtype(ids.dtype, np.integer):
            raise ValueError(f"scenario ids must be a sequence of {self.batch} integers, got "
                             f"{scenarios!r}")
        if (ids < 0).any():
            raise ValueError(f"scenario ids must be non-negative, got {scenarios!r}")
        return ids.astype(np.int64)

    @property
    def scenarios(self) -> np.ndarray:
        """(B,) the scenario ids of the episode."""
        return self._running().sim.rng.scenario_ids.copy()

    @property
    def epoch(self) -> int:
        """The epoch of the pending decision (the number of epochs when done)."""
        return self._running().sim.epoch

    @property
    def record(self) -> EpisodeRecord:
        """The kernel's record of the episode so far (complete when done)."""
        return self._running().sim.record

    @property
    def allocation(self) -> Allocation | None:
        """The allocation in force (None before the initial one)."""
        return self._running().sim.allocation

    def _running(self) -> Simulation:
        if self.simulation is None:
            raise RuntimeError("no episode has started: call reset first")
        return self.simulation

    def step(self, allocation: Allocation | None, active: np.ndarray | None) -> np.ndarray:
        """Apply the pending decision (as ``Simulation.end_epoch``), run the epoch, and begin
        the next one, or end the episode after the last. Returns the epoch's points (B,)."""
        sim = self._running()
        if self.done:
            raise RuntimeError("the episode is over: call reset")
        k = sim.sim.epoch
        sim.end_epoch(allocation, active)
        reward = sim.sim.record.r_perf[:, k].copy()
        if sim.sim.epoch < self.n_epochs:
            self.context = sim.begin_epoch()
        else:
            sim.end_episode()
            self.done = True
        return reward

    def decide(self) -> tuple[Any, np.ndarray | None]:
        """What the mission's own decision components decide for the pending decision
        (``Simulation.decide``); they keep state, so ask once per epoch, at every epoch."""
        if self.done:
            raise RuntimeError("the episode is over: nothing to decide")
        return self._running().decide(self.context)
