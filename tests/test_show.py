"""`ata show` and its recorder: recording is opt-in and changes nothing, the recorded trace agrees
with the results, a replayed scenario scores what it scored in its run, and the command writes its
pictures or gives one message for bad input."""

from __future__ import annotations

import csv

import numpy as np
import pytest

from _support import assert_user_error, flat
from ata.session import BASELINE_MISSION, BUILTIN_MISSION, load_session
from ata.core.kernel import Simulation
from ata.experiment.units import run_batch
from ata.model import tables
from ata.viz.record import RIGHT, WRONG, Episode, Recorder, replay

SMALL = ["mission.setting='custom'", "mission.humans=2", "mission.robots=3", "mission.tasks=10",
         "mission.uncertainty='high'", "mission.scenarios=4", "mission.batch_size=4"]
"""A small team under high uncertainty: scenarios 0-3 hold robot failures (one cutting a leg
short), changed attributes, navigated legs with waits, and reallocations with re-briefs."""

SMALL_TOML = """\
[mission]
name = "small"
setting = "custom"
humans = 2
robots = 3
tasks = 10
uncertainty = "high"
scenarios = 4
batch_size = 2
"""

STEMS = ("show_map", "show_timeline", "show_humans")


@pytest.fixture(scope="module")
def small():
    # spread 0: the scenarios whose events SMALL's note lists (a leg cut short among them) are
    # those of the humans on the population's fatigue line
    return load_session(str(BASELINE_MISSION), SMALL + ["human.fatigue_spread=0"])


@pytest.fixture(scope="module")
def recorded(small):
    """The four scenarios run together, recorded, and each one's episode."""
    simulation = Simulation(small.mission, small.registry, [0, 1, 2, 3], trace=True)
    recorder = Recorder.attach(simulation)
    record = simulation.run()
    return record, [Episode.build(simulation, recorder, b, b) for b in range(4)]


def test_recording_off_records_nothing_and_never_runs(small, monkeypatch):
    """Off (as in `ata run`), no recorder is built (so none of its hooks can run), the trace
    stays None, and nothing is registered beyond the mission's components."""
    def boom(*args, **kwargs):
        raise AssertionError("a recorder was built with recording off")
    monkeypatch.setattr(Recorder, "__init__", boom)
    simulation = Simulation(small.mission, small.registry, [0, 1, 2, 3])
    simulation.run()
    assert simulation.sim.trace is None
    assert simulation.pm.get_plugin("recorder") is None
    assert not any(isinstance(p, Recorder) for p in simulation.pm.get_plugins())
    run_batch(small.mission, small.registry, np.arange(4))


def test_recording_leaves_results_bit_identical(small, recorded):
    record, _ = recorded
    plain = Simulation(small.mission, small.registry, [0, 1, 2, 3]).run()
    np.testing.assert_array_equal(record.r_perf, plain.r_perf)
    np.testing.assert_array_equal(record.r_expected, plain.r_expected)
    np.testing.assert_array_equal(record.allocations, plain.allocations)
    np.testing.assert_array_equal(record.reallocated, plain.reallocated)
    np.testing.assert_array_equal(record.task_gain, plain.task_gain)
    np.testing.assert_array_equal(record.upper_bound, plain.upper_bound)
    assert record.metrics.keys() == plain.metrics.keys()
    for key in plain.metrics:
        np.testing.assert_array_equal(record.metrics[key], plain.metrics[key])


def test_the_scenarios_exercise_every_event(recorded):
    _, episodes = recorded
    legs = [leg for ep in episodes for leg in ep.legs]
    assert any(np.isfinite(ep.fail_time).any() for ep in episodes)
    assert any(not leg.captured for leg in legs)
    assert any(leg.navigator >= 0 for leg in legs) and any(leg.navigator < 0 for leg in legs)
    assert any(ep.changed.any() for ep in episodes)
    assert any(n for ep in episodes for _, n in ep.reallocations)
    assert any(w.kind == "rebrief" for ep in episodes for w in ep.work)
    assert any(w.end > w.start for ep in episodes for w in ep.waits)


