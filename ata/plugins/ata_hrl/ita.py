"""Optional plugin ``ita``: the attention ITA policy of ATA-HRL (its trainer ``ata_hrl`` is
the plugin ``ata.plugins.ata_hrl.train``, loaded when a training mission names it: deciding
needs no torch)."""

from ata import hookimpl
from ata.plugins.ata_hrl.components import AttentionITA


@hookimpl
def ata_register_components(register) -> None:
    register("policy", "attention", AttentionITA)
