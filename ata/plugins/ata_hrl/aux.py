"""Optional plugin ``aux``: the auxiliary state reconstruction of ATA-HRL (cVAE for fatigue,
stacked GRUs for delayed states); without it the ``identity`` reconstructor gives w/o.AUX."""

from ata import hookimpl
from ata.plugins.ata_hrl.components import AuxReconstructor

ATA_REQUIRES = ("ita",)
"""The ITA policy comes along: this part of ATA-HRL acts on its allocation."""


@hookimpl
def ata_register_components(register) -> None:
    register("reconstructor", "aux", AuxReconstructor)
