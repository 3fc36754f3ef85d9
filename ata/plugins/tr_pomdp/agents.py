"""The Q-networks of TR-POMDP's decentralised agents (one shared by the robots, one by the
humans) and their epsilon-greedy joint action. What an agent observes and how the agents'
actions become an allocation is the host's ``ata.model.agents``."""

from __future__ import annotations

import numpy as np
import torch
from torch import nn

from ata.core.state import DecisionContext
from ata.model.agents import AgentConfig, AgentInputs


class QNet(nn.Module):
    """Observation -> one Q-value per action (an MLP)."""

    def __init__(self, dim: int, actions: int, hidden: int):
        super().__init__()
        self.body = nn.Sequential(nn.Linear(dim, hidden), nn.ReLU(), nn.Linear(hidden, hidden),
                                  nn.ReLU(), nn.Linear(hidden, actions))

    def forward(self, obs: torch.Tensor) -> torch.Tensor:
        return self.body(obs)


class AgentNets(nn.Module):
    """One Q-network per member kind (parameter sharing within a kind)."""

    def __init__(self, cfg: AgentConfig):
        super().__init__()
        self.cfg = cfg
        self.robot = QNet(cfg.robot_dim, cfg.robot_actions, cfg.hidden)
        self.human = QNet(cfg.human_dim, cfg.human_actions, cfg.hidden)

    def q(self, kind: str, obs: torch.Tensor) -> torch.Tensor:
        return getattr(self, kind)(obs)


def masked_argmax(q: torch.Tensor, legal: torch.Tensor) -> torch.Tensor:
    return torch.where(legal, q, torch.full_like(q, -torch.inf)).argmax(-1)


def act(nets: AgentNets, inputs: AgentInputs, epsilon: float, ctx: DecisionContext,
        stream: str = "tr_pomdp") -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Epsilon-greedy joint action; exploration draws come from each scenario's own stream.

    Returns (robot actions, their Q, human actions, their Q)."""
    out = []
    for kind, obs, legal in (("robot", inputs.robot_obs, inputs.robot_legal),
                             ("human", inputs.human_obs, inputs.human_legal)):
        with torch.no_grad():
            q = nets.q(kind, torch.as_tensor(obs)).numpy()
        qm = np.where(legal, q, -np.inf)
        a = qm.argmax(-1)
        if epsilon > 0:
            shape = legal.shape[1:]
            u = ctx.rng.uniform(f"{stream}.{kind}.explore", ctx.epoch, shape[:1])
            g = ctx.rng.uniform(f"{stream}.{kind}.action", ctx.epoch, shape)
            # a uniformly random legal action: the legal one with the largest uniform
            rand = np.where(legal, g, -1.0).argmax(-1)
            a = np.where(u < epsilon, rand, a)
        out += [a, np.take_along_axis(q, a[..., None], -1)[..., 0]]
    return out[0], out[1], out[2], out[3]
