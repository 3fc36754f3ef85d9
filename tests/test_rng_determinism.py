"""The counter-based RNG and the determinism of whole runs: a scenario's numbers depend on
(seed, scenario index) alone, whatever the batch, batch size or number of workers."""

from __future__ import annotations

import math

import numpy as np
import pytest

from ata.session import BASELINE_MISSION
from ata.core.rng import BatchRNG, stream_word, threefry2x64, world_keys
from ata.session import load_session
from ata.experiment.runner import run_mission

SEED = 12345


def draws(rng: BatchRNG) -> dict[str, np.ndarray]:
    return {"bits": rng.bits("s.bits", 3, (4, 5)), "uniform": rng.uniform("s.u", 0, (7,)),
            "normal": rng.normal("s.n", 2, (3, 2)), "integers": rng.integers("s.i", 1, 9, (6,)),
            "scalar": rng.uniform("s.scalar", 0)}


# --- BatchRNG ------------------------------------------------------------------------------------

def test_draws_do_not_depend_on_the_rest_of_the_batch():
    ids = np.arange(20)
    full = draws(BatchRNG(SEED, ids))
    assert full["bits"].shape == (20, 4, 5) and full["scalar"].shape == (20,)
    subset = np.array([13, 2, 7])
    sub = draws(BatchRNG(SEED, ids[subset]))
    perm = np.random.default_rng(0).permutation(20)
    permuted = draws(BatchRNG(SEED, ids[perm]))
    alone = draws(BatchRNG(SEED, [7]))
    sub_method = draws(BatchRNG(SEED, ids).subset(subset))
    for name, arr in full.items():
        np.testing.assert_array_equal(sub[name], arr[subset], err_msg=name)
        np.testing.assert_array_equal(permuted[name], arr[perm], err_msg=name)
        np.testing.assert_array_equal(alone[name][0], arr[7], err_msg=name)
        np.testing.assert_array_equal(sub_method[name], arr[subset], err_msg=name)
    # a scenario beyond the first batch: index 1000 alone equals index 1000 in a big batch
    big = BatchRNG(SEED, np.arange(990, 1010)).uniform("s.u", 0, (7,))
    np.testing.assert_array_equal(BatchRNG(SEED, [1000]).uniform("s.u", 0, (7,))[0], big[10])


def test_draws_differ_across_scenarios_streams_counters_and_seeds():
    rng = BatchRNG(SEED, np.arange(50))
    u = rng.uniform("a", 0, (10,))
    assert len({tuple(row) for row in u}) == 50                 # every scenario its own numbers
    assert not np.array_equal(u, rng.uniform("b", 0, (10,)))    # stream
    assert not np.array_equal(u, rng.uniform("a", 1, (10,)))    # counter
    assert not np.array_equal(u, BatchRNG(SEED + 1, np.arange(50)).uniform("a", 0, (10,)))
    # same inputs, same numbers (pure function)
    np.testing.assert_array_equal(u, BatchRNG(SEED, np.arange(50)).uniform("a", 0, (10,)))
    # a shape's first elements do not depend on its size
    np.testing.assert_array_equal(rng.uniform("a", 0, (3,)), u[:, :3])
    assert stream_word("fatigue_noise") == stream_word("fatigue_noise") != stream_word("latency.tasks")
    keys = world_keys(SEED, np.arange(1000))
    assert keys.shape == (1000, 2) and len({tuple(k) for k in keys.tolist()}) == 1000


# Random123's known-answer vectors for Threefry-2x64-20 (tests/kat_vectors):
# counter (c0, c1), key (k0, k1) -> (out0, out1)
KAT = [((0, 0), (0, 0), (0xC2B6E3A8C2C69865, 0x6F81ED42F350084D)),
       ((2**64 - 1, 2**64 - 1), (2**64 - 1, 2**64 - 1), (0xE02CB7C4D95D277A, 0xD06633D0893B8B68)),
       ((0x243F6A8885A308D3, 0x13198A2E03707344), (0xA4093822299F31D0, 0x082EFA98EC4E6C89),
        (0x263C7D30BB0F0AF1, 0x56BE8361D3311526))]


@pytest.mark.parametrize("counter,key,expected", KAT)
def test_threefry_matches_random123s_known_answers(counter, key, expected):
    u = lambda x: np.array([x], dtype=np.uint64)   # noqa: E731
    x0, x1 = threefry2x64(u(key[0]), u(key[1]), u(counter[0]), u(counter[1]))
    assert (int(x0[0]), int(x1[0])) == expected


def test_resalted_streams_draw_again_and_the_others_do_not():
    world = BatchRNG(SEED, np.arange(8))
    again = world.resalted(("tasks.outcome", "robot_failure."), 1)
    assert not np.array_equal(again.uniform("tasks.outcome", 0, (5,)),
                              world.uniform("tasks.outcome", 0, (5,)))
    assert not np.array_equal(again.normal("robot_failure.time", 0, (3,)),
                              world.normal("robot_failure.time", 0, (3,)))
    for stream in ("tasks.kind", "robot_failure", "latency.tasks"):   # prefixes, not names
        np.testing.assert_array_equal(again.uniform(stream, 2, (5,)), world.uniform(stream, 2, (5,)))
    np.testing.assert_array_equal(again.subset(np.array([3])).uniform("tasks.outcome", 0, (5,)),
                                  again.uniform("tasks.outcome", 0, (5,))[[3]])
    same = world.resalted(("tasks.outcome",), 0)
    np.testing.assert_array_equal(same.uniform("tasks.outcome", 0, (5,)),
                                  world.uniform("tasks.outcome", 0, (5,)))
    assert world.salted == ()                                          # the original unchanged


