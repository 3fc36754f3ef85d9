"""The centralised view as Gymnasium environments: one agent allocates the whole team.

At epoch 0 the agent makes the initial allocation; at each later epoch it decides whether to
reallocate and, if so, the new allocation (the condition and the reallocation of the model in
one action). The reward of a step is the team's points in that epoch (``EpisodeRecord.r_perf``).

Observation (a ``Dict`` of float32 ``Box`` spaces, fixed shapes for a mission's team):

- ``inherent_<group>`` (N, F): the inherent information I, one table per entity group
  (``humans``, ``robots``, ``tasks`` for the built-in models), the same at every epoch;
- ``observed_<group>`` (N, F): the observed state S of the epoch, after the uncertainty
  injectors (never the true state);
- ``allocation`` (P, 3): the allocation in force, (robot, navigator, classifier) per POI, -1
  for autonomous / onboard; all -1 at epoch 0, before the initial allocation;
- ``reallocatable`` (P,): 1 where the POI's triple may change now (uncaptured, no leg under way);
- ``epoch`` (1,): the decision epoch k.

The observation that comes with ``terminated`` repeats the last epoch's I and S, with the final
allocation, no POI reallocatable and ``epoch`` = T (there is no state observed at the horizon).
``env.columns`` names the columns of every key. Table values are unbounded (injected noise is);
``allocation``, ``reallocatable`` and ``epoch`` carry their bounds.

Action: ``MultiDiscrete([2] + [R, 1 + H, 1 + H] * P)``:

- ``action[0]``: reallocate now (1) or keep the allocation in force (0); at epoch 0 the initial
  allocation is made whatever the flag;
- ``action[1 + 3p]``: POI p's robot, 0 .. R-1;
- ``action[2 + 3p]``: its navigator: 0 autonomous, 1 + h human h;
- ``action[3 + 3p]``: its classifier: 0 onboard, 1 + h human h.

Action mask: ``info["action_mask"]`` and ``env.action_masks()`` give one flat bool array over the
concatenated choices of the dimensions, ``sum(nvec)`` long, in the order above: the layout
sb3-contrib's MaskablePPO expects (split per dimension, it is what ``MultiDiscrete.sample(mask=
...)`` takes). The flag allows only 1 at epoch 0. At a later epoch a POI that is not
``reallocatable`` allows only its triple in force; every other POI allows every robot and every
human as navigator or classifier, as the model forbids no member a role. After the last epoch
only "keep" is allowed. An action the mask forbids is not an error: a POI that may not change
keeps its triple whatever the action says (the kernel enforces it).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Sequence

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from ata.core.kernel import Simulation
from ata.session import Session
from ata.core.state import Allocation, DecisionContext
from ata.gym.episodes import Episodes, load
from ata.runtime import memory


class CentralisedView:
    """The observation and action spaces of the centralised view for a mission, and the
    conversions between a batch of episodes and observations, masks and actions."""

    def __init__(self, session: Session):
        mission = session.mission
        self.sizes = mission.sizes
        self.n_epochs = mission.clock.n_epochs
        H, R, P = self.sizes.humans, self.sizes.robots, self.sizes.tasks
        probe = Simulation(mission, session.registry, [mission.settings.first_scenario])
        memory.remember(mission, probe.pm)      # Episodes' memory check asks its components
        probe.reset()
        ctx = probe.begin_epoch()
        self.tables: dict[str, tuple[str, str]] = {}     # key -> ("inherent" | "observed", group)
        self.columns: dict[str, tuple[str, ...]] = {}
        boxes: dict[str, spaces.Space] = {}
        for source, obs in (("inherent", ctx.inherent), ("observed", ctx.observed)):
            for group, table in obs.items():
                key = f"{source}_{group}"
                self.tables[key] = (source, group)
                self.columns[key] = table.names
                boxes[key] = spaces.Box(-np.inf, np.inf, table.features.shape[1:], np.float32)
        self.columns.update(allocation=("robot", "navigator", "classifier"),
                            reallocatable=("reallocatable",), epoch=("epoch",))
        high = np.broadcast_to(np.array([R - 1, H - 1, H - 1], np.float32), (P, 3))
        boxes["allocation"] = spaces.Box(-1.0, high, (P, 3), np.float32)
        boxes["reallocatable"] = spaces.Box(0.0, 1.0, (P,), np.float32)
        boxes["epoch"] = spaces.Box(0.0, float(self.n_epochs), (1,), np.float32)
        self.observation_space = spaces.Dict(boxes)
        self.nvec = np.array([2] + [R, 1 + H, 1 + H] * P, dtype=np.int64)
        self.action_space = spaces.MultiDiscrete(self.nvec)

    def observe(self, episodes: Episodes) -> dict[str, np.ndarray]:
        """The batch's observations, (B, ...) per key."""
        ctx, B, P = episodes.context, episodes.batch, self.sizes.tasks
        out = {}
        for key, (source, group) in self.tables.items():
            obs = ctx.inherent if source == "inherent" else ctx.observed
            out[key] = obs[group].features.astype(np.float32)
        allocation = episodes.allocation
        out["allocation"] = (np.full((B, P, 3), -1.0, np.float32) if allocation is None
                             else allocation.stack().astype(np.float32))
        out["reallocatable"] = (np.zeros((B, P), np.float32) if episodes.done
                                else ctx.reallocatable.astype(np.float32))
        out["epoch"] = np.full((B, 1), episodes.epoch, np.float32)
        return out

    def action_mask(self, episodes: Episodes) -> np.ndarray:
        """(B, sum(nvec)) bool: the allowed choices of every dimension, concatenated. After the
        last epoch only "keep" is allowed (an action then is not taken)."""
        B, P = episodes.batch, self.sizes.tasks
        H, R = self.sizes.humans, self.sizes.robots
        allocation = episodes.allocation
        if episodes.done:
            free, flag = np.zeros((B, P), bool), [True, False]
        elif allocation is None:
            free, flag = np.ones((B, P), bool), [False, True]
        else:
            free, flag = episodes.context.reallocatable, [True, True]
        # every choice of a free POI; of the others, the triple in force (as action values:
        # robot, then navigator and classifier shifted by one, each dimension at its offset)
        per_task = np.empty((B, P, R + 2 * (1 + H)), bool)
        per_task[...] = free[..., None]
        current = (np.zeros((B, P, 3), np.int64) if allocation is None
                   else allocation.stack() + [0, 1, 1])
        np.put_along_axis(per_task, current + [0, R, R + 1 + H], True, axis=-1)
        out = np.empty((B, 2 + per_task[0].size), bool)
        out[:, :2] = flag
        out[:, 2:] = per_task.reshape(B, -1)
        return out

    @staticmethod
    def encode(allocation: Allocation, reallocate: np.ndarray) -> np.ndarray:
        """The actions (B, 1 + 3P) that make `allocation`, with flags `reallocate` (B,)."""
        B, P = allocation.robot.shape
        out = np.empty((B, 1 + 3 * P), np.int64)
        out[:, 0] = reallocate
        out[:, 1::3] = allocation.robot
        out[:, 2::3] = allocation.navigator + 1
        out[:, 3::3] = allocation.classifier + 1
        return out

    def decode(self, actions: Any, batch: int | None) -> tuple[Allocation, np.ndarray]:
        """Actions (B, 1 + 3P), or one action (1 + 3P,) when `batch` is None, checked against
        the action space, as the allocation they make and their reallocate flags (B,)."""
        a = np.asarray(actions)
        expected = (self.nvec.size,) if batch is None else (batch, self.nvec.size)
        if a.shape != expected:
            raise ValueError(f"actions must have shape {expected}, got {a.shape}")
        if not np.issubdtype(a.dtype, np.integer):
            raise TypeError(f"actions must be integers, got dtype {a.dtype}")
        a = a.reshape(-1, self.nvec.size)
        bad = (a < 0) | (a >= self.nvec)
        if bad.any():
            b, d = (int(x[0]) for x in np.nonzero(bad))
            env = "" if batch is None else f"environment {b}, "
            raise ValueError(f"action ({env}index {d}, {self.describe(d)}) is {a[b, d]}; "
                             f"allowed: 0 .. {self.nvec[d] - 1}")
        a = a.astype(np.int64)
        return Allocation(a[:, 1::3].copy(), a[:, 2::3] - 1, a[:, 3::3] - 1), a[:, 0] == 1

    @staticmethod
    def describe(index: int) -> str:
        """What one dimension of the action chooses, for messages."""
        if index == 0:
            return "the reallocate flag"
        p, part = divmod(index - 1, 3)
        return f"POI {p}'s " + ("robot", "navigator", "classifier")[part]

    def step(self, episodes: Episodes, actions: Any, single: bool = False) -> np.ndarray:
        """Apply a batch of actions (one action if `single`); the epoch's points (B,)."""
        allocation, flags = self.decode(actions, None if single else episodes.batch)
        return episodes.step(allocation, flags)   # the kernel ignores what the flags rule out

    def mission_action(self, episodes: Episodes) -> np.ndarray:
        """The actions (B, 1 + 3P) of the mission's own decision components (its ``initial``,
        ``condition`` and ``reallocation``) at the pending decision. Driving the environment with
        them at every epoch gives the episodes `ata run` gives (tests/test_gym.py). The triples
        of POIs that may not change are encoded as in force, so the actions pass the mask."""
        allocation, active = episodes.decide()
        previous = episodes.allocation
        if previous is None:
            return self.encode(allocation, np.ones(episodes.batch, bool))
        if active.any():
            previous = allocation.where(active[:, None] & episodes.context.reallocatable,
                                        previous)
        return self.encode(previous, active)


