"""Greedy's score of a candidate, written once: what a human classification is expected to earn
and what it is worth net of the human's time, what an option (a robot, with or without a
navigator, at a POI) is worth, and the rate of that worth per robot second. The greedy planner
(`ata.model.greedy_planner`) ranks its candidates by these, and learned policies that build on
greedy use them as their prior (the ATA-HRL decoder's compiled steps). Each is one function for
arrays and numbers (`ata.model.generic`): the compiled loops run these same functions
(`ata.model.scalar`)."""

from __future__ import annotations

import numpy as np

from ata.model import tables
from ata.model.generic import select


def human_gain(eta: np.ndarray, lam: np.ndarray, f_f: np.ndarray, f_d: np.ndarray,
               points: np.ndarray) -> np.ndarray:
    """The expected points of a human classification as greedy scores it: P_hc
    (`tables.human_success`) with F_w = 1, greedy projecting no workload. A caller holding eta
    * lambda passes it as `eta` and 1.0 as `lam`."""
    return tables.expected_points(points, tables.human_success(eta, lam, f_f, 1.0, f_d))


def human_net(expected: np.ndarray, t_bar: np.ndarray, delay: np.ndarray,
              price: float) -> np.ndarray:
    """A human classification's expected points less the price of the human's time: the item
    (`t_bar` seconds) and the wait until the image arrives (`delay`), at `price` a second."""
    return expected - price * (t_bar + delay)


def option_value(best_net: np.ndarray, finish: np.ndarray, horizon: float,
                 onboard: np.ndarray) -> np.ndarray:
    """An option's worth: the best human's net value (0 where that human would finish after
    the horizon: an unclassified POI scores 0), or classifying onboard, whichever is more."""
    return np.maximum(select(finish <= horizon, best_net, 0.0), onboard)


def rate(value: np.ndarray, robot_s: np.ndarray, offset_s: float) -> np.ndarray:
    """Worth per robot second: `value` over the robot's seconds until the capture plus
    `offset_s` (which favours value over nearness)."""
    return value / (robot_s + offset_s)


def option_rate(best_net: np.ndarray, finish: np.ndarray, horizon: float,
                onboard: np.ndarray, cost: np.ndarray, robot_s: np.ndarray,
                offset_s: float) -> np.ndarray:
    """Greedy's score of an option: its worth (`option_value`) less what it costs besides (a
    human navigator's time), per robot second (`rate`)."""
    return rate(option_value(best_net, finish, horizon, onboard) - cost, robot_s, offset_s)
