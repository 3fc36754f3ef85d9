"""Counter-based random numbers that keep their secrets: a draw is a keyed pseudo-random function
of (scenario key, stream name, counter, element index), and no number of outputs reveals the key.

A batch of B scenarios must give every scenario the numbers it would get if it were run alone,
whatever the batch size or the number of worker processes, so every draw is a pure function of

    (scenario key, stream name, counter, element index)

with no state shared by the batch. Components name their streams ("fatigue_noise", ...) and
pass a counter (an epoch index, say) so that no two draws of a scenario share an input.

The function is Threefry-2x64 with 20 rounds (Salmon et al., "Parallel random numbers: as easy
as 1, 2, 3", SC'11; the generator JAX and Random123 use), a tweakable block cipher run in
counter mode: the scenario's 128-bit key, the block (stream word, counter and block index). The
stream word is a BLAKE2b digest of the stream name. A policy is shown some outputs of some
streams (POI positions in I, noisy fatigue in S); working back to the key from them is a
known-plaintext attack on the cipher, for which no method better than searching 2^128 keys is
known, and without the key no other stream, nor an unseen element of a shown one, can be told.

Each scenario's key is itself a keyed BLAKE2b hash of its index under the root seed, with a
personalisation per purpose: the world's generator (`BatchRNG`: models, perturbations,
injectors) and the decision-makers' (`decision_rng`: policies, conditions, reconstructors)
share no key, and neither key leads back to the root seed or to the other.
"""

from __future__ import annotations

import functools
import hashlib
from typing import Sequence

import numpy as np

ROUNDS = 20
"""Threefry-2x64's rounds: 13 pass every statistical test; 20 is Random123's choice."""
_ROTATIONS = (16, 42, 12, 31, 16, 32, 24, 21)
_PARITY = np.uint64(0x1BD11BDAA9FC1A22)
_TO_UNIT = 1.0 / float(1 << 53)
WORLD_KEY = b"ata.world"
"""The personalisation of the world's scenario keys (16 bytes at most)."""
DECISION_KEY = b"ata.decisions"
"""The personalisation of the decision-makers' scenario keys (16 bytes at most)."""


def threefry2x64(k0: np.ndarray, k1: np.ndarray, c0: np.ndarray, c1: np.ndarray
                 ) -> tuple[np.ndarray, np.ndarray]:
    """Threefry-2x64-20 of counter blocks (c0, c1) under keys (k0, k1), all uint64 arrays that
    broadcast together: the two output words, each of the broadcast shape."""
    k0, k1 = np.asarray(k0, dtype=np.uint64), np.asarray(k1, dtype=np.uint64)
    schedule = (k0, k1, k0 ^ k1 ^ _PARITY)
    shape = np.broadcast_shapes(k0.shape, k1.shape, np.shape(c0), np.shape(c1))
    x0 = np.empty(shape, dtype=np.uint64)
    x1 = np.empty(shape, dtype=np.uint64)
    spare = np.empty(shape, dtype=np.uint64)
    with np.errstate(over="ignore"):
        np.add(c0, k0, out=x0, dtype=np.uint64, casting="unsafe")
        np.add(c1, k1, out=x1, dtype=np.uint64, casting="unsafe")
        for r in range(ROUNDS):
            rot = _ROTATIONS[r % 8]
            np.add(x0, x1, out=x0)
            np.left_shift(x1, np.uint64(rot), out=spare)
            np.right_shift(x1, np.uint64(64 - rot), out=x1)
            np.bitwise_or(x1, spare, out=x1)
            np.bitwise_xor(x1, x0, out=x1)
            if r % 4 == 3:                      # the key schedule's injection
                s = (r + 1) // 4
                np.add(x0, schedule[s % 3], out=x0)
                np.add(x1, schedule[(s + 1) % 3] + np.uint64(s), out=x1)
    return x0, x1


@functools.lru_cache(maxsize=4096)
def stream_word(name: str) -> int:
    """A stream name's 64-bit word of the counter block (a BLAKE2b digest of the name)."""
    digest = hashlib.blake2b(name.encode("utf-8"), digest_size=8, person=b"ata.stream")
    return int.from_bytes(digest.digest(), "little")


