"""The ``greedy`` policy: list scheduling on expected points, the bar that every learned method
must clear. It serves the initial and the reallocation slot; the planner itself is the domain
library's (`ata.model.greedy_planner`, where it is described), so that the methods that build on
it share it without importing this plugin."""

from __future__ import annotations

import numpy as np

from ata import hookimpl
from ata.core.state import Allocation, DecisionContext
from ata.model.greedy_planner import GreedyPlanner, GreedySettings


class GreedyPolicy(GreedyPlanner):
    """Greedy list scheduling; serves the initial and the reallocation slot."""

    Settings = GreedySettings

    def __init__(self, settings: GreedySettings, mission: object):
        super().__init__(settings)

    @hookimpl
    def ata_initial_allocation(self, ctx: DecisionContext) -> Allocation:
        return self.initial(ctx)

    @hookimpl
    def ata_reallocate(self, ctx: DecisionContext, active: np.ndarray) -> Allocation:
        return self.reallocate(ctx, active)


@hookimpl
def ata_register_components(register) -> None:
    register("policy", "greedy", GreedyPolicy)
