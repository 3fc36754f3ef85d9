"""Work passed between models: named queues of rows, and the helpers an owner writes them with.

A model never writes another's arrays: a robot's capture, a human's work item, a perturbation
drawn at set-up travel as rows of a queue (``sim.queue(name)``) that the owner of the state
takes and scatters into its own arrays.
"""

from __future__ import annotations

from typing import Any

import numpy as np


class Queue:
    """Work passed from one model to another: the producer puts rows (columns of equal length,
    one row per item, by name), the consumer takes every pending row at once, in the order put.

    Models never write each other's arrays: a robot's capture, a human's work item, a
    perturbation drawn at set-up travel as rows of a queue that the owner of the state takes.
    """

    def __init__(self, name: str):
        self.name = name
        self._parts: list[dict[str, np.ndarray]] = []
        self._columns: tuple[str, ...] | None = None

    def put(self, **columns: Any) -> None:
        """Append rows: every column a 1-D array (or a scalar, broadcast) of one length."""
        names = tuple(sorted(columns))
        if self._columns is None:
            self._columns = names
        elif names != self._columns:
            raise ValueError(f"queue {self.name!r} takes columns {', '.join(self._columns)}; "
                             f"got {', '.join(names)}")
        arrays = {k: v if type(v) is np.ndarray and v.ndim == 1 else np.atleast_1d(np.asarray(v))
                  for k, v in columns.items()}
        lengths = {a.shape[0] for a in arrays.values()}
        n = max(lengths)
        if len(lengths) > 1 or any(a.ndim != 1 for a in arrays.values()):
            for k, a in arrays.items():
                if a.ndim != 1 or a.shape[0] not in (1, n):
                    raise ValueError(f"queue {self.name!r}: column {k!r} has shape {a.shape}; "
                                     f"expected ({n},)")
                if a.shape[0] != n:
                    arrays[k] = np.repeat(a, n)
        if n:
            self._parts.append(arrays)

    def __len__(self) -> int:
        return sum(next(iter(p.values())).shape[0] for p in self._parts)

    def take(self) -> dict[str, np.ndarray] | None:
        """Every pending row, concatenated in the order put, and the queue emptied; None when
        nothing is pending."""
        if not self._parts:
            return None
        parts, self._parts = self._parts, []
        if len(parts) == 1:
            return parts[0]
        return {k: np.concatenate([p[k] for p in parts]) for k in parts[0]}


def scatter(state: Any, rows: dict[str, np.ndarray], at: tuple[str, ...],
            columns: dict[str, str]) -> None:
    """Write taken queue rows into the owner's arrays: ``state.FIELD[rows[at]] = rows[COLUMN]``
    for each FIELD -> COLUMN of `columns` (`at` names the index columns, e.g. ("b", "p"))."""
    index = tuple(rows[k] for k in at)
    for name, column in columns.items():
        getattr(state, name)[index] = rows[column]


def run_starts(sorted_keys: np.ndarray) -> np.ndarray:
    """(n,) bool: where each run of equal keys begins in a sorted 1-D array of n >= 1 keys."""
    out = np.empty(sorted_keys.size, dtype=bool)
    out[0] = True
    np.not_equal(sorted_keys[1:], sorted_keys[:-1], out=out[1:])
    return out


def last_per_key(*keys: np.ndarray) -> np.ndarray:
    """Indices of the last row of each distinct key (rows taken in order: the latest wins), in
    the order of the keys. Keys are non-negative integer columns (indices: scenario, robot)."""
    n = keys[0].shape[0]
    if n <= 1:
        return np.arange(n)
    key = keys[0].astype(np.int64)
    for k in keys[1:]:                                  # one key, ordered as the tuple of keys
        key = key * (int(k.max()) + 1) + k
    order = np.argsort(key, kind="stable")              # stable: rows in order per key
    last = np.append(run_starts(key[order])[1:], True)  # a row before a new key is a last
    return order[last]