def test_classifications_in_the_trace_are_the_results(recorded):
    record, episodes = recorded
    for b, ep in enumerate(episodes):
        assert ep.score == record.total[b] == ep.gain.sum()
        np.testing.assert_array_equal(ep.r_perf, record.r_perf[b])
        classified = np.isfinite(ep.classified_at)
        assert classified.mean() == record.metrics["classified_share"][b]
        started = [w for w in ep.work if w.kind == "classify"]
        assert len(started) == record.metrics["human_classifications"][b]
        by_humans = {w.poi: w for w in started if w.end < ep.horizon_s}
        for poi, w in by_humans.items():
            assert classified[poi] and ep.classified_at[poi] == w.end
            assert ep.classifier[poi] == w.human
            assert w.end - w.begin == pytest.approx(
                tables.T_BAR[ep.quality[poi], ep.true_diff[poi]], rel=1e-12)
        onboard = classified & (ep.classifier < 0)
        assert set(np.flatnonzero(classified & ~onboard)) == set(by_humans)
        np.testing.assert_array_equal(ep.classified_at[onboard], ep.capture_time[onboard])
        assert np.all((ep.gain != 0) == classified)
        assert set(ep.outcome[classified]) <= {RIGHT, WRONG}
        captured = {leg.poi for leg in ep.legs if leg.captured}
        assert captured == set(np.flatnonzero(np.isfinite(ep.capture_time)))


def test_robot_routes_start_at_the_base_and_chain(recorded):
    _, episodes = recorded
    for ep in episodes:
        for robot in range(ep.robot_type.size):
            legs = [leg for leg in ep.legs if leg.robot == robot]
            if not legs:
                continue
            assert legs[0].origin == ep.base
            for before, after in zip(legs, legs[1:]):
                assert after.origin == before.dest
                assert after.start >= before.end - 1e-9
            assert all(0.0 <= leg.start < leg.end <= ep.horizon_s for leg in legs)
            assert all(leg.captured for leg in legs[:-1])
            cut = [leg for leg in legs if not leg.captured]
            assert all(leg.end == ep.fail_time[robot] for leg in cut)
            for leg in legs:
                if leg.captured:
                    assert leg.dest == tuple(ep.poi_pos[leg.poi])
                    assert leg.end == ep.capture_time[leg.poi]


def test_navigation_and_waits_agree(recorded):
    _, episodes = recorded
    for ep in episodes:
        nav = {(w.robot, w.end): w for w in ep.work if w.kind == "nav"}
        for leg in ep.legs:
            if leg.navigator >= 0 and leg.captured:
                w = nav[(leg.robot, leg.end)]
                assert w.human == leg.navigator and w.begin == pytest.approx(leg.start, abs=1e-9)
        starts = {(leg.robot, leg.start) for leg in ep.legs if leg.navigator >= 0}
        for wait in ep.waits:
            assert 0.0 <= wait.start <= wait.end <= ep.horizon_s
            if wait.how == "taken":
                assert (wait.robot, wait.end) in starts
            if wait.how == "failed":
                assert wait.end == ep.fail_time[wait.robot]
        for w in ep.work:
            assert w.start <= w.begin < w.end


def test_human_states_in_range(recorded, small):
    _, episodes = recorded
    floor = small.mission.component_settings["human"].fatigue_floor
    for ep in episodes:
        assert ep.times[0] == 0.0 and ep.times[-1] == ep.horizon_s
        assert np.all((ep.fatigue >= floor) & (ep.fatigue <= 1.0))
        assert np.all((ep.sa >= 0.0) & (ep.sa <= 1.0))
        assert np.all((ep.utilisation >= 0.0) & (ep.utilisation <= 1.0))
        assert np.all(np.diff(ep.working_h, axis=1) >= 0.0)
        assert ep.fatigue_seen.shape == (ep.skill.size, ep.epoch_times.size)


def test_true_state_is_what_policies_see_without_noise():
    """With no uncertainty the observed F_f is the true one; the per-tick curves sampled at the
    epochs give exactly what the human model put in S."""
    s = load_session(str(BASELINE_MISSION), SMALL[:-3] + [
        "mission.uncertainty='none'"])
    ep = replay(s.mission, s.registry, 1)
    per_epoch = np.searchsorted(ep.times, ep.epoch_times)
    np.testing.assert_array_equal(ep.fatigue[:, per_epoch], ep.fatigue_seen)


@pytest.mark.parametrize("mission", ["greedy", "default"])
def test_a_replay_is_the_scenario_of_a_batch(mission):
    """A scenario replayed alone scores what it scored in a batch, for greedy and ATA-HRL."""
    path = BASELINE_MISSION if mission == "greedy" else BUILTIN_MISSION
    s = load_session(str(path))
    batch = run_batch(s.mission, s.registry, np.arange(2))
    ep = replay(s.mission, s.registry, 1)
    assert ep.score == batch["total"][1]
    assert ep.upper_bound == batch["upper_bound"][1]
    assert len(ep.reallocations) == batch["reallocations"][1]


