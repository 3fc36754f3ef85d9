"""The constants a team model publishes for the policies, typed, with the model's defaults.

The built-in human and robot models publish a `HumanConstants` and a `RobotConstants` in
``ata_setup`` (``sim.publish(value)``), from their settings. A policy reads them from its context
(``ctx.published(HumanConstants)``), the recorder of ``ata show`` from the simulation
(``sim.published``). A replacement team model publishes its own values of these types, and the
policies price it by them; one that publishes none makes a policy that needs them fail with an
error naming the missing type, never assume a default.

The module constants are the model's defaults, held here once: the team models' settings start
from them, and so do the fields of the published types.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

from ata.model.fatigue import FATIGUE_SPREAD

FATIGUE_FLOOR = 0.4
"""The lowest F_f (section 5, [default])."""
WINDOW_S = 300.0
"""Utilisation is the busy share of this trailing window, s (section 5, [testbed])."""
SA_DROP = 0.25
"""SA lost on a switch of robot (section 5)."""
SA_RECOVERY_PER_MIN = 0.1
"""SA regained a minute of work on the same robot, or idle (section 5)."""
SWITCH_COST_S = 30.0
"""A switch costs (1 - SA) times this in extra busy time, s (section 5)."""
REBRIEF_S = 20.0
"""Busy time of a human whose work a reallocation changes, s (section 3a)."""
CAPTURE_S = 3.0
"""Time to capture the image at a POI, s (section 4, [testbed])."""
REPLAN_S = 10.0
"""Hold of a robot out on its route whose next target a reallocation changes, s (section 3a)."""
UAV_SPEED = 8.0
"""A UAV's autonomous speed, m/s (section 4, [testbed]); learned policies read speeds in units of
it."""
UGV_SPEED = 3.0
"""A UGV's autonomous speed, m/s (section 4, [testbed])."""
SKILL_SPEED = (2.0 / 3.0, 1.0, 1.5)
"""Speed factor under a human navigator of skill band low, medium, high (section 4)."""


@dataclass(frozen=True)
class HumanConstants:
    """The human model's constants that a policy may assume (docs/library.md)."""

    published_by: ClassVar[str] = "the human model (slot human_model)"

    fatigue_floor: float = FATIGUE_FLOOR
    fatigue_spread: float = FATIGUE_SPREAD
    """Spread s of the hidden individual onsets and slopes (`ata.model.fatigue`): the prior
    is public, each human's draw is not."""
    window_s: float = WINDOW_S
    sa_drop: float = SA_DROP
    sa_recovery_per_min: float = SA_RECOVERY_PER_MIN
    switch_cost_s: float = SWITCH_COST_S
    rebrief_s: float = REBRIEF_S


@dataclass(frozen=True)
class RobotConstants:
    """The robot model's constants that a policy may assume (docs/library.md)."""

    published_by: ClassVar[str] = "the robot model (slot robot_model)"

    capture_s: float = CAPTURE_S
    replan_s: float = REPLAN_S
    skill_speed: tuple[float, float, float] = SKILL_SPEED
