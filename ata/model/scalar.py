"""The model's formulas for one value at a time, compiled with numba, for compiled loops that
score candidates one by one (the ATA-HRL decoder's steps, the projection's loop).

Most are not written here: `workload`, `human_success` and `expected_points` are
`ata.model.tables`' own functions, `individual` (a human's fatigue curve) is
`ata.model.fatigue`'s, `human_gain`, `human_net`, `option_value`, `rate` and `option_rate` are
`ata.model.greedy_score`'s, each compiled as it stands (`ata.model.generic` says how one
function serves arrays and numbers; this module registers the compiled form of its helpers, and
makes each shared formula callable from compiled code, so that one formula may call another).
`cum_at` and `utilisation` are
`ata.model.grid`'s, the load grid's read that `ata.model.load.HumanLoad` runs on arrays; `book`,
its booking of one (plan, human) in the load's arrays, adds `ata.model.grid.busy_ramp` as
`HumanLoad.book` does.

`jit` is the host's way of compiling (`ata.model.compiling`): cached, and compiled again when
a file of `ata.model` changes; the first process to call a function compiles it (a few seconds).
"""

from __future__ import annotations

import numpy as np
from numba.core import types
from numba.extending import overload, register_jitable

from ata.model import fatigue, generic, greedy_score, grid, tables
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


@overload(generic.as_int)
def _as_int(x):
    if isinstance(x, (types.Float, types.Integer)):
        return lambda x: int(x)
    return None


@overload(generic.take)
def _take(a, index):
    if isinstance(a, types.Array) and isinstance(index, types.Integer):
        return lambda a, index: a[index]
    return None


_SHARED = (tables.workload, tables.human_success, tables.expected_points, fatigue.individual,
           greedy_score.human_gain, greedy_score.human_net, greedy_score.option_value,
           greedy_score.rate, greedy_score.option_rate, grid.cum_at, grid.utilisation,
           grid.busy_ramp)
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


cum_at = jit(grid.cum_at)
utilisation = jit(grid.utilisation)


@jit
def book(cum: np.ndarray, booked: np.ndarray, free: np.ndarray, edges: np.ndarray, e: int,
         h: int, a: float, b: float) -> None:
    """`HumanLoad.book` of one (plan, human): human h of plan e busy over [a, b), in the load's
    arrays (cum (E, H, edges), booked and free (E, H))."""
    cum[e, h] += grid.busy_ramp(edges, a, b - a)
    booked[e, h] += b - a
    free[e, h] = max(free[e, h], b)
