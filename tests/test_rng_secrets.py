"""The world's generator keeps its secrets: the inversion attack that broke the SplitMix64
construction (from POI 0's position in I, the world key, and from it every hidden draw) succeeds
on that construction and finds nothing on Threefry; and no bit of a shown draw predicts a hidden
one."""

from __future__ import annotations

import math
import zlib

import numpy as np

from ata.core.kernel import Simulation
from ata.core.rng import BatchRNG
from ata.session import BASELINE_MISSION, load_session

SEED = 2024
MASK = (1 << 64) - 1
M1, M2, GOLDEN = 0xBF58476D1CE4E5B9, 0x94D049BB133111EB, 0x9E3779B97F4A7C15


# --- the construction the attack breaks: SplitMix64's finaliser, a bijection, three times ------

def _mix(x: np.ndarray) -> np.ndarray:
    with np.errstate(over="ignore"):
        x = (x ^ (x >> np.uint64(30))) * np.uint64(M1)
        x = (x ^ (x >> np.uint64(27))) * np.uint64(M2)
        return x ^ (x >> np.uint64(31))


def _unshift(x: np.ndarray, s: int) -> np.ndarray:
    """The inverse of x ^ (x >> s)."""
    y = x.copy()
    for _ in range(64 // s + 1):
        y = x ^ (y >> np.uint64(s))
    return y


def _unmix(x: np.ndarray) -> np.ndarray:
    with np.errstate(over="ignore"):
        x = _unshift(x, 31) * np.uint64(pow(M2, -1, 1 << 64))
        x = _unshift(x, 27) * np.uint64(pow(M1, -1, 1 << 64))
        return _unshift(x, 30)


def _stream_key(stream: str) -> np.uint64:
    with np.errstate(over="ignore"):
        return np.uint64(zlib.crc32(stream.encode())) * np.uint64(M1)


def _counter_word(counter: int) -> np.uint64:
    with np.errstate(over="ignore"):
        return np.uint64(counter & 0xFFFFFFFF) * np.uint64(M2) + np.uint64(GOLDEN)


class SplitMixWorld(BatchRNG):
    """The world's generator as the SplitMix64 construction drew it:
    out = mix(mix(mix(key ^ stream) ^ counter) + index * golden)."""

    def __init__(self, keys: np.ndarray):
        self.keys = np.asarray(keys, dtype=np.uint64)
        self.scenario_ids = np.arange(self.keys.size)
        self.salted, self.salt = (), 0

    def bits(self, stream, counter, shape=()):
        n = int(np.prod(shape)) if shape else 1
        with np.errstate(over="ignore"):
            base = _mix(_mix(self.keys ^ _stream_key(stream)) ^ _counter_word(counter))
            idx = np.arange(n, dtype=np.uint64) * np.uint64(GOLDEN)
            return _mix(base[:, None] + idx[None, :]).reshape((self.keys.size, *shape))


def invert(x: float, y: float) -> int | None:
    """The SplitMix world key that draws POI 0 of a scenario at (x, y) (as fractions of the
    area, the way I shows them), or None: x gives 53 bits of one output, the 2,048 missing low
    bits are tried, each candidate inverted three times and checked against y."""
    with np.errstate(over="ignore"):
        top = np.array([int(round(x * 2.0**53)) + d for d in range(-2, 3)], dtype=np.uint64)
        out = ((top[:, None] << np.uint64(11)) | np.arange(2048, dtype=np.uint64)).ravel()
        base = _unmix(out)                                      # index 0: out = mix(base)
        key = _unmix(_unmix(base) ^ _counter_word(0)) ^ _stream_key("tasks.pos")
        y_out = _mix(base + np.uint64(GOLDEN))                 # index 1 of the same draw
    u = (y_out >> np.uint64(11)).astype(np.float64) / 2.0**53
    hit = np.flatnonzero(np.abs(u - y) < 1e-12)
    return int(key[hit[0]]) if hit.size else None


def shown_and_hidden(world: BatchRNG | None, n: int) -> tuple[np.ndarray, np.ndarray]:
    """POI 0's position as I shows it and every POI's hidden classification outcome draw, for
    scenarios 0..n-1 of the greedy mission, its world drawn by `world` (None: the product's)."""
    session = load_session(str(BASELINE_MISSION), [f"mission.scenarios={n}",
                                                   f"mission.seed={SEED}"])
    sim = Simulation(session.mission, session.registry, np.arange(n))
    if world is not None:
        sim.sim.rng = world
    inherent = sim.reset()
    tasks = inherent["tasks"]
    xy = np.stack([tasks.col("x")[:, 0], tasks.col("y")[:, 0]], axis=1)
    return xy, sim.sim.groups["tasks"].outcome_u.copy()


def predict(key: int, P: int) -> np.ndarray:
    return SplitMixWorld(np.array([key], dtype=np.uint64)).uniform("tasks.outcome", 0, (P,))[0]


def test_the_inversion_attack_recovers_every_hidden_draw_of_the_splitmix_world():
    keys = np.random.default_rng(7).integers(0, 2**63, size=4, dtype=np.uint64) * np.uint64(2)
    xy, hidden = shown_and_hidden(SplitMixWorld(keys), 4)
    for s in range(4):
        key = invert(*xy[s])
        assert key == int(keys[s])
        np.testing.assert_array_equal(predict(key, hidden.shape[1]), hidden[s])


def test_the_inversion_attack_finds_nothing_in_the_threefry_world():
    xy, hidden = shown_and_hidden(None, 8)
    for s in range(8):
        key = invert(*xy[s])
        # no candidate key draws POI 0's y; were one to, it would not predict the outcomes
        if key is not None:
            assert not np.array_equal(predict(key, hidden.shape[1]), hidden[s])
        assert key is None


def test_no_bit_of_a_shown_draw_predicts_a_hidden_one():
    """Across 4,000 scenarios: each of the 53 bits of POI 0's x in I against POI 0's outcome
    draw, and the positions against the outcomes, all within sampling noise of no relation."""
    n = 4000
    rng = BatchRNG(SEED, np.arange(n))
    x = rng.uniform("tasks.pos", 0, (60, 2))[:, :, 0]
    outcome = rng.uniform("tasks.outcome", 0, (60,))
    bits = ((x[:, 0] * 2.0**53).astype(np.uint64)[:, None] >> np.arange(53, dtype=np.uint64)) & 1
    bound = 5 / math.sqrt(n)
    for b in range(53):
        r = np.corrcoef(bits[:, b].astype(float), outcome[:, 0])[0, 1]
        assert abs(r) < bound, f"bit {b}: r = {r:.3f}"
    r_all = np.corrcoef(x.ravel(), outcome.ravel())[0, 1]
    assert abs(r_all) < 5 / math.sqrt(x.size)
