"""Optional plugin ``ctr``: conditional task reallocation of ATA-HRL (pi_C and pi_TR), one
component for the condition and the reallocation slot."""

from ata import hookimpl
from ata.plugins.ata_hrl.components import CTRPolicy

ATA_REQUIRES = ("ita",)
"""The ITA policy comes along: this part of ATA-HRL acts on its allocation."""


@hookimpl
def ata_register_components(register) -> None:
    register("condition", "ctr", CTRPolicy)
    register("policy", "ctr", CTRPolicy)
