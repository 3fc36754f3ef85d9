"""The identity reconstructor: passes the observed state on unchanged (the w/o.AUX ablation)."""

from __future__ import annotations

import numpy as np

from ata import hookimpl
from ata.core.state import Observation, SimState


class IdentityReconstructor:
    """Writes each observed group's features under its own name."""

    def __init__(self, settings: None, mission: object):
        pass

    @hookimpl
    def ata_reconstruct(self, sim: SimState, obs: Observation, inherent: Observation,
                        out: dict[str, np.ndarray]) -> None:
        for group, table in obs.items():
            out.setdefault(group, table.features)


@hookimpl
def ata_register_components(register) -> None:
    register("reconstructor", "identity", IdentityReconstructor)
