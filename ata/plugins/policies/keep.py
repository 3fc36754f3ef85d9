"""The `keep` reallocation: the allocation in force, unchanged. It fills the reallocation slot of
a method that only makes the initial allocation (an ITA-only method, or a policy under test),
whatever the condition says."""

from __future__ import annotations

import numpy as np

from ata import hookimpl
from ata.core.state import Allocation, DecisionContext


class Keep:
    """Returns ``ctx.previous``: a reallocation that changes nothing and costs nothing."""

    def __init__(self, settings: None, mission: object):
        pass

    @hookimpl
    def ata_reallocate(self, ctx: DecisionContext, active: np.ndarray) -> Allocation:
        return ctx.previous


@hookimpl
def ata_register_components(register) -> None:
    register("policy", "keep", Keep)
