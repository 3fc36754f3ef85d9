"""Optional plugin ``ita``: the attention ITA policy of ATA-HRL and its trainer."""

from ata import hookimpl
from ata.plugins.ata_hrl.components import AttentionITA
from ata.plugins.ata_hrl.trainer import ATAHRLTrainer


@hookimpl
def ata_register_components(register) -> None:
    register("policy", "attention", AttentionITA)
    register("trainer", "ata_hrl", ATAHRLTrainer)
