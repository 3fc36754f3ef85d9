"""TR-POMDP (optional plugin ``trp``): the decentralised DQN agents of Wu et al., as the paper's
baseline uses them, and their trainer ``dqn``. Everything of the method lives in this package:
``agents`` (observations, Q-networks, joint actions), ``policy`` (the reallocation component
``tr_pomdp``), ``trainer`` (independent double DQN). With the attention ITA of ATA-HRL trained
alone as the initial allocation, the same agents make AtRL-TR."""

from ata import hookimpl
from ata.plugins.tr_pomdp.policy import TRPOMDPPolicy
from ata.plugins.tr_pomdp.trainer import DQNTrainer


@hookimpl
def ata_register_components(register) -> None:
    register("policy", "tr_pomdp", TRPOMDPPolicy)
    register("trainer", "dqn", DQNTrainer)
