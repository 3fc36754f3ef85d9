"""The decoder's step inputs: the feature columns of each sub-decision's candidates, by name, and
how many there are, the constants the decoder assumes, one step's inputs."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ata.model.greedy_planner import HUMAN_TIME_COST, RATE_OFFSET_S
from ata.model.team import WINDOW_S

# The feature columns of the compiled steps' candidates, by name: the steps write each feature
# at its column, and `Decoder`'s step methods say what each is. An option's pair of columns
# (autonomous, navigated) starts at its name; a one-hot image quality at its name plus the
# quality.

# the POI step (`Decoder.poi_inputs`)
POI_ARRIVE = 0           # the arrival of the robot free first, autonomous and navigated (2)
POI_ONBOARD = 2          # the expected points onboard, both options (2)
POI_HUMAN = 4            # the best human's expected points, both options (2)
POI_RATE = 6             # greedy's rate, both options (2)
POI_SOONER = 8           # how much sooner another robot arrives
POI_BETTER = 9           # how much better onboard another robot does
POI_POINTS = 10
POI_KIND = 11
POI_DIFFICULTY = 12
POI_TIME_LEFT = 13       # the robot free first's time left
POI_SHARE_LEFT = 14      # the share of POIs left
POI_SAME_ROBOT = 15      # in force: the POI's robot is the robot free first
POI_VALID = 16           # in force: the POI's robot can still go
POI_HUMAN_CLASSIFIES = 17  # in force: a human classifies the POI
POI_FEATURES = 18

# the robot step (`Decoder.robot_inputs`)
ROBOT_ARRIVE = 0
ROBOT_FREE = 1
ROBOT_TRAVEL = 2
ROBOT_ONBOARD = 3
ROBOT_FREE_FIRST = 4
ROBOT_ASSIGNED = 5       # the robot's share of the POIs assigned
ROBOT_HOLDS = 6          # in force: the robot holds the POI
ROBOT_TYPE = 7
ROBOT_QUALITY = 8        # one-hot, the four qualities (4)
ROBOT_FEATURES = 12

# the navigator step (`Decoder.nav_inputs`): autonomous, then each human
NAV_ARRIVE = 0
NAV_WAIT = 1             # the wait for the navigator
NAV_LEG = 2
NAV_ONBOARD = 3
NAV_RATE = 4             # greedy's rate (the prior)
NAV_UTILISATION = 5
NAV_HOLDS = 6            # in force: this option navigates
NAV_HUMAN = 7
NAV_QUALITY = 8          # one-hot, the four qualities (4)
NAV_FEATURES = 12

# the classifier step (`Decoder.cls_inputs`): onboard, then each human
CLS_POINTS = 0           # expected points
CLS_SUCCESS = 1          # success probability
CLS_FINISH = 2
CLS_WAIT = 3             # the wait before the item starts
CLS_UTILISATION = 4
CLS_WORKLOAD = 5         # F_w
CLS_FATIGUE = 6          # F_f
CLS_ITEM = 7             # the item's length
CLS_NET = 8              # greedy's net value
CLS_REBRIEF = 9
CLS_HUMAN = 10
CLS_HOLDS = 11           # in force: this option classifies
CLS_QUALITY = 12         # one-hot, the two lowest qualities (2)
CLS_FEATURES = 14

KEEP_FEATURES = 13


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
