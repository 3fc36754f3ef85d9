"""What lets a formula of the model be written once, for arrays and for numbers: `select`,
`as_float`, `as_int` and `take` are numpy's ``where``, ``asarray(x, dtype=float)``,
``astype(int64)`` and ``take`` on arrays, and, in code compiled by `ata.model.compiling.jit`,
``a if cond else b``, ``float(x)``, ``int(x)`` and ``a[i]`` on numbers (`ata.model.scalar`
registers that compiled form).

A formula written with these, numpy's ``maximum`` and ``minimum`` and plain arithmetic is one
function: numpy runs it on arrays, and `ata.model.scalar` compiles that same function for the
loops that take one value at a time. The compiled form does the same operations in the same
order, without fast-math, so it gives numpy's bits.
"""

from __future__ import annotations

import numpy as np


def select(cond, a, b):
    """``a`` where `cond`, else ``b`` (numpy's ``where``; compiled, on numbers, ``a if cond
    else b``)."""
    return np.where(cond, a, b)


def as_float(x):
    """`x` as floats (``np.asarray(x, dtype=float)``; compiled, on a number, ``float(x)``)."""
    return np.asarray(x, dtype=float)


def as_int(x):
    """`x` truncated to integers (``x.astype(np.int64)``; compiled, on a number, ``int(x)``)."""
    return np.asarray(x).astype(np.int64)


def take(a, index):
    """The elements of the flat array `a` at `index` (``a.take(index)``; compiled, at an
    integer, ``a[index]``)."""
    return a.take(index)