def _scenario_keys(root_seed: int, scenario_ids: np.ndarray, person: bytes) -> np.ndarray:
    """(B, 2) uint64: BLAKE2b of each scenario index keyed by the root seed, personalised."""
    seed = (int(root_seed) & 0xFFFFFFFFFFFFFFFF).to_bytes(8, "little")
    ids = np.asarray(scenario_ids, dtype=np.int64).ravel()
    raw = b"".join(hashlib.blake2b(int(i).to_bytes(8, "little", signed=True), digest_size=16,
                                   key=seed, person=person).digest() for i in ids)
    return np.frombuffer(raw, dtype="<u8").astype(np.uint64).reshape(ids.size, 2)


def world_keys(root_seed: int, scenario_ids: Sequence[int] | np.ndarray) -> np.ndarray:
    """The world's key of each scenario, (B, 2) uint64: a function of the root seed and the
    scenario index alone."""
    return _scenario_keys(root_seed, np.asarray(scenario_ids), WORLD_KEY)


def decision_keys(root_seed: int, scenario_ids: Sequence[int] | np.ndarray) -> np.ndarray:
    """The decision-makers' key of each scenario, (B, 2) uint64: it reveals neither the seed
    nor a world key."""
    return _scenario_keys(root_seed, np.asarray(scenario_ids), DECISION_KEY)


class StreamRNG:
    """Per-scenario independent draws for a batch, keyed by stream name and counter, from one
    128-bit key per scenario (``keys``, (B, 2) uint64)."""

    def __init__(self, keys: np.ndarray):
        keys = np.asarray(keys, dtype=np.uint64)
        if keys.ndim != 2 or keys.shape[1] != 2:
            raise ValueError(f"keys must have shape (B, 2), got {keys.shape}")
        self.keys = keys

    @property
    def batch_size(self) -> int:
        return int(self.keys.shape[0])

    def _stream_word(self, stream: str) -> np.uint64:
        return np.uint64(stream_word(stream))

    def bits(self, stream: str, counter: int, shape: tuple[int, ...] = ()) -> np.ndarray:
        """uint64 draws of shape (B, *shape): element i of the stream's draw at `counter` is
        word i % 2 of the block (stream word, counter << 32 | i // 2)."""
        n = int(np.prod(shape)) if shape else 1
        blocks = (n + 1) // 2
        c1 = (np.uint64(counter & 0xFFFFFFFF) << np.uint64(32)) \
            | np.arange(blocks, dtype=np.uint64)
        x0, x1 = threefry2x64(self.keys[:, :1], self.keys[:, 1:], self._stream_word(stream),
                              c1[None, :])
        out = np.empty((self.batch_size, 2 * blocks), dtype=np.uint64)
        out[:, 0::2], out[:, 1::2] = x0, x1
        return out[:, :n].reshape((self.batch_size, *shape))

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
    """The world's generator: per-scenario draws keyed by (root seed, scenario index). It keeps
    the scenario indices (a replay names them) but not the root seed.

    `resalted` gives the same generator with some streams drawing other numbers: the
    integrity check of `ata.testing` redraws what the decision-makers must not see.
    """

    def __init__(self, root_seed: int, scenario_ids: Sequence[int] | np.ndarray):
        self.scenario_ids = np.asarray(scenario_ids, dtype=np.int64)
        super().__init__(world_keys(root_seed, self.scenario_ids))
        self.salted: tuple[str, ...] = ()
        self.salt = 0
        self.drawn: set[str] | None = None
        """When a set, the name of every stream drawn is added to it (a normal draw's two
        streams under their common name): the integrity check learns what to redraw."""

    def _stream_word(self, stream: str) -> np.uint64:
        if self.drawn is not None:
            self.drawn.add(stream.split("#", 1)[0])
        word = stream_word(stream)
        if self.salted and stream.startswith(self.salted):
            word ^= stream_word(f"salt:{self.salt}")
        return np.uint64(word)

    def resalted(self, streams: Sequence[str], salt: int = 1) -> "BatchRNG":
        """A copy whose streams named with one of the prefixes `streams` draw other numbers
        (salt 0: the same ones); every other stream is unchanged."""
        out = self.subset(np.arange(self.batch_size))
        out.salted, out.salt = tuple(streams), int(salt) & 0xFFFFFFFFFFFFFFFF
        if out.salt == 0:
            out.salted = ()
        return out

    def subset(self, index: np.ndarray) -> "BatchRNG":
        """The generator of a sub-batch: the same numbers for the same scenarios."""
        sub = BatchRNG.__new__(BatchRNG)
        sub.scenario_ids = self.scenario_ids[index]
        sub.keys = self.keys[index]
        sub.salted, sub.salt, sub.drawn = self.salted, self.salt, self.drawn
        return sub