def _info(view: CentralisedView, episodes: Episodes) -> dict[str, np.ndarray]:
    """The batch's infos: the action masks and scenario ids; at the end, each scenario's total
    points and upper bound U."""
    info = {"action_mask": view.action_mask(episodes), "scenario": episodes.scenarios}
    if episodes.done:
        info["total"] = episodes.record.total
        info["upper_bound"] = episodes.record.upper_bound.copy()
    return info


def _option(options: dict[str, Any] | None, allowed: str) -> Any:
    """The one option an environment's reset takes, or None."""
    options = options or {}
    unknown = set(options) - {allowed}
    if unknown:
        raise ValueError(f"unknown reset option(s) {sorted(unknown)}; allowed: {allowed!r}")
    return options.get(allowed)


class CentralisedEnv(gym.Env):
    """One scenario at a time, centralised view (module docstring: spaces, action encoding,
    masks).

    Episodes: T = horizon / epoch steps, then ``terminated``; never ``truncated``. ``reset()``
    takes the next scenario id (from ``[mission] first_scenario``); ``reset(seed=s)`` sets the
    root seed to s and restarts the ids; ``reset(options={"scenario": i})`` runs scenario i. The
    mission's own ``seed`` is the root seed until a reset gives one.

    :param mission: a mission file, a loaded `Session`, or None for the greedy reference
        mission (setting (a)). Its team, clock, models and injectors make the environment; its
        decision components make `mission_action`.
    :param overrides: ``table.key=value`` overrides, as ``ata run --set``.
    """

    metadata = {"render_modes": []}

    def __init__(self, mission: str | Path | Session | None = None, *,
                 overrides: Sequence[str] = ()):
        session = load(mission, overrides)
        self._view = CentralisedView(session)
        self._episodes = Episodes(session, 1)
        self.observation_space = self._view.observation_space
        self.action_space = self._view.action_space
        self.columns = self._view.columns

    def reset(self, *, seed: int | None = None,
              options: dict[str, Any] | None = None) -> tuple[dict[str, np.ndarray], dict]:
        super().reset(seed=seed)
        scenario = _option(options, "scenario")
        self._episodes.reset(seed, None if scenario is None else [scenario])
        return self._observation(), self._info()

    def step(self, action: Any) -> tuple[dict[str, np.ndarray], float, bool, bool, dict]:
        reward = self._view.step(self._episodes, action, single=True)
        return self._observation(), float(reward[0]), self._episodes.done, False, self._info()

    def _observation(self) -> dict[str, np.ndarray]:
        return {k: v[0] for k, v in self._view.observe(self._episodes).items()}

    def _info(self) -> dict[str, Any]:
        info = _info(self._view, self._episodes)
        return {k: v[0].item() if k != "action_mask" else v[0] for k, v in info.items()}

    def action_masks(self) -> np.ndarray:
        """The flat bool mask of the pending decision (as ``info["action_mask"]``)."""
        return self._view.action_mask(self._episodes)[0]

    def mission_action(self) -> np.ndarray:
        """The action the mission's own decision components take now; ask once per epoch, at
        every epoch of the episode (they keep state, as they do in `ata run`)."""
        return self._view.mission_action(self._episodes)[0]

    @property
    def context(self) -> DecisionContext | None:
        """The kernel's `DecisionContext` of the pending decision (a batch of one): what a
        built-in policy would be asked with (no policy's context holds the true state)."""
        return self._episodes.context


