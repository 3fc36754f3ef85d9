"""TR-POMDP reallocation (optional plugin ``trp``): decentralised DQN agents, one per member.

The baseline of Wu et al. (ICRA 2022) as the paper uses it: every epoch, each human and each
robot acts on its own partial observation (``agents``) with a Q-network shared by its
kind, and the joint action edits the allocation in force. Uncertainty is handled only by the
POMDP formulation: the agents read the raw observation, never a reconstruction. Pair it with
``condition = "always"``; the initial allocation is ``random`` (TR-POMDP) or the attention ITA
trained alone (AtRL-TR).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ata import hookimpl
from ata.core.state import Allocation, DecisionContext
from ata.model.agents import AgentConfig, AgentInputs, apply_actions, observe
import ata.plugins.tr_pomdp.agents as dqn
from ata.plugins.tr_pomdp.settings import Settings as TRPOMDPSettings
from ata.training import CheckpointError, load_cached, trained_on

KIND = "tr_pomdp"
"""The ``kind`` a TR-POMDP checkpoint carries."""


def agents_from_checkpoint(data: dict[str, Any], path: str | Path) -> dqn.AgentNets:
    """The agents' Q-networks stored in a checkpoint (its ``agents`` entry)."""
    if "agents" not in data or "agents_config" not in data:
        raise CheckpointError(path, "holds no TR-POMDP agents (train them with "
                                    "`ata train --plugins trp`)")
    try:
        nets = dqn.AgentNets(AgentConfig(**data["agents_config"]))
        nets.load_state_dict(data["agents"])
    except (TypeError, RuntimeError) as exc:
        raise CheckpointError(path, f"agents do not fit their architecture: "
                                    f"{str(exc).splitlines()[0][:200]}") from None
    return nets


def load_agents(spec: str) -> dqn.AgentNets:
    """The agents of a checkpoint, in evaluation mode, cached per process."""
    return load_cached(spec, agents_from_checkpoint, KIND)


@dataclass
class Transition:
    """One epoch of the agents, as a trainer records it."""

    inputs: AgentInputs
    robot_a: np.ndarray
    human_a: np.ndarray


class TRPOMDPPolicy:
    """Every epoch, the joint epsilon-greedy action of the decentralised agents."""

    component_name = "tr_pomdp"

    Settings = TRPOMDPSettings      # one table with the trainer `tr_pomdp` (settings.py)

    def __init__(self, settings: "TRPOMDPPolicy.Settings", mission: Any,
                 nets: dqn.AgentNets | None = None, log: list[Transition] | None = None,
                 epsilon: float | None = None):
        self.settings = settings
        self.from_checkpoint = nets is None
        self.nets = nets if nets is not None else load_agents(settings.checkpoint)
        self.log = log
        self.epsilon = settings.epsilon if epsilon is None else epsilon

    @hookimpl
    def ata_trained_on(self) -> list[tuple[int, int, int]]:
        return trained_on(self.settings.checkpoint, KIND) if self.from_checkpoint else []

    @hookimpl
    def ata_reallocate(self, ctx: DecisionContext, active: np.ndarray) -> Allocation:
        cfg = self.nets.cfg
        inputs = observe(ctx, cfg)
        ra, rq, ha, hq = dqn.act(self.nets, inputs, self.epsilon, ctx)
        if self.log is not None:
            self.log.append(Transition(inputs, ra, ha))
        return apply_actions(ctx.previous, inputs, ra, rq, ha, hq, cfg.k)

