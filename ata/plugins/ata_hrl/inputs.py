"""The decoder's step inputs: how many features each sub-decision's candidates have, the
constants the decoder assumes, one step's inputs, and how they are written."""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

from ata.model.greedy_planner import HUMAN_TIME_COST, RATE_OFFSET_S
from ata.model.team import WINDOW_S

POI_FEATURES = 18
KEEP_FEATURES = 13
ROBOT_FEATURES = 12
NAV_FEATURES = 12
CLS_FEATURES = 14


def _quiet(method):
    """Numpy's warnings off: episodes whose decoding is over carry dummy choices (inf - inf)."""

    @functools.wraps(method)
    def wrapper(*args, **kwargs):
        with np.errstate(invalid="ignore", divide="ignore"):
            return method(*args, **kwargs)

    return wrapper


def _fill(out: np.ndarray, parts: list) -> np.ndarray:
    """Write `parts` side by side along `out`'s last axis and return `out` (float32): each part
    a column (broadcast to ``out.shape[:-1]``) or a block of columns (``out.ndim`` dimensions),
    cast as ``astype`` casts: the features np.stack and astype would give, without their
    intermediate arrays (the decoder builds four such arrays at each of a decode's steps)."""
    i = 0
    for part in parts:
        if np.ndim(part) == out.ndim:
            w = part.shape[-1]
            out[..., i:i + w] = part
            i += w
        else:
            out[..., i] = part
            i += 1
    assert i == out.shape[-1]
    return out


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
