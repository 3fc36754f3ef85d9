"""The tables and formulas of the model, as arrays and vectorised functions, for the team models
and the policies alike. Each formula is written once: `workload`, `human_success` and
`expected_points` use only arithmetic and `ata.model.generic`, so the same functions run on
arrays here and, compiled (`ata.model.scalar`), on numbers in the compiled loops.

Codes: kind 0 = air, 1 = ground; difficulty 0 = low, 1 = medium, 2 = high; image quality
0 = Low, 1 = Medium, 2 = Upper-Medium, 3 = High; robot type 0 = UAV, 1 = UGV; skill band
0 = low, 1 = medium, 2 = high; navigator class 0 = low skill, 1 = auto or medium, 2 = high.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from ata.model import fatigue as _fatigue
from ata.model import team
from ata.model.generic import as_float, select
from ata.model.team import FATIGUE_FLOOR

AIR, GROUND = 0, 1
UAV, UGV = 0, 1
KINDS = ("air", "ground")
DIFFICULTIES = ("low", "medium", "high")
QUALITIES = ("Low", "Medium", "Upper-Medium", "High")
SKILLS = ("low", "medium", "high")

def _frozen(table: np.ndarray) -> np.ndarray:
    """`table`, read-only for good: the world and every decision-maker read the same tables,
    so none may write them (an in-place edit would move another method's rows, or the world's).
    Its memory is an immutable bytes object, so its write flag cannot be set again."""
    data = np.ascontiguousarray(table)
    return np.frombuffer(data.tobytes(), dtype=data.dtype).reshape(data.shape)


POINTS = _frozen(np.array([15.0, 25.0, 35.0]))
"""Points by difficulty [paper]."""
MAX_POINTS = float(POINTS.max())
"""The most a POI is worth (35 points): the scale on which learned policies read points."""

QUALITY = _frozen(np.array([
    # navigator class:  low, auto/medium, high
    [[1, 2, 3],    # UAV, air POI
     [0, 1, 2]],   # UAV, ground POI
    [[0, 1, 2],    # UGV, air POI
     [1, 2, 3]],   # UGV, ground POI
], dtype=np.int64))
"""QUALITY[robot type, POI kind, navigator class] -> image quality [paper, Table I]."""

P_RC = _frozen(np.array([[0.5, 0.3, 0.1],
                 [0.6, 0.4, 0.2],
                 [0.7, 0.5, 0.3],
                 [0.8, 0.6, 0.4]]))
"""P_RC[quality, difficulty]: onboard classification success [testbed]."""

T_BAR = _frozen(np.array([[45.0, 125.0, 245.0],
                  [35.0, 95.0, 195.0],
                  [25.0, 65.0, 145.0],
                  [15.0, 35.0, 95.0]]))
"""T_BAR[quality, difficulty]: human classification time in seconds [testbed]."""

SKILL_SPEED = _frozen(np.array(team.SKILL_SPEED))
"""Speed multiplier under a human navigator of skill band low, medium, high [testbed ratio]."""


def decision_difficulty(t_bar: np.ndarray) -> np.ndarray:
    """F_d = 1 / (1 + exp(0.04 (t_bar - 180)))."""
    return 1.0 / (1.0 + np.exp(0.04 * (np.asarray(t_bar, dtype=float) - 180.0)))


F_D = _frozen(decision_difficulty(T_BAR))
"""F_D[quality, difficulty]."""


class Tables(NamedTuple):
    """The tables a compiled loop reads, as one record: a loop takes `TABLES` and reads each
    table by its name (numba reads a named tuple's fields by name)."""

    quality: np.ndarray
    p_rc: np.ndarray
    t_bar: np.ndarray
    f_d: np.ndarray
    skill_speed: np.ndarray


TABLES = Tables(QUALITY, P_RC, T_BAR, F_D, SKILL_SPEED)
"""`QUALITY`, `P_RC`, `T_BAR`, `F_D` and `SKILL_SPEED` as one `Tables` record."""


def fatigue(hours: np.ndarray, floor: float = FATIGUE_FLOOR) -> np.ndarray:
    """F_f of the population line: 1 below one working hour, then 1.3 - 0.3 T, not below
    ``floor`` (`ata.model.fatigue.individual` at the population's onset and slope)."""
    return _fatigue.individual(hours, _fatigue.ONSET_H, _fatigue.SLOPE_PER_H, floor)


WORKLOAD_PLATEAU = (0.45, 0.65)
"""F_w is 1 for a utilisation u in [0.45, 0.65) [paper]; below, a human is too idle, above, too
busy."""
WORKLOAD_LOW = (-2.47, 2.22, 0.5)
"""F_w = a u^2 + b u + c below the plateau, (a, b, c) [paper]."""
WORKLOAD_HIGH = (-4.08, 5.31, 0.724)
"""F_w = a u^2 + b u - c from the plateau's end, (a, b, c) [paper]."""
FATIGUED_BELOW = 0.95
"""A classification counts as fatigued when F_f is below this (the calibration target, the human
model's ``fatigued_share``)."""


def workload(u: np.ndarray) -> np.ndarray:
    """F_w of utilisation u: rising quadratic, plateau at 1 on `WORKLOAD_PLATEAU`, falling
    quadratic."""
    u = as_float(u)
    (a, b, c), (a2, b2, c2) = WORKLOAD_LOW, WORKLOAD_HIGH
    low = a * u * u + b * u + c
    high = a2 * u * u + b2 * u - c2
    return select(u < WORKLOAD_PLATEAU[0], low, select(u < WORKLOAD_PLATEAU[1], 1.0, high))


def human_success(eta: np.ndarray, lam: np.ndarray, f_f: np.ndarray, f_w: np.ndarray,
                  f_d: np.ndarray) -> np.ndarray:
    """P_hc = 1/2 + eta * F_f * F_w * lambda * F_d, multiplied in that order.

    The one definition of P_hc. A caller that holds a product of some factors already (eta *
    lambda, or eta * F_f * lambda) passes it as `eta` and 1.0 for each factor it holds: a
    product with 1.0 is exact, so P_hc has the bits of that caller's order of multiplication.
    """
    return 0.5 + eta * f_f * f_w * lam * f_d


def skill_band(theta_s: np.ndarray) -> np.ndarray:
    """Skill band from theta_s: low below pi/12, medium below pi/6, high from pi/6."""
    t = np.asarray(theta_s, dtype=float)
    return np.where(t < np.pi / 12, 0, np.where(t < np.pi / 6, 1, 2)).astype(np.int64)


def navigator_class(navigator: np.ndarray, skill: np.ndarray) -> np.ndarray:
    """Navigator class per task: 1 for auto (navigator -1), else the human's skill band.

    :param navigator: (B, ...) human index or -1; :param skill: (B, H) skill bands.
    """
    nav = np.asarray(navigator)
    flat = nav.reshape(nav.shape[0], -1)
    # plain indexing: the same values as take_along_axis, without its per-call index building
    cls = skill[np.arange(flat.shape[0])[:, None], np.maximum(flat, 0)]
    return np.where(flat < 0, 1, cls).reshape(nav.shape)


def expected_points(points: np.ndarray, p_success: np.ndarray) -> np.ndarray:
    """Expected score of a classification: +points with p, -points with 1 - p."""
    return points * (2.0 * p_success - 1.0)


def working_hours(t0_h: np.ndarray, busy_ticks: np.ndarray, now: float, tick_s: float
                  ) -> np.ndarray:
    """Working time T in hours at a tick boundary `now`: the initial T0 (B, H) plus the busy
    seconds booked in the ticks before it (`busy_ticks`, (B, H, n_ticks))."""
    k = int(round(now / tick_s))
    return t0_h + busy_ticks[:, :, :k].sum(axis=2) / 3600.0


def utilisation(busy_ticks: np.ndarray, now: float, tick_s: float, window_s: float
                ) -> np.ndarray:
    """Busy share u of the trailing `window_s` at a tick boundary `now` (of the elapsed time
    before the window has passed), (B, H)."""
    k = int(round(now / tick_s))
    lo = max(0, k - int(round(window_s / tick_s)))
    span = min(window_s, now)
    if span <= 0:
        return np.zeros(busy_ticks.shape[:2])
    return np.minimum(1.0, busy_ticks[:, :, lo:k].sum(axis=2) / span)


def awareness(sa: np.ndarray, sa_time: np.ndarray, now: float | np.ndarray,
              recovery_per_min: float) -> np.ndarray:
    """Situational awareness at `now` from its value `sa` at `sa_time`: it recovers by
    `recovery_per_min` a minute, up to 1 (a value set for a later time stays as it is)."""
    recovered = np.minimum(1.0, sa + recovery_per_min * (now - sa_time) / 60.0)
    return np.where(sa_time <= now, recovered, sa)