def test_uniform_range_and_moments():
    u = BatchRNG(SEED, np.arange(1000)).uniform("check.uniform", 0, (1000,)).ravel()
    n = u.size
    assert u.min() >= 0.0 and u.max() < 1.0
    assert abs(u.mean() - 0.5) < 5 * math.sqrt(1 / 12 / n)
    assert abs(u.var() - 1 / 12) < 5 * math.sqrt(1 / 180 / n)   # var of (u - 1/2)^2 is 1/180
    counts, _ = np.histogram(u, bins=20, range=(0.0, 1.0))
    chi2 = ((counts - n / 20) ** 2 / (n / 20)).sum()
    assert chi2 < 60.0                                          # chi2(19): p ~ 4e-6
    # independence of neighbouring elements and scenarios
    grid = u.reshape(1000, 1000)
    assert abs(np.corrcoef(grid[:, 0], grid[:, 1])[0, 1]) < 5 / math.sqrt(1000)
    assert abs(np.corrcoef(grid[0], grid[1])[0, 1]) < 5 / math.sqrt(1000)


def test_uniform_extremes_stay_in_unit_interval(monkeypatch):
    rng = BatchRNG(SEED, [0, 1])
    extremes = np.array([[0], [np.iinfo(np.uint64).max]], dtype=np.uint64)
    monkeypatch.setattr(rng, "bits", lambda stream, counter, shape=(): extremes)
    u = rng.uniform("x", 0, (1,))
    assert u[0, 0] == 0.0
    assert u[1, 0] < 1.0 and u[1, 0] == 1.0 - 2.0 ** -53
    # integers stay below `high` even at the top of the range
    assert rng.integers("x", 0, 3, (1,)).tolist() == [[0], [2]]
    # and the normal transform stays finite at both ends
    assert np.isfinite(rng.normal("x", 0, (1,))).all()


def test_normal_moments():
    z = BatchRNG(SEED, np.arange(1000)).normal("check.normal", 0, (1000,)).ravel()
    n = z.size
    assert np.isfinite(z).all()
    assert abs(z.mean()) < 5 / math.sqrt(n)
    assert abs(z.var() - 1.0) < 5 * math.sqrt(2.0 / n)
    assert abs((np.abs(z) < 1.0).mean() - 0.682689) < 5 * math.sqrt(0.682689 * 0.317311 / n)
    assert abs((z ** 4).mean() - 3.0) < 5 * math.sqrt(96.0 / n)   # kurtosis; var of z^4 is 96


def test_integers_uniform():
    k = BatchRNG(SEED, np.arange(500)).integers("check.int", 0, 3, (600,)).ravel()
    assert k.min() == 0 and k.max() == 2
    share = np.bincount(k, minlength=3) / k.size
    assert np.all(np.abs(share - 1 / 3) < 5 * math.sqrt(2 / 9 / k.size))
    # per-element high
    hi = np.array([1, 2, 5])
    v = BatchRNG(SEED, np.arange(200)).integers("check.int2", 0, hi, (3,))
    assert (v >= 0).all() and (v < hi).all() and (v[:, 0] == 0).all()


# --- whole runs ----------------------------------------------------------------------------------

N = 14
BASE = [f"mission.scenarios={N}", "mission.uncertainty='high'"]


def run(*extra: str, workers: int | None = None):
    return run_mission(load_session(str(BASELINE_MISSION), BASE + list(extra)), workers=workers)


@pytest.fixture(scope="module")
def reference():
    return run("mission.batch_size=7")


def assert_same(a, b):
    np.testing.assert_array_equal(a.scenario, b.scenario)
    np.testing.assert_array_equal(a.total, b.total)
    np.testing.assert_array_equal(a.upper_bound, b.upper_bound)
    np.testing.assert_array_equal(a.reallocations, b.reallocations)
    assert set(a.metrics) == set(b.metrics)
    for k in a.metrics:
        np.testing.assert_array_equal(a.metrics[k], b.metrics[k], err_msg=k)


def test_reference_run_is_not_degenerate(reference):
    assert reference.scenario.tolist() == list(range(N))
    assert len(set(reference.total.tolist())) > N // 2     # scenarios differ
    assert reference.reallocations.sum() > 0                 # reallocation paths exercised
    assert reference.metrics["robot_failures"].sum() > 0    # high uncertainty shows


def test_same_seed_same_results(reference):
    assert_same(reference, run("mission.batch_size=7"))


def test_different_seed_different_results(reference):
    other = run("mission.batch_size=7", "mission.seed=1")
    assert not np.array_equal(other.total, reference.total)
    assert (other.upper_bound != reference.upper_bound).sum() >= N - 1


def test_batch_size_does_not_matter(reference):
    assert_same(reference, run("mission.batch_size=50"))
    assert_same(reference, run("mission.batch_size=3"))


def test_workers_do_not_matter(reference):
    assert_same(reference, run("mission.batch_size=7", "mission.workers=2"))
    assert_same(reference, run("mission.batch_size=5", workers=2))


def test_first_scenario_selects_the_same_scenarios(reference):
    part = run("mission.batch_size=4", "mission.first_scenario=9", "mission.scenarios=5")
    assert part.scenario.tolist() == list(range(9, 14))
    np.testing.assert_array_equal(part.total, reference.total[9:])
    np.testing.assert_array_equal(part.upper_bound, reference.upper_bound[9:])
