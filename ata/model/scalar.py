"""The model's formulas for one value at a time, compiled with numba, for compiled loops that
score candidates one by one (the ATA-HRL decoder's POI step). Each is the formula of its array
twin, written in the same order of operations, so the two give the same bits
(tests/test_compiled_steps.py): `workload` is `ata.model.tables.workload`, `expected_points`
`tables.expected_points`, `human_net`, `option_value` and `rate` those of
`ata.model.greedy_score`, `cum_at` and `utilisation` `ata.model.load.HumanLoad`'s grid read,
`book` its booking.

`jit` is the host's way of compiling (`ata.model.compiling`): cached, and compiled again when
this module changes; the first process to call a function compiles it (a few seconds).
"""

from __future__ import annotations

import numpy as np

from ata.model.compiling import jit
from ata.model.tables import WORKLOAD_HIGH, WORKLOAD_LOW, WORKLOAD_PLATEAU

__all__ = ["jit", "workload", "expected_points", "human_net", "option_value", "rate", "cum_at",
           "utilisation", "book"]


_LO, _HI = WORKLOAD_PLATEAU
_A, _B, _C = WORKLOAD_LOW
_A2, _B2, _C2 = WORKLOAD_HIGH


@jit
def workload(u: float) -> float:
    if u < _LO:
        return _A * u * u + _B * u + _C
    if u < _HI:
        return 1.0
    return _A2 * u * u + _B2 * u - _C2


@jit
def expected_points(points: float, p_success: float) -> float:
    return points * (2.0 * p_success - 1.0)


@jit
def human_net(expected: float, t_bar: float, delay: float, price: float) -> float:
    return expected - price * (t_bar + delay)


@jit
def option_value(best_net: float, finish: float, horizon: float, onboard: float) -> float:
    v = best_net if finish <= horizon else 0.0
    return v if v >= onboard or np.isnan(v) else onboard


@jit
def rate(value: float, robot_s: float, offset_s: float) -> float:
    return value / (robot_s + offset_s)


@jit
def cum_at(flat: np.ndarray, base: int, last_edge: float, n_edges: int, bin_s: float,
           t: float) -> float:
    """Cumulative busy seconds by time t on a grid of `n_edges` edges `bin_s` apart whose
    values for one human start at flat[base] (linear within a bin)."""
    x = min(max(t, 0.0), last_edge) / bin_s
    k = min(int(x), n_edges - 2)
    frac = x - k
    lo = flat[base + k]
    return lo + frac * (flat[base + k + 1] - lo)


@jit
def utilisation(flat: np.ndarray, base: int, last_edge: float, n_edges: int, bin_s: float,
                window_s: float, t: float) -> float:
    """Busy share of [t - window, t] from the grid (`ata.model.load.HumanLoad.utilisation_at`)."""
    busy = (cum_at(flat, base, last_edge, n_edges, bin_s, t)
            - cum_at(flat, base, last_edge, n_edges, bin_s, t - window_s))
    span = min(window_s, max(t, 1e-9))
    return min(max(busy / span, 0.0), 1.0)


@jit
def book(cum: np.ndarray, booked: np.ndarray, free: np.ndarray, edges: np.ndarray, e: int,
         h: int, a: float, b: float) -> None:
    """`HumanLoad.book` of one (plan, human): human h of plan e busy over [a, b), in the load's
    arrays (cum (E, H, edges), booked and free (E, H))."""
    span = b - a
    row = cum[e, h]
    for k in range(edges.shape[0]):
        row[k] += min(max(edges[k] - a, 0.0), span)
    booked[e, h] += span
    free[e, h] = max(free[e, h], b)