class CentralisedVectorEnv(VectorEnv):
    """`num_envs` scenarios in one `Simulation`: one kernel call steps them all.

    The spaces of each sub-environment are those of `CentralisedEnv`; ``info`` holds
    ``action_mask`` (num_envs, sum(nvec)), ``scenario`` and, at the end, ``total`` and
    ``upper_bound``, each with its ``_key`` array as Gymnasium's vector infos have.

    Episodes all have T steps, so every sub-environment ends at the same step and they reset
    together. Autoreset is Gymnasium's default, ``NEXT_STEP``: the step after the one that
    terminated resets every sub-environment, ignores its actions, and returns the first
    observations with reward 0 and ``terminated`` False. ``reset()`` at any time does the same.
    Episode e after a seeded reset runs scenario ids ``first_scenario + e * num_envs + i``;
    ``reset(options={"scenarios": ids})`` runs the given ids (one per sub-environment).
    """

    metadata = {"render_modes": [], "autoreset_mode": AutoresetMode.NEXT_STEP}

    def __init__(self, mission: str | Path | Session | None = None, *, num_envs: int = 8,
                 overrides: Sequence[str] = ()):
        session = load(mission, overrides)
        self._view = CentralisedView(session)
        self._episodes = Episodes(session, num_envs)
        self.num_envs = num_envs
        self.single_observation_space = self._view.observation_space
        self.single_action_space = self._view.action_space
        self.observation_space = batch_space(self.single_observation_space, num_envs)
        self.action_space = batch_space(self.single_action_space, num_envs)
        self.columns = self._view.columns
        self._autoreset = False

    def reset(self, *, seed: int | None = None,
              options: dict[str, Any] | None = None) -> tuple[dict[str, np.ndarray], dict]:
        super().reset(seed=seed)
        self._episodes.reset(seed, _option(options, "scenarios"))
        self._autoreset = False
        return self._view.observe(self._episodes), self._info()

    def step(self, actions: Any) -> tuple[dict[str, np.ndarray], np.ndarray, np.ndarray,
                                          np.ndarray, dict]:
        N = self.num_envs
        if self._autoreset:
            obs, info = self.reset()
            return obs, np.zeros(N), np.zeros(N, bool), np.zeros(N, bool), info
        rewards = self._view.step(self._episodes, actions)
        self._autoreset = self._episodes.done
        return (self._view.observe(self._episodes), rewards, np.full(N, self._episodes.done),
                np.zeros(N, bool), self._info())

    def _info(self) -> dict[str, np.ndarray]:
        info = _info(self._view, self._episodes)
        info.update({f"_{k}": np.ones(self.num_envs, bool) for k in list(info)})
        return info

    def action_masks(self) -> np.ndarray:
        """(num_envs, sum(nvec)) bool: the masks of the pending decisions."""
        return self._view.action_mask(self._episodes)

    def mission_action(self) -> np.ndarray:
        """(num_envs, 1 + 3P): the actions of the mission's own decision components now (see
        `CentralisedEnv.mission_action`)."""
        return self._view.mission_action(self._episodes)

    @property
    def context(self) -> DecisionContext | None:
        """The kernel's batched `DecisionContext` of the pending decisions (see
        `CentralisedEnv.context`)."""
        return self._episodes.context


