"""Counter-based random numbers: each scenario's draws depend on (root seed, scenario index) alone.

A batch of B scenarios must give every scenario the numbers it would get if it were run alone,
whatever the batch size or the number of worker processes. A stateful generator shared by the
batch cannot do that, so every draw here is a pure function of

    (scenario key, stream name, counter, element index)

hashed with the SplitMix64 finaliser. Components name their streams ("fatigue_noise", ...) and
pass a counter (an epoch index, say) so that no two draws of a scenario share an input.

Two generators serve a batch. The world's (`BatchRNG`: models, perturbations, injectors) is
keyed by the root seed and the scenario index. The decision-makers' (`decision_rng`: policies,
conditions, reconstructors) is keyed by a cryptographic hash of the two under a key of its own:
its streams share nothing with the world's whatever their names, and neither the seed nor a
world key can be worked back from it (SplitMix64 alone is invertible).
"""

from __future__ import annotations

import hashlib
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


DECISION_KEY = b"ata.decisions"
"""The personalisation of the decision-makers' key hash (16 bytes at most)."""


def decision_keys(root_seed: int, scenario_ids: np.ndarray) -> np.ndarray:
    """One uint64 key per scenario for the decision-makers' generator: BLAKE2b of the scenario
    index keyed by the root seed, so that it reveals neither the seed nor a world key."""
    seed = (int(root_seed) & 0xFFFFFFFFFFFFFFFF).to_bytes(8, "little")
    keys = [int.from_bytes(hashlib.blake2b(int(i).to_bytes(8, "little", signed=True),
                                           digest_size=8, key=seed,
                                           person=DECISION_KEY).digest(), "little")
            for i in np.asarray(scenario_ids, dtype=np.int64).ravel()]
    return np.array(keys, dtype=np.uint64)


class StreamRNG:
    """Per-scenario independent draws for a batch, keyed by stream name and counter, from one
    uint64 key per scenario."""

    def __init__(self, keys: np.ndarray):
        self.keys = np.asarray(keys, dtype=np.uint64)

    @property
    def batch_size(self) -> int:
        return int(self.keys.shape[0])

    def _stream_key(self, stream: str) -> np.uint64:
        return np.uint64(stream_id(stream)) * _M1

    def bits(self, stream: str, counter: int, shape: tuple[int, ...] = ()) -> np.ndarray:
        """uint64 draws of shape (B, *shape)."""
        n = int(np.prod(shape)) if shape else 1
        with np.errstate(over="ignore"):
            base = _mix(self.keys ^ self._stream_key(stream))
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

    def subset(self, index: np.ndarray) -> "StreamRNG":
        """The generator of a sub-batch: the same numbers for the same scenarios."""
        return StreamRNG(self.keys[index])


def decision_rng(root_seed: int, scenario_ids: Sequence[int] | np.ndarray) -> StreamRNG:
    """The decision-makers' generator of a batch (`DecisionContext.rng`): it carries neither
    the root seed nor the scenario indices."""
    return StreamRNG(decision_keys(root_seed, np.asarray(scenario_ids)))


class BatchRNG(StreamRNG):
    """The world's generator: per-scenario draws keyed by (root seed, scenario index).

    `resalted` gives the same generator with some streams drawing other numbers: the
    integrity check of `ata.testing` redraws what the decision-makers must not see.
    """

    def __init__(self, root_seed: int, scenario_ids: Sequence[int] | np.ndarray):
        self.root_seed = int(root_seed)
        self.scenario_ids = np.asarray(scenario_ids, dtype=np.int64)
        super().__init__(scenario_keys(self.root_seed, self.scenario_ids))
        self.salted: tuple[str, ...] = ()
        self.salt = 0

    def _stream_key(self, stream: str) -> np.uint64:
        key = super()._stream_key(stream)
        if self.salted and stream.startswith(self.salted):
            with np.errstate(over="ignore"):
                key ^= _mix(np.array([self.salt], dtype=np.uint64))[0]
        return key

    def resalted(self, streams: Sequence[str], salt: int = 1) -> "BatchRNG":
        """A copy whose streams named with one of the prefixes `streams` draw other numbers
        (salt 0: the same ones); every other stream is unchanged."""
        out = self.subset(np.arange(self.batch_size))
        out.salted, out.salt = tuple(streams), int(salt) & 0xFFFFFFFFFFFFFFFF
        return out

    def subset(self, index: np.ndarray) -> "BatchRNG":
        """The generator of a sub-batch: the same numbers for the same scenarios."""
        sub = BatchRNG.__new__(BatchRNG)
        sub.root_seed = self.root_seed
        sub.scenario_ids = self.scenario_ids[index]
        sub.keys = self.keys[index]
        sub.salted, sub.salt = self.salted, self.salt
        return sub
