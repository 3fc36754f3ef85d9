"""MODEL.md revision 3: individual hidden fatigue, and its spread 0 giving revision 2 bit for bit.

tests/data/rev2_golden.json holds per-scenario results of the code before individual fatigue
(revision 2, commit 73f148f), seed 0: ``random_a_high`` the random mission
(examples/missions/random_baseline.toml) at (a) high, 8 scenarios; ``greedy_a_high`` and
``greedy_b_high`` the greedy mission (ata/missions/greedy.toml) at (a) high, 8 scenarios, and at
(b) high, 4 scenarios.
"""

import json
from pathlib import Path

import numpy as np
import pytest

from ata.core.kernel import Simulation
from ata.experiment.runner import BASELINE_MISSION, load_session, run_mission
from ata.model import fatigue

ROOT = Path(__file__).resolve().parents[1]
GOLDEN = json.loads((Path(__file__).parent / "data" / "rev2_golden.json").read_text())
RANDOM = str(ROOT / "examples" / "missions" / "random_baseline.toml")
CASES = {"random_a_high": (RANDOM, ["mission.setting='a'", "mission.scenarios=8"]),
         "greedy_a_high": (str(BASELINE_MISSION), ["mission.setting='a'", "mission.scenarios=8"]),
         "greedy_b_high": (str(BASELINE_MISSION), ["mission.setting='b'", "mission.scenarios=4"])}


def run(case, *sets):
    path, own = CASES[case]
    result = run_mission(load_session(path, [*own, "mission.uncertainty='high'", *sets]))
    return {"total": result.total.tolist(), "reallocations": result.reallocations.tolist(),
            **{k: result.metrics[k].tolist() for k in ("expected_score", "fatigued_share")}}


def test_spread_zero_is_revision_2_bit_for_bit():
    assert run("random_a_high", "human.fatigue_spread=0") == GOLDEN["random_a_high"]


def test_the_default_spread_changes_results():
    got = run("random_a_high")
    # the same world but for the fatigue curves: scenarios 3 and 5 score otherwise
    assert got["total"] != GOLDEN["random_a_high"]["total"]
    assert got["total"] == [15.0, 280.0, 275.0, -25.0, -235.0, 40.0, -120.0, -140.0]


def simulation(*sets):
    s = load_session(str(BASELINE_MISSION), ["mission.scenarios=6", *sets])
    sim = Simulation(s.mission, s.registry, np.arange(6))
    sim.reset()
    return sim


@pytest.mark.parametrize("spread", [0.0, 1.0, 1.5])
def test_individual_curves_drawn_within_the_spread(spread):
    sim = simulation(f"human.fatigue_spread={spread}")
    h = sim.sim.group("humans")
    on_lo, on_hi = fatigue.onset_range(spread)
    sl_lo, sl_hi = fatigue.slope_range(spread)
    assert h.fatigue_onset.shape == h.fatigue_slope.shape == (6, sim.sim.sizes.humans)
    assert ((h.fatigue_onset >= on_lo) & (h.fatigue_onset <= on_hi)).all()
    assert ((h.fatigue_slope >= sl_lo) & (h.fatigue_slope <= sl_hi)).all()
    assert (h.fatigue_slope > 0).all()
    if spread == 0:
        assert (h.fatigue_onset == 1.0).all() and (h.fatigue_slope == 0.3).all()
    else:
        assert np.unique(h.fatigue_onset).size == h.fatigue_onset.size


def test_true_fatigue_follows_each_humans_curve_and_is_hidden():
    sim = simulation("human.t0_max_h=3.0")        # far enough into the shift to tire
    ctx = sim.begin_epoch()
    h = sim.sim.group("humans")
    truth = sim.last_truth["humans"]
    want = fatigue.individual(truth.col("working_time"), h.fatigue_onset, h.fatigue_slope,
                              0.4)
    assert np.array_equal(truth.col("fatigue"), want)
    assert (want < 1).any() and (want > 0.4).any()
    # neither I nor the observed S carries the onset or the slope
    for table in (ctx.inherent["humans"], ctx.observed["humans"]):
        assert not {"fatigue_onset", "fatigue_slope"} & set(table.names)