def sample_masked(mask: np.ndarray, nvec: Sequence[int],
                  rng: np.random.Generator) -> np.ndarray:
    """Uniformly random allowed actions of a ``MultiDiscrete(nvec)``, for a batch at once.

    :param mask: (..., sum(nvec)) bool, the dimensions' masks concatenated (``action_mask``).
    :returns: (..., len(nvec)) int64, one allowed choice per dimension.
    """
    nvec = np.asarray(nvec, dtype=np.int64)
    mask = np.asarray(mask, bool)
    flat = mask.reshape(-1, mask.shape[-1])                                  # (N, S)
    width = int(nvec.max())
    inside = np.arange(width)[:, None] < nvec                                # (W, D)
    offsets = np.concatenate([[0], np.cumsum(nvec)[:-1]])
    # (W, D, N): the choice axis first, so that counting along it adds contiguous slices
    # (numpy's cumsum along an axis is several times slower than these W additions)
    seen = (flat.T[np.where(inside, offsets + np.arange(width)[:, None], 0)]
            & inside[..., None]).astype(np.int32)
    for w in range(1, width):
        seen[w] += seen[w - 1]                       # allowed choices up to w, per dimension
    n = seen[-1]
    if not n.all():
        raise ValueError("the mask allows no choice in some dimension")
    # the k-th allowed choice, k uniform in 0 .. n - 1, is w = the number of choices whose
    # running count is at most k
    k = np.minimum((rng.random(n.shape) * n).astype(np.int32), n - 1)
    choice = np.zeros(n.shape, dtype=np.int64)
    for w in range(width):
        choice += seen[w] <= k
    return choice.T.reshape(mask.shape[:-1] + (-1,))
