"""The decoder's step inputs: how many features each sub-decision's candidates have, the
constants the decoder assumes, one step's inputs, and how they are written."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ata.model.greedy_planner import HUMAN_TIME_COST, RATE_OFFSET_S
from ata.model.team import WINDOW_S

POI_FEATURES = 18
KEEP_FEATURES = 13
ROBOT_FEATURES = 12
NAV_FEATURES = 12
CLS_FEATURES = 14


@dataclass(frozen=True)
class DecodeSettings:
    """The constants the decoder assumes beside the plan start's: the human model's utilisation
    window and re-brief, and the greedy heuristic's prices (for the priors)."""

    window_s: float = WINDOW_S
    human_time_cost: float = HUMAN_TIME_COST
    rate_offset_s: float = RATE_OFFSET_S
    rebrief_s: float = 0.0


@dataclass
class StepInputs:
    """One sub-decision for every episode: candidate features (E, N, F), legal candidates
    (E, N), the heuristic prior (E, N), and which episodes decide at all (E,)."""

    features: np.ndarray
    mask: np.ndarray
    prior: np.ndarray
    active: np.ndarray

    def take(self, rows: np.ndarray) -> "StepInputs":
        """The inputs of episodes `rows` alone."""
        return StepInputs(self.features[rows], self.mask[rows], self.prior[rows],
                          self.active[rows])
