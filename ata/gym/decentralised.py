"""The decentralised view as a PettingZoo ``ParallelEnv``: one agent per team member.

The agents are TR-POMDP's (``ata.model.agents``, the baseline of Wu et al. as
`ata train --plugins trp` trains it), with the same partial observations and actions:

- agents ``human_0 .. human_{H-1}`` and ``robot_0 .. robot_{R-1}``;
- an observation is ``{"observation": float32 vector, "action_mask": int8 vector}`` (PettingZoo's
  convention for masks). The vector holds only the member's own row of I and of the observed S,
  its own load, the clock, and K candidate POIs (their inherent attributes, observed status and
  who holds them); never another member's private state, never the true state. Robots: 10 + 12 K
  numbers; humans: 12 + 22 K;
- actions, ``Discrete``: 0 keeps everything. A robot: 1 .. K claims its k-th nearest
  reallocatable POI it does not hold. A human: 1 .. K takes the classification of its k-th
  candidate POI, K+1 .. 2K its navigation (highly skilled humans only), 2K+1 .. 3K releases the
  k-th role it holds (the POI goes onboard, or autonomous);
- claims on one POI (and role) by several agents: the lowest member index wins (TR-POMDP's
  agents break the tie by their Q-values, which an environment does not have); releases apply
  before takes. An action the mask forbids is taken as 0 (keep).

Time: the mission's ``initial`` component makes the allocation at epoch 0, as TR-POMDP and
AtRL-TR have it; the agents act at every later epoch (T - 1 steps), all at once, and every
agent's reward is the team's points of the epoch (``r_perf``). The points of epoch 0, before any
agent acts, are in no step's reward; the last step's infos give every agent the episode's
``total`` (epoch 0 included) and its upper bound U. Seeds and scenario ids are as in
`ata.gym.CentralisedEnv`; ``reset(options={"scenario": i})`` runs scenario i, and other option
keys are ignored (PettingZoo's API test passes one of its own).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Sequence

import numpy as np
from gymnasium import spaces
from pettingzoo import ParallelEnv

from ata.session import Session
from ata.core.state import DecisionContext
from ata.gym.episodes import Episodes, load
from ata.model import agents as trp


class DecentralisedParallelEnv(ParallelEnv):
    """One scenario at a time, one agent per human and robot (module docstring).

    :param mission: a mission file, a loaded `Session`, or None for the greedy reference mission.
    :param overrides: ``table.key=value`` overrides, as ``ata run --set``.
    :param k: candidate POIs per agent (and roles a human may release): TR-POMDP's K.
    """

    metadata = {"name": "ata_decentralised_v0", "render_modes": [], "is_parallelizable": True}

    def __init__(self, mission: str | Path | Session | None = None, *,
                 overrides: Sequence[str] = (), k: int = 4):
        session = load(mission, overrides)
        if k < 1:
            raise ValueError(f"k must be at least 1, got {k}")
        if session.mission.clock.n_epochs < 2:
            raise ValueError("the decentralised view needs at least 2 decision epochs: the "
                             "agents act from epoch 1 (horizon_s / epoch_s is 1)")
        self._episodes = Episodes(session, 1)
        self._cfg = trp.AgentConfig(k=k)
        sizes = session.mission.sizes
        self._members = ([("human", h) for h in range(sizes.humans)]
                         + [("robot", r) for r in range(sizes.robots)])
        self.possible_agents = [f"{kind}_{i}" for kind, i in self._members]
        self._index = dict(zip(self.possible_agents, self._members))
        self.agents: list[str] = []
        dims = {"human": (self._cfg.human_dim, self._cfg.human_actions),
                "robot": (self._cfg.robot_dim, self._cfg.robot_actions)}
        self._obs_spaces, self._act_spaces = {}, {}
        for agent, (kind, _) in self._index.items():
            dim, n = dims[kind]
            self._obs_spaces[agent] = spaces.Dict({
                "observation": spaces.Box(-np.inf, np.inf, (dim,), np.float32),
                "action_mask": spaces.Box(0, 1, (n,), np.int8)})
            self._act_spaces[agent] = spaces.Discrete(n)
        self._inputs: trp.AgentInputs | None = None

    def observation_space(self, agent: str) -> spaces.Dict:
        return self._obs_spaces[agent]

    def action_space(self, agent: str) -> spaces.Discrete:
        return self._act_spaces[agent]

    def reset(self, seed: int | None = None,
              options: dict[str, Any] | None = None) -> tuple[dict[str, dict], dict[str, dict]]:
        scenario = (options or {}).get("scenario")
        self._episodes.reset(seed, None if scenario is None else [scenario])
        allocation, _ = self._episodes.decide()
        self._episodes.step(allocation, None)
        self._inputs = trp.observe(self._episodes.context, self._cfg)
        self.agents = self.possible_agents[:]
        return self._observations(), {agent: {} for agent in self.agents}

    def step(self, actions: dict[str, Any]) -> tuple[dict, dict, dict, dict, dict]:
        if not self.agents:
            raise RuntimeError("the episode is over (or has not begun): call reset")
        inputs, ctx = self._inputs, self._episodes.context
        chosen = {"robot": np.zeros((1, len(inputs.robot_legal[0])), np.int64),
                  "human": np.zeros((1, len(inputs.human_legal[0])), np.int64)}
        for agent, action in actions.items():
            if agent not in self._index:
                raise ValueError(f"unknown agent {agent!r}; agents: "
                                 f"{', '.join(self.possible_agents)}")
            kind, i = self._index[agent]
            a = int(action)
            if not 0 <= a < self._act_spaces[agent].n:
                raise ValueError(f"action of {agent} is {a}; allowed: 0 .. "
                                 f"{self._act_spaces[agent].n - 1}")
            legal = (inputs.robot_legal if kind == "robot" else inputs.human_legal)[0, i, a]
            chosen[kind][0, i] = a if legal else 0
        no_q = {kind: np.zeros(a.shape) for kind, a in chosen.items()}
        allocation = trp.apply_actions(ctx.previous, inputs, chosen["robot"], no_q["robot"],
                                       chosen["human"], no_q["human"], self._cfg.k)
        reward = float(self._episodes.step(allocation, np.ones(1, bool))[0])
        done = self._episodes.done
        if not done:
            self._inputs = trp.observe(self._episodes.context, self._cfg)
        observations = self._observations(keep_only=done)
        agents = self.agents
        infos: dict[str, dict] = {agent: {} for agent in agents}
        if done:
            record = self._episodes.record
            infos = {agent: {"total": float(record.total[0]),
                             "upper_bound": float(record.upper_bound[0])} for agent in agents}
            self.agents = []
        return (observations, {agent: reward for agent in agents},
                {agent: done for agent in agents}, {agent: False for agent in agents}, infos)

    def _observations(self, keep_only: bool = False) -> dict[str, dict[str, np.ndarray]]:
        """Every live agent's observation; after the last epoch, the last one observed with only
        "keep" allowed."""
        inputs, out = self._inputs, {}
        for agent in self.agents:
            kind, i = self._index[agent]
            obs = inputs.robot_obs if kind == "robot" else inputs.human_obs
            legal = inputs.robot_legal if kind == "robot" else inputs.human_legal
            mask = legal[0, i].astype(np.int8)
            if keep_only:
                mask[1:] = 0
            out[agent] = {"observation": obs[0, i].copy(), "action_mask": mask}
        return out

    @property
    def context(self) -> DecisionContext | None:
        """The kernel's `DecisionContext` of the pending decision (see
        `ata.gym.CentralisedEnv.context`)."""
        return self._episodes.context
