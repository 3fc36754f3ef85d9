"""The model's formulas for one value at a time, compiled with numba, for compiled loops that
score candidates one by one (the ATA-HRL decoder's steps, the projection's loop).

Most are not written here: `workload`, `human_success` and `expected_points` are
`ata.model.tables`' own functions, `individual` (a human's fatigue curve) is
`ata.model.fatigue`'s, `human_gain`, `human_net`, `option_value`, `rate` and `option_rate` are
`ata.model.greedy_score`'s, each compiled as it stands (`ata.model.generic` says how one
function serves arrays and numbers; this module registers the compiled form of its helpers, and
makes each shared formula callable from compiled code, so that one formula may call another).
Written here is the compiled
form of `ata.model.load.HumanLoad`'s grid, which its arrays read in bulk: `cum_at` and
`utilisation` its grid read, `book` its booking, each in the order of operations of its array
twin (tests/test_compiled_steps.py).

`jit` is the host's way of compiling (`ata.model.compiling`): cached, and compiled again when
a file of `ata.model` changes; the first process to call a function compiles it (a few seconds).
"""

from __future__ import annotations

import numpy as np
from numba.core import types
from numba.extending import overload, register_jitable

from ata.model import fatigue, generic, greedy_score, tables
from ata.model.compiling import jit

__all__ = ["jit", "workload", "human_success", "expected_points", "individual", "human_gain",
           "human_net", "option_value", "rate", "option_rate", "cum_at", "utilisation", "book"]


# the compiled form of `ata.model.generic` on numbers, registered before anything compiles
@overload(generic.select)
def _select(cond, a, b):
    if isinstance(cond, types.Boolean):
        return lambda cond, a, b: a if cond else b
    return None


@overload(generic.as_float)
def _as_float(x):
    if isinstance(x, (types.Float, types.Integer, types.Boolean)):
        return lambda x: float(x)
    return None


_SHARED = (tables.workload, tables.human_success, tables.expected_points, fatigue.individual,
           greedy_score.human_gain, greedy_score.human_net, greedy_score.option_value,
           greedy_score.rate, greedy_score.option_rate)
# each callable from compiled code as it stands, so that one calling another compiles too
for _fn in _SHARED:
    register_jitable(nogil=True, error_model="numpy")(_fn)

workload = jit(tables.workload)
human_success = jit(tables.human_success)
expected_points = jit(tables.expected_points)
individual = jit(fatigue.individual)
human_gain = jit(greedy_score.human_gain)
human_net = jit(greedy_score.human_net)
option_value = jit(greedy_score.option_value)
rate = jit(greedy_score.rate)
option_rate = jit(greedy_score.option_rate)


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
