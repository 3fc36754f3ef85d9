"""TR-POMDP (optional plugin ``trp``): the decentralised DQN agents of Wu et al., as the paper's
baseline uses them. Everything of the method lives in this package, under one component name,
``tr_pomdp``: the reallocation policy and its trainer, which share the ``[tr_pomdp]`` table
(``settings``). Modules: ``agents`` (observations, Q-networks, joint actions), ``policy``,
``trainer`` (independent double DQN). With the attention ITA of ATA-HRL trained alone as the
initial allocation, the same agents make AtRL-TR."""

from ata import hookimpl
from ata.plugins.tr_pomdp.policy import TRPOMDPPolicy
from ata.plugins.tr_pomdp.trainer import TRPOMDPTrainer


@hookimpl
def ata_register_components(register) -> None:
    register("policy", "tr_pomdp", TRPOMDPPolicy)
    register("trainer", "tr_pomdp", TRPOMDPTrainer)
