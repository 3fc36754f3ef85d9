"""The paper's hierarchical rewards on a hand-built episode record."""

import numpy as np
import pytest

from ata.plugins.ata_hrl.rewards import delta_performance, hierarchical_rewards
from ata.core.state import EpisodeRecord


def record():
    # one scenario, 4 epochs, 2 POIs; reallocations at epochs 1 and 3
    rec = EpisodeRecord.empty(1, 4, 2)
    rec.r_perf[0] = [10.0, 5.0, 20.0, -5.0]
    rec.reallocated[0] = [False, True, False, True]
    ita = [[0, -1, -1], [1, -1, 0]]
    rec.allocations[0, 0] = ita
    rec.allocations[0, 1] = [[1, -1, -1], [1, -1, 0]]     # POI 0's robot changed: 1 change
    rec.allocations[0, 2] = [[1, -1, -1], [1, -1, 0]]
    rec.allocations[0, 3] = [[1, 0, 1], [1, -1, 0]]       # POI 0's navigator and classifier
    return rec


def test_delta_performance_between_reallocations():
    # epoch 1: r1 - r0 = 5 - 10 = -5; epoch 3: r3 - r1 = -5 - 5 = -10
    rec = record()
    assert delta_performance(rec.r_perf, rec.reallocated)[0] == pytest.approx(-15.0)


def test_hierarchical_rewards_by_hand():
    R = hierarchical_rewards(record())
    total = 30.0
    # ||a1 - a_ITA||_F = sqrt(2 * 1); ||a3 - a_ITA||_F = sqrt(2 * 3)
    assert R["total"][0] == total
    assert R["R_ITA"][0] == pytest.approx(total - 0.2 * (np.sqrt(2) + np.sqrt(6)))
    # two reallocations over T = 4 epochs
    assert R["R_C"][0] == pytest.approx(total - 15.0 - 0.4 * 2 / 4)
    # ||a1 - a0|| = sqrt(2); ||a3 - a2|| = sqrt(4)
    assert R["R_TR"][0] == pytest.approx(total - 15.0 - 0.2 * (np.sqrt(2) + 2.0) / 4)


def test_no_reallocation_means_plain_performance():
    rec = record()
    rec.reallocated[:] = False
    R = hierarchical_rewards(rec)
    assert R["R_ITA"][0] == R["R_C"][0] == R["R_TR"][0] == 30.0


def test_expected_points_replace_the_drawn_ones_when_asked():
    rec = record()
    rec.r_expected[0] = [4.0, 2.0, 6.0, 1.0]
    R = hierarchical_rewards(rec, expected=True)
    # the same formulas on r_expected: total 13; Delta r: (2 - 4) + (1 - 2) = -3
    assert R["total"][0] == 13.0
    assert R["R_C"][0] == pytest.approx(13.0 - 3.0 - 0.4 * 2 / 4)
    assert hierarchical_rewards(rec)["total"][0] == 30.0
