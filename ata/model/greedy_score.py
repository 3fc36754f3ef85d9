"""Greedy's score of a candidate, written once: what a human classification is worth net of the
human's time, what an option (a robot, with or without a navigator, at a POI) is worth, and the
rate of that worth per robot second. The greedy planner (`ata.model.greedy_planner`) ranks its
candidates by these, and learned policies that build on greedy use them as their prior. Each is
one function for arrays and numbers (`ata.model.generic`): the compiled loops run these same
functions (`ata.model.scalar`)."""

from __future__ import annotations

import numpy as np

from ata.model.generic import select


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