# --- the command ----------------------------------------------------------------------------------

@pytest.fixture
def run_dir(cli, tmp_path):
    path = tmp_path / "small.toml"
    path.write_text(SMALL_TOML, encoding="utf-8")
    out = tmp_path / "run"
    result = cli("run", path, "--out", out, "--quiet")
    assert result.exit_code == 0, result.output
    return out


def test_show_writes_the_pictures_and_matches_the_run(cli, run_dir, tmp_path):
    pytest.importorskip("matplotlib")
    with open(run_dir / "results.csv", newline="", encoding="utf-8") as f:
        scores = {int(r["scenario"]): float(r["score"]) for r in csv.DictReader(f)}
    s = load_session(str(run_dir / "mission.resolved.toml"))
    for scenario, score in scores.items():       # every row, from batches of two
        assert replay(s.mission, s.registry, scenario).score == score
    out = tmp_path / "pictures"
    result = cli("show", run_dir, "--scenario", 3, "--out", out)
    assert result.exit_code == 0, result.output
    text = flat(result.output)
    assert f"small: scenario 3 (seed 0): score {scores[3]:.1f}" in text
    assert f"the same score as the run: {run_dir / 'results.csv'}" in text
    for stem in STEMS:
        png, svg = out / f"{stem}.png", out / f"{stem}.svg"
        assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
        assert svg.read_text(encoding="utf-8").rstrip().endswith("</svg>")
        assert f"{png}" in text and f"{svg}" in text


def test_show_warns_when_the_run_scored_otherwise(cli, run_dir, tmp_path):
    pytest.importorskip("matplotlib")
    path = run_dir / "results.csv"
    with open(path, newline="", encoding="utf-8") as f:
        rows = list(csv.DictReader(f))
    rows[1]["score"] = str(float(rows[1]["score"]) + 5.0)
    with open(path, "w", newline="", encoding="utf-8") as f:
        writer = csv.DictWriter(f, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    result = cli("show", run_dir, "-n", 1, "-o", tmp_path / "pictures")
    assert result.exit_code == 0, result.output
    assert "warning: the replay scored" in flat(result.output)
    assert "the same score as the run" not in result.output


def test_show_defaults_to_a_folder_in_the_run(cli, run_dir):
    pytest.importorskip("matplotlib")
    result = cli("show", run_dir, "-n", 0)
    assert result.exit_code == 0, result.output
    assert sorted(p.name for p in (run_dir / "show-0").iterdir()) == sorted(
        f"{stem}.{ext}" for stem in STEMS for ext in ("png", "svg"))


@pytest.mark.parametrize("scenario", [4, -1, 1000])
def test_bad_scenario_number(cli, run_dir, tmp_path, scenario):
    out = tmp_path / "pictures"
    result = cli("show", run_dir, "--scenario", scenario, "--out", out)
    assert_user_error(result, f"error: {run_dir / 'mission.resolved.toml'}: --scenario: "
                             f"{scenario} is not one of the mission's scenarios: ids 0 to 3")
    assert not out.exists()


def test_folder_without_a_mission(cli, tmp_path):
    result = cli("show", tmp_path, "--scenario", 0)
    assert_user_error(result, f"error: {tmp_path}: no mission.resolved.toml here: not a run "
                             "folder")


def test_mission_file_is_replayed_too(cli, tmp_path):
    pytest.importorskip("matplotlib")
    path = tmp_path / "small.toml"
    path.write_text(SMALL_TOML, encoding="utf-8")
    out = tmp_path / "pictures"
    result = cli("show", path, "-n", 2, "-o", out)
    assert result.exit_code == 0, result.output
    assert "the same score as the run" not in result.output
    assert (out / "show_map.png").is_file()


def test_show_takes_a_built_in_mission_and_writes_under_the_runs_folder(cli, tmp_path,
                                                                        monkeypatch):
    pytest.importorskip("matplotlib")
    monkeypatch.setenv("ATA_RUNS", str(tmp_path / "runs"))
    result = cli("show", "builtin:greedy", "-n", "0")
    assert result.exit_code == 0, result.output
    assert "greedy: scenario 0 (seed 0): score" in flat(result.output)
    assert sorted(p.name for p in (tmp_path / "runs" / "show-greedy-0").glob("*.png")) == [
        "show_humans.png", "show_map.png", "show_timeline.png"]
