"""Counter-based random numbers: each scenario's draws depend on (root seed, scenario index) alone.

A batch of B scenarios must give every scenario the numbers it would get if it were run alone,
whatever the batch size or the number of worker processes. A stateful generator shared by the
batch cannot do that, so every draw here is a pure function of

    (scenario key, stream name, counter, element index)

hashed with the SplitMix64 finaliser. Components name their streams ("fatigue_noise", ...) and
pass a counter (an epoch index, say) so that no two draws of a scenario share an input.
"""

from __future__ import annotations

import zlib
from typing import Sequence

import numpy as np

_M1 = np.uint64(0xBF58476D1CE4E5B9)
_M2 = np.uint64(0x94D049BB133111EB)
_GOLDEN = np.uint64(0x9E3779B97F4A7C15)
_S30, _S27, _S31 = np.uint64(30), np.uint64(27), np.uint64(31)
_TO_UNIT = 1.0 / float(1 << 53)


def _mix(x: np.ndarray) -> np.ndarray:
    """SplitMix64 finaliser on a uint64 array (wrapping arithmetic)."""
    with np.errstate(over="ignore"):
        x = (x ^ (x >> _S30)) * _M1
        x = (x ^ (x >> _S27)) * _M2
        return x ^ (x >> _S31)


def stream_id(name: str) -> int:
    """A stable 32-bit id for a stream name (crc32, identical on every platform and run)."""
    return zlib.crc32(name.encode("utf-8"))


def scenario_keys(root_seed: int, scenario_ids: np.ndarray) -> np.ndarray:
    """One uint64 key per scenario, a function of the root seed and the scenario index only."""
    ids = np.asarray(scenario_ids, dtype=np.uint64)
    with np.errstate(over="ignore"):
        seed = _mix(np.array([root_seed & 0xFFFFFFFFFFFFFFFF], dtype=np.uint64))
        return _mix(seed ^ ((ids + np.uint64(1)) * _GOLDEN))


class BatchRNG:
    """Per-scenario independent draws for a batch, keyed by stream name and counter."""

    def __init__(self, root_seed: int, scenario_ids: Sequence[int] | np.ndarray):
        self.root_seed = int(root_seed)
        self.scenario_ids = np.asarray(scenario_ids, dtype=np.int64)
        self.keys = scenario_keys(self.root_seed, self.scenario_ids)

    @property
    def batch_size(self) -> int:
        return int(self.keys.shape[0])

    def bits(self, stream: str, counter: int, shape: tuple[int, ...] = ()) -> np.ndarray:
        """uint64 draws of shape (B, *shape)."""
        n = int(np.prod(shape)) if shape else 1
        with np.errstate(over="ignore"):
            base = _mix(self.keys ^ (np.uint64(stream_id(stream)) * _M1))
            base = _mix(base ^ (np.uint64(counter & 0xFFFFFFFF) * _M2 + _GOLDEN))
            idx = np.arange(n, dtype=np.uint64) * _GOLDEN
            out = _mix(base[:, None] + idx[None, :])
        return out.reshape((self.batch_size, *shape))

    def uniform(self, stream: str, counter: int, shape: tuple[int, ...] = ()) -> np.ndarray:
        """Floats in [0, 1) of shape (B, *shape)."""
        return (self.bits(stream, counter, shape) >> np.uint64(11)).astype(np.float64) * _TO_UNIT

    def normal(self, stream: str, counter: int, shape: tuple[int, ...] = ()) -> np.ndarray:
        """Standard normal draws of shape (B, *shape), by Box-Muller on two uniforms."""
        u1 = self.uniform(stream + "#n1", counter, shape)
        u2 = self.uniform(stream + "#n2", counter, shape)
        return np.sqrt(-2.0 * np.log1p(-u1)) * np.cos(2.0 * np.pi * u2)

    def integers(self, stream: str, counter: int, high: int | np.ndarray,
                 shape: tuple[int, ...] = ()) -> np.ndarray:
        """Integers in [0, high) of shape (B, *shape); `high` may broadcast against that shape."""
        u = self.uniform(stream, counter, shape)
        return np.minimum((u * high).astype(np.int64), np.asarray(high) - 1)

    def subset(self, index: np.ndarray) -> "BatchRNG":
        """The generator of a sub-batch: the same numbers for the same scenarios."""
        sub = BatchRNG.__new__(BatchRNG)
        sub.root_seed = self.root_seed
        sub.scenario_ids = self.scenario_ids[index]
        sub.keys = self.keys[index]
        return sub
