"""The settings of the component ``tr_pomdp``: one table for the policy and its trainer.

TR-POMDP is one method with one name: the reallocation policy ``tr_pomdp`` and the trainer
``tr_pomdp`` read the same ``[tr_pomdp]`` table. The policy reads the first group, the trainer
the second; each leaves the other's keys alone.
"""

from __future__ import annotations

from dataclasses import dataclass

from ata.core.settings import param
from ata.training import VALIDATION_SEED_OFFSET


@dataclass
class PolicySettings:
    """What the policy reads."""

    checkpoint: str = param("builtin:tr_pomdp_a", help="trained agents: a path or "
                            "builtin:NAME")
    epsilon: float = param(0.0, min=0.0, max=1.0, help="exploration rate at evaluation "
                           "(random legal action, per agent, from the scenario's stream)")


@dataclass
class TrainingSettings:
    """What the trainer reads: double DQN with replay, the agents' reward and architecture."""

    seed: int = param(12345, min=0, max=2**40, help="training: root seed of the training "
                      f"scenarios (validation uses seed + {VALIDATION_SEED_OFFSET})")
    batch_size: int = param(16, min=1, max=4096, help="training: episodes per step")
    steps: int = param(500, min=0, help="training: steps; each rolls out batch_size episodes "
                       "with epsilon-greedy agents, then makes `updates` gradient steps")
    updates: int = param(32, min=1, help="training: gradient steps per step")
    lr: float = param(1e-3, min=0.0, max=1.0, help="training: Adam learning rate of the agents")
    gamma: float = param(0.9, min=0.0, max=1.0, help="training: discount per decision epoch")
    buffer: int = param(30000, min=64, max=10_000_000,
                        help="training: replay buffer capacity, transitions per member kind "
                        "(allocated whole at the start)")
    minibatch: int = param(256, min=1, help="training: transitions per gradient step")
    target_sync: int = param(50, min=1, help="training: gradient steps between copies of the "
                             "online networks into the target networks")
    eps_start: float = param(1.0, min=0.0, max=1.0, help="training: epsilon of the first step")
    eps_end: float = param(0.05, min=0.0, max=1.0, help="training: epsilon after the decay")
    eps_decay_steps: int = param(300, min=1, help="training: steps of linear epsilon decay")
    k: int = param(4, min=1, help="training: candidate POIs per agent (and roles a human may "
                   "release)")
    hidden: int = param(64, min=4, max=4096, help="training: width of the agents' Q-networks")
    reward_scale: float = param(20.0, min=1e-6, help="training: points per unit of agent "
                                "reward")
    team_weight: float = param(0.5, min=0.0, help="training: weight of the team's points of the "
                               "epoch in each agent's reward, beside its own POIs'")
    load_overload: float = param(0.1, min=0.0, help="training: load management penalty per "
                                 "unit of overload (human utilisation above human_load_cap, "
                                 "robots holding more than 1.5 fair shares of the open POIs)")
    load_use: float = param(0.005, min=0.0, help="training: load management penalty per "
                            "non-idle action (discourages needless changes)")
    human_load_cap: float = param(0.65, min=0.0, max=0.99, help="training: utilisation above "
                                  "which a human counts as overloaded")
    average: float = param(0.0, min=0.0, max=0.999999, help="training: weight averaging: 0 "
                           "off; else after every gradient step the averaged agents move "
                           "(1 - average) of the way to the online ones, each validation plays "
                           "both, and best.pt keeps whichever scored higher")
    eval_every: int = param(50, min=1, help="training: held-out validation every N steps")
    eval_scenarios: int = param(64, min=1, help="training: validation scenarios")
    select: str = param("drawn", choices=("drawn", "expected"), help="training: the "
                        "validation score best.pt follows: the points drawn, or the points in "
                        "expectation over the classification outcomes (steadier)")
    checkpoint_every: int = param(10, min=1, help="training: write checkpoint.pt every N steps")
    threads: int = param(1, min=1, max=256, help="training: torch CPU threads")


@dataclass
class Settings(TrainingSettings, PolicySettings):
    """The ``[tr_pomdp]`` table: the policy's keys, then the trainer's."""
