"""Individual hidden fatigue, and its spread 0 putting every human on the population line.

tests/data/rev2_golden.json holds per-scenario results of the population-line model (every
human's fatigue a function of the working hours, the policies computing it from them), seed 0:
``random_a_high`` the random mission
(examples/missions/random_baseline.toml) at (a) high, 8 scenarios; ``greedy_a_high`` and
``greedy_b_high`` the greedy mission (ata/missions/greedy.toml) at (a) high, 8 scenarios, and at
(b) high, 4 scenarios.
"""

import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest

from ata.core.kernel import Simulation
from ata.session import BASELINE_MISSION, load_session
from ata.experiment.runner import run_mission
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
    # the same world but for the fatigue curves: who is fatigued when, and so what each
    # classification expected, differ (the drawn totals of these 8 happen to agree)
    share = np.array(got["fatigued_share"]) - GOLDEN["random_a_high"]["fatigued_share"]
    expected = np.array(got["expected_score"]) - GOLDEN["random_a_high"]["expected_score"]
    assert np.count_nonzero(share) == 6 and np.count_nonzero(expected) == 8
    assert np.round(share[3], 3) == -0.263 and np.round(expected[5], 2) == -7.40


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


@pytest.mark.parametrize("case", ["greedy_a_high", "greedy_b_high"])
def test_greedy_with_the_oracles_fatigue_at_spread_0_is_the_population_line_model(case):
    # at spread 0 the exact belief of one curve is the population line: greedy handed the true
    # fatigue plans as a greedy that computes it from the working hours
    got = run(case, "human.fatigue_spread=0", "components.reconstructors=['identity', 'oracle']",
              "oracle.channels=['fatigue']")
    assert got == GOLDEN[case]


def test_greedy_reads_the_fatigue_it_is_given():
    # with identity it reads the noisy observation, moved along the population line: not
    # the population-line model's plans even at spread 0
    assert run("greedy_a_high", "human.fatigue_spread=0")["total"] != GOLDEN["greedy_a_high"]["total"]


def milp_inputs(*reconstructors):
    from ata.plugins.policies import milp as M

    s = load_session(str(BASELINE_MISSION), [
        "mission.scenarios=2", "mission.uncertainty='high'", "human.t0_max_h=3.0",
        "components.initial='milp'", "components.condition='never'",
        "components.reallocation='keep'", f"components.reconstructors={list(reconstructors)!r}"])
    sim = Simulation(s.mission, s.registry, np.arange(2))
    sim.reset()
    ctx = sim.begin_epoch()
    return sim, M.scenario_data(ctx, s.mission, s.mission.component_settings["milp"])


def test_milp_takes_fatigue_from_the_belief_and_the_noise_margin_only_off_the_raw_one():
    from ata.plugins.policies import milp as M

    sim, raw = milp_inputs("identity")
    _, exact = milp_inputs("identity", "oracle")
    truth, observed = sim.last_truth["humans"], sim.last_context.observed["humans"]
    h = sim.sim.group("humans")
    cap_h = 0.65 * sim.sim.clock.horizon_s / 3600.0     # a shift at the default cap
    for b in range(2):
        # identity: the noisy F_f now; the population line's change over the shift
        noisy = np.clip(observed.col("fatigue")[b], 0.4, 1.0)
        hours = observed.col("working_time")[b]
        assert np.allclose(raw[b].fatigue_now, noisy)
        line = fatigue.individual(hours + cap_h, 1.0, 0.3, 0.4) - \
            fatigue.individual(hours, 1.0, 0.3, 0.4)
        assert np.allclose(raw[b].fatigue_worn, np.clip(noisy + line, 0.4, 1.0))
        assert raw[b].fatigue_noisy
        # the oracle: each human's true curve, no noise margin
        assert np.array_equal(exact[b].fatigue_now, truth.col("fatigue")[b])
        assert np.array_equal(exact[b].fatigue_worn, fatigue.individual(
            hours + cap_h, h.fatigue_onset[b], h.fatigue_slope[b], 0.4))
        assert not exact[b].fatigue_noisy
    # without the noise margin fewer options fail the redundancy requirement
    settings = M.MilpSettings()
    sizes = [M.build_model(dataclasses.replace(raw[0], fatigue_noisy=noisy), settings).task.size
             for noisy in (True, False)]
    assert sizes == [1592, 2216]
