"""ata.model.fatigue: the individual curve and the beliefs a planner projects with."""

import numpy as np

from ata.model import fatigue, tables


def test_population_curve_is_revision_2_bit_for_bit():
    h = np.random.default_rng(0).uniform(0.0, 5.0, 100_000)
    one = np.ones_like(h)
    got = fatigue.individual(h, one * fatigue.ONSET_H, one * fatigue.SLOPE_PER_H, 0.4)
    assert np.array_equal(got, tables.fatigue(h, 0.4))


def test_ranges_of_the_spread():
    assert fatigue.onset_range(1.0) == (0.5, 1.5)
    lo, hi = fatigue.slope_range(1.0)
    assert np.isclose(lo, 0.1) and np.isclose(hi, 0.5)
    assert fatigue.onset_range(0.0) == (1.0, 1.0) and fatigue.slope_range(0.0) == (0.3, 0.3)


def test_individual_curve_by_hand():
    # onset 0.5 h, slope 0.5 per hour: 1 before, 1 - 0.5 (T - 0.5) after, floor 0.4
    f = fatigue.individual(np.array([0.4, 0.5, 1.0, 1.5, 3.0]), 0.5, 0.5, 0.4)
    assert np.allclose(f, [1.0, 1.0, 0.75, 0.5, 0.4])


def test_exact_belief_is_the_curve():
    on, sl = np.array([[0.5, 1.5]]), np.array([[0.5, 0.1]])
    b = fatigue.FatigueBelief.exact(on, sl, 0.4)
    T = np.array([[2.0, 2.0]])
    assert np.array_equal(b.at(T), fatigue.individual(T, on, sl, 0.4))
    rows = (np.array([0, 0]), np.array([1, 0]))
    assert np.allclose(b.at(np.array([2.5, 1.0]), rows=rows), [0.9, 0.75])


def test_shifted_belief_starts_at_the_value_now_and_follows_the_population_line():
    now, hours = np.array([[0.9, 0.2]]), np.array([[1.5, 0.5]])
    b = fatigue.FatigueBelief.shifted(now, hours, 0.4)
    assert np.allclose(b.at(hours), [[0.9, 0.4]])            # 0.2 is clipped to the floor
    # half an hour more: the population line falls 0.15 past its onset of 1 h
    assert np.allclose(b.at(hours + 0.5), [[0.75, 0.4]])


def test_mixture_belief_is_the_weighted_mean():
    rec = {"fatigue_onset": np.array([[[0.5, 1.5]]]), "fatigue_slope": np.array([[[0.5, 0.1]]]),
           "fatigue_weight": np.array([[[0.25, 0.75]]])}
    b = fatigue.belief_from(rec, np.array([[0.0]]), np.array([[0.0]]), 0.4)
    assert b.curves == 2
    assert np.allclose(b.at(np.array([[1.0]])), 0.25 * 0.75 + 0.75 * 1.0)
    sub = b.take(np.array([0, 0]))
    assert sub.at(np.array([[1.0], [1.0]])).shape == (2, 1)
