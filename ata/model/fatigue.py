"""Individual fatigue (docs/model.md: "Humans"), and what a policy believes about it.

A human's F_f is 1 below the onset T_on (hours of work), then ``max(floor, 1 - k (T - T_on))``.
Each human's onset and slope are drawn per scenario and hidden; ``fatigue_spread`` s sets how far
they range around the testbed's population line (onset 1 h, slope 0.3 per hour):
``T_on ~ U(1 - s/2, 1 + s/2)``, ``k ~ U(0.3 (1 - 2s/3), 0.3 (1 + 2s/3))``. With s = 0 every human
has the population line, and `individual` equals `tables.fatigue` to the bit.

A planner projects fatigue ahead with a `FatigueBelief`: for every human, a weighted set of
(onset, slope) curves, whose weighted mean is the estimate of F_f at any working time, plus an
offset. A reconstructor hands one over through ``ctx.reconstructed`` under the keys of
`BELIEF_KEYS` (each (B, H, K)): the ``oracle`` one curve, the truth; the ``filter`` its
posterior over a grid. Without those keys, `belief_from` takes the fatigue of the reconstructed
(or observed) S as the value now and moves it ahead along the population line: what a policy
reading the raw noisy observation knows.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Mapping

import numpy as np

from ata.model.generic import as_float, select

ONSET_H = 1.0
"""The population's fatigue onset, hours of work (docs/model.md, "Humans"[testbed])."""
SLOPE_PER_H = 0.3
"""The population's fatigue slope, per hour of work after the onset ([testbed])."""
FATIGUE_SPREAD = 1.0
"""The default spread s of the individual onsets and slopes ([default])."""

BELIEF_KEYS = ("fatigue_onset", "fatigue_slope", "fatigue_weight")
"""The keys of ``ctx.reconstructed`` that carry a `FatigueBelief` (each (B, H, K))."""
CURVE_KEYS = ("fatigue_onset", "fatigue_slope")
"""The names under which a human model hides each human's true onset and slope in the true S
(``Observation.hide``, each (B, H)): never observed, only a reference reconstructor gets them."""


def onset_range(spread: float) -> tuple[float, float]:
    """(low, high) of the individual onset T_on, hours, for spread s."""
    return ONSET_H - spread / 2.0, ONSET_H + spread / 2.0


def slope_range(spread: float) -> tuple[float, float]:
    """(low, high) of the individual slope k, per hour, for spread s."""
    return SLOPE_PER_H * (1.0 - 2.0 * spread / 3.0), SLOPE_PER_H * (1.0 + 2.0 * spread / 3.0)


def individual(hours: np.ndarray, onset: np.ndarray, slope: np.ndarray,
               floor: float) -> np.ndarray:
    """F_f at working time `hours` of humans with this onset and slope (broadcast): 1 before
    the onset, then ``max(floor, 1 - k (T - T_on))``, written as ``(1 + k T_on) - k T`` so that
    onset 1 and slope 0.3 give the population line ``1.3 - 0.3 T`` to the bit. The one
    definition of the curve: the compiled loops run this function too (`ata.model.scalar`)."""
    h = as_float(hours)
    return select(h < onset, 1.0, np.maximum(floor, (1.0 + slope * onset) - slope * h))


@dataclass(frozen=True)
class FatigueBelief:
    """What a policy believes of every human's fatigue curve: weights (B, H, K) over curves of
    onsets and slopes (B, H, K), plus an offset (B, H) on their weighted mean. `at` gives the
    estimate of F_f at any working time, within [floor, 1]."""

    onset: np.ndarray
    slope: np.ndarray
    weight: np.ndarray
    offset: np.ndarray
    floor: float

    @classmethod
    def exact(cls, onset: np.ndarray, slope: np.ndarray, floor: float) -> "FatigueBelief":
        """One curve per human, known: onset and slope (B, H)."""
        return cls(onset[..., None], slope[..., None], np.ones(onset.shape + (1,)),
                   np.zeros(onset.shape), float(floor))

    @classmethod
    def shifted(cls, now: np.ndarray, hours_now: np.ndarray, floor: float) -> "FatigueBelief":
        """The value `now` (B, H) at working time `hours_now` (B, H), moved ahead along the
        population line: ``clip(now, floor, 1) + F(T) - F(T_now)`` (the population's F)."""
        onset = np.full(now.shape, ONSET_H)
        slope = np.full(now.shape, SLOPE_PER_H)
        offset = np.clip(now, floor, 1.0) - individual(hours_now, onset, slope, floor)
        return cls(onset[..., None], slope[..., None], np.ones(now.shape + (1,)), offset,
                   float(floor))

    @property
    def curves(self) -> int:
        return self.weight.shape[-1]

    def at(self, hours: np.ndarray, rows: tuple[np.ndarray, np.ndarray] | None = None
           ) -> np.ndarray:
        """The estimate of F_f at working time `hours`: (B, H) or, with leading axes, (..., B,
        H)... broadcast against the humans; or, with ``rows = (b, h)`` index arrays, of those
        humans at `hours` of the same shape as b."""
        if rows is None:
            on, sl, w, off = self.onset, self.slope, self.weight, self.offset
        else:
            b, h = rows
            on, sl, w, off = self.onset[b, h], self.slope[b, h], self.weight[b, h], self.offset[b, h]
        hours = np.asarray(hours, dtype=float)
        if w.shape[-1] == 1:
            f = individual(hours, on[..., 0], sl[..., 0], self.floor)
        else:
            f = (w * individual(hours[..., None], on, sl, self.floor)).sum(-1)
        return np.clip(f + off, self.floor, 1.0)

    def ahead(self, hours: np.ndarray, free: np.ndarray, now: float,
              rows: tuple[np.ndarray, np.ndarray] | None = None) -> np.ndarray:
        """The estimate of F_f of humans at working time `hours` now once they are free at
        `free` (seconds; now if earlier): `at` the hours plus the time booked until then."""
        return self.at(hours + np.maximum(free - now, 0) / 3600.0, rows)

    def take(self, rows: np.ndarray) -> "FatigueBelief":
        """The belief of a sub-batch of scenarios (or of plans: rows may repeat)."""
        return FatigueBelief(self.onset[rows], self.slope[rows], self.weight[rows],
                             self.offset[rows], self.floor)


def has_belief(reconstructed: Mapping[str, np.ndarray]) -> bool:
    """Whether a reconstructor handed over a belief (every key of `BELIEF_KEYS`)."""
    return all(k in reconstructed for k in BELIEF_KEYS)


def belief_from(reconstructed: Mapping[str, np.ndarray], fatigue_now: np.ndarray,
                hours_now: np.ndarray, floor: float) -> FatigueBelief:
    """The belief a reconstructor handed over in `reconstructed` (the `BELIEF_KEYS`), else the
    value `fatigue_now` (B, H) (the reconstructed or observed S) moved ahead along the
    population line from `hours_now`."""
    if has_belief(reconstructed):
        on, sl, w = (np.asarray(reconstructed[k], dtype=float) for k in BELIEF_KEYS)
        return FatigueBelief(on, sl, w, np.zeros(on.shape[:-1]), float(floor))
    return FatigueBelief.shifted(np.asarray(fatigue_now, dtype=float),
                                 np.asarray(hours_now, dtype=float), floor)
