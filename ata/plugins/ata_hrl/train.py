"""Plugin of ATA-HRL's trainer ``ata_hrl`` (torch), apart from the components it trains so that
a run of them never imports torch: a training mission naming the trainer loads it (entry point
``trainer.ata_hrl`` of ``ata.components``)."""

from ata import hookimpl
from ata.plugins.ata_hrl.trainer import ATAHRLTrainer


@hookimpl
def ata_register_components(register) -> None:
    register("trainer", "ata_hrl", ATAHRLTrainer)
