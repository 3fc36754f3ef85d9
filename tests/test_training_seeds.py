"""Training as researchers do (docs/training.md): the smoke recipe for several seeds, their
curves across seeds, TensorBoard scalars equal to log.csv, and the trained weights evaluated in
one step (`ata run TRAIN_DIR`, a suite naming the training folder as a method)."""

import csv
import json
import math

import pytest

from ata.runtime.inputs import file_digest

TINY = ["--set", "ata_hrl.ita_steps=2", "--set", "ata_hrl.batch_size=1", "--set",
        "ata_hrl.samples=2", "--set", "ata_hrl.eval_every=1", "--set",
        "ata_hrl.eval_scenarios=2", "--set", "ata_hrl.checkpoint_every=1"]


@pytest.fixture(scope="module")
def seeds_dir(tmp_path_factory):
    """The smoke recipe of the ITA alone for seeds 0 and 1, tiny, on the serial executor."""
    from typer.testing import CliRunner
    from ata.cli import app
    out = tmp_path_factory.mktemp("train") / "seeds"
    result = CliRunner(env={"COLUMNS": "200"}).invoke(app, [
        "train", "--plugins", "ita", "--preset", "smoke", "--seeds", "2", "-e", "serial",
        "-o", str(out), *TINY])
    assert result.exit_code == 0, result.output
    assert f"ata report {out}" in result.output and f"ata eval {out}" in result.output
    return out


def test_seeds_train_report_and_eval_against_greedy(seeds_dir, cli, tmp_path):
    import torch
    from ata.results.rows import paired_values, read_results
    assert json.loads((seeds_dir / "seeds.json").read_text())["seeds"] == [0, 1]
    for s in (0, 1):
        folder = seeds_dir / f"seed-{s}"
        mission = (folder / "mission.resolved.toml").read_text()
        assert "seed = %d" % s in mission and str(folder / "best.pt") in mission
        assert "builtin:ata_hrl_a" not in mission    # names the trained weights, not the shipped
        data = torch.load(folder / "checkpoint.pt", weights_only=True)
        assert data["counters"]["ita"] == 2 and "optimizer" in data and "rng" in data
    # the two seeds trained apart: different weights
    a, b = (torch.load(seeds_dir / f"seed-{s}" / "best.pt", weights_only=True)["model"]
            for s in (0, 1))
    assert any(not torch.equal(a[k], b[k]) for k in a if k.startswith("ita."))

    result = cli("report", seeds_dir)
    assert result.exit_code == 0, result.output
    report = (seeds_dir / "curves.md").read_text()
    assert "| 0 |" in report and "| 1 |" in report and "IQM" in report
    assert (seeds_dir / "fig_curves_seeds.png").stat().st_size > 0

    suite = tmp_path / "suite.toml"
    suite.write_text(f'[suite]\nname = "mine"\nsettings = ["a"]\nuncertainty = ["medium"]\n'
                     f'[[method]]\nname = "mine"\nmission = "{seeds_dir}"\n'
                     '[[method]]\nname = "greedy"\nmission = "builtin:greedy"\n')
    out = tmp_path / "eval"
    result = cli("eval", suite, "-n", "2", "-e", "serial", "-o", out, "-q")
    assert result.exit_code == 0, result.output
    res = read_results(out)
    assert sorted(res.methods) == ["greedy", "mine seed 0", "mine seed 1"]
    ref = res.select("greedy", "a", "medium")
    for s in (0, 1):
        mine, greedy = paired_values(res, ref, res.select(f"mine seed {s}", "a", "medium"))
        assert mine.size == greedy.size == 2          # paired on the same two scenarios


def test_run_train_dir_evaluates_the_trained_weights(seeds_dir, cli, tmp_path):
    import tomllib
    folder = seeds_dir / "seed-1"
    result = cli("run", folder, "-n", "1", "-o", tmp_path / "run")
    assert result.exit_code == 0, result.output
    inputs = tomllib.loads((tmp_path / "run" / "plugins.toml").read_text())["inputs"]
    assert inputs["attention.checkpoint"] == file_digest(str(folder / "best.pt"))
    assert inputs["attention.checkpoint"] != file_digest("builtin:ata_hrl_a")


def test_tensorboard_scalars_are_log_csv(seeds_dir):
    pytest.importorskip("tensorboard")
    from tensorboard.backend.event_processing.event_accumulator import EventAccumulator
    folder = seeds_dir / "seed-0"
    with open(folder / "log.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    acc = EventAccumulator(str(folder), size_guidance={"scalars": 0})
    acc.Reload()
    for column in ("loss", "mean_score", "R_ITA", "eval_score", "eval_expected", "wall_s"):
        want = [(int(r["step"]), float(r[column])) for r in rows if r[column] != ""]
        got = [(e.step, e.value) for e in acc.Scalars(column)]
        assert len(got) == len(want) > 0, column
        for (s1, v1), (s2, v2) in zip(got, want):
            assert s1 == s2 and math.isclose(v1, v2, rel_tol=1e-6), (column, s1, v1, v2)
    # what does not apply in the ITA phase stays empty, in both
    assert all(r["R_C"] == r["R_TR"] == r["reallocations"] == "" for r in rows)
    assert not {"R_C", "R_TR", "reallocations"} & set(acc.Tags()["scalars"])


def test_a_folder_of_seeds_resumes_as_a_whole(seeds_dir, cli, tmp_path):
    """A seed that never started trains from its folder's mission, to the same weights and
    log as before; a finished seed is left as it was."""
    import shutil
    import torch
    copy = tmp_path / "seeds"
    shutil.copytree(seeds_dir, copy)
    for name in ("log.csv", "checkpoint.pt", "best.pt", "trained.json"):
        (copy / "seed-1" / name).unlink()
    for events in (copy / "seed-1").glob("events.out.tfevents.*"):
        events.unlink()
    before = (copy / "seed-0" / "log.csv").read_text()
    result = cli("train", "--resume", copy, "-e", "serial")
    assert result.exit_code == 0, result.output
    assert (copy / "seed-0" / "log.csv").read_text() == before

    def rows(folder):      # the columns that do not depend on the machine's speed
        with open(folder / "log.csv", newline="") as f:
            return [{k: v for k, v in r.items() if k not in ("episodes_per_s", "wall_s")}
                    for r in csv.DictReader(f)]
    assert rows(copy / "seed-1") == rows(seeds_dir / "seed-1")
    a, b = (torch.load(d / "seed-1" / "best.pt", weights_only=True)["model"]
            for d in (copy, seeds_dir))
    assert all(torch.equal(a[k], b[k]) for k in a)
    # the copy's resolved missions name the original folder's weights: refused, not run
    result = cli("run", copy / "seed-1", "-n", "1")
    assert result.exit_code == 2 and "moved or copied" in result.output


def test_without_tensorboard_training_logs_and_says_how_to_get_curves(tmp_path, monkeypatch,
                                                                      capsys):
    import importlib.util
    import sys
    from ata.cli.training import _curves_note
    from ata.training import TrainRun
    monkeypatch.setitem(sys.modules, "tensorboard", None)       # import tensorboard fails
    run = TrainRun(tmp_path / "run", "", ["phase", "step", "loss"])
    run.log({"phase": "ita", "step": 1, "loss": "0.5"})
    run.close()
    assert run.tensorboard_missing
    assert sorted(p.name for p in (tmp_path / "run").iterdir()) == ["log.csv",
                                                                   "mission.resolved.toml"]
    monkeypatch.setattr(importlib.util, "find_spec", lambda name: None)
    _curves_note(tmp_path / "run")
    _curves_note(tmp_path / "run", done=True)
    text = " ".join(capsys.readouterr().err.split())
    assert text.count("pip install 'ata[tensorboard]'") == 1


@pytest.mark.parametrize("plugins, phases", [(["ctr", "aux"], {"aux", "ita", "ctr"}),
                                             (["ita"], {"ita"}), (["trp"], {"dqn"}),
                                             (["ita", "trp"], {"dqn"})])
def test_the_smoke_preset_trains_every_phase_of_the_recipe(plugins, phases):
    from ata.session import build_trainer, load_session, training_mission_for
    from ata.training.presets import preset_overrides
    source = str(training_mission_for(plugins))
    recipe = build_trainer(load_session(source))
    name = recipe.component_name
    smoke = build_trainer(load_session(
        source, preset_overrides(name, type(recipe), "smoke")))
    if name == "ata_hrl":
        full, small = recipe.phases(), smoke.phases()
        assert {p for p, n in small.items() if n} == {p for p, n in full.items() if n} == phases
    else:
        assert phases == {"dqn"} and 0 < smoke.total_steps() < recipe.total_steps()
    assert smoke.total_steps() < recipe.total_steps() / 10


def test_the_curves_across_seeds_draw_each_seed_their_mean_the_middle_half_and_the_phases(
        tmp_path):
    from ata.results.curves import read_log
    from ata.results.report import pyplot
    from ata.results.seed_curves import SeedLogs, seeds_figure

    logs = []
    for seed in range(4):
        folder = tmp_path / f"seed{seed}"
        folder.mkdir()
        rows = ["phase,step,loss"] + [f"aux,{k},{1.0 + seed - 0.1 * k}" for k in range(1, 6)]
        rows += [f"ita,{k},{seed + 0.5 * k}" for k in range(1, 4)]
        (folder / "log.csv").write_text("\n".join(rows) + "\n")
        logs.append(read_log(folder))
    plt = pyplot()
    fig = seeds_figure(plt, SeedLogs(tmp_path, [0, 1, 2, 3], logs, [tmp_path] * 4))
    ax = fig.axes[0]
    lines = [ln for ln in ax.get_lines() if ln.get_linestyle() != "--"]
    assert len(lines) == 1 + 4                      # the mean and each seed
    mean = lines[0].get_ydata()
    assert mean[0] == pytest.approx((0.9 + 1.9 + 2.9 + 3.9) / 4)
    assert [ln.get_linewidth() for ln in lines[1:]] == [0.5] * 4
    band = ax.collections[0].get_paths()[0].vertices[:, 1]
    assert band.min() == pytest.approx(min(1.65, 0.9 + 0.75 - 0.4), abs=1.0)
    dashed = [ln for ln in ax.get_lines() if ln.get_linestyle() == "--"]
    assert [ln.get_xdata()[0] for ln in dashed] == [logs[0].starts[1]]   # where ita begins
    plt.close(fig)


@pytest.mark.parametrize("relative", [False, True])
def test_eval_of_one_run_folder_pairs_its_weights_with_greedy(seeds_dir, cli, tmp_path,
                                                              relative, monkeypatch):
    folder = seeds_dir / "seed-1"
    if relative:                     # `ata eval runs/NAME` from the folder above it
        monkeypatch.chdir(seeds_dir)
        folder = "seed-1"
    result = cli("eval", folder, "-n", 2, "-o", tmp_path / "ev", "-e", "serial", "-q")
    assert result.exit_code == 0, result.output
    with open(tmp_path / "ev" / "results.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    methods = {r["method"] for r in rows}
    assert "greedy" in methods and len(methods) == 2, methods
    assert {r["scenario"] for r in rows if r["method"] == "greedy"} == \
        {r["scenario"] for r in rows if r["method"] != "greedy"}


def test_seeds_start_from_the_same_seed_of_a_folder_of_seeds(seeds_dir, cli, tmp_path):
    """`--set ata_hrl.ita_from=SEEDS` with --seeds: seed S starts from SEEDS/seed-S/best.pt;
    a seed the folder lacks, or the folder without --seeds, is refused before any work."""
    import tomllib
    out = tmp_path / "variants"
    result = cli("train", "--plugins", "ita", "--preset", "smoke", "--seeds", "2", "-e",
                 "serial", "-o", out, "--set", f"ata_hrl.ita_from={seeds_dir}",
                 "--set", "ata_hrl.aux_steps=0", *TINY)
    assert result.exit_code == 0, result.output
    for s in (0, 1):
        mission = tomllib.loads((out / f"seed-{s}" / "mission.resolved.toml").read_text())
        assert mission["ata_hrl"]["ita_from"] == str((seeds_dir / f"seed-{s}" / "best.pt")
                                                     .resolve())
        assert mission["ata_hrl"]["seed"] == s
    result = cli("train", "--plugins", "ita", "--seeds", "0,5", "-o", tmp_path / "five",
                 "--set", f"ata_hrl.ita_from={seeds_dir}")
    assert result.exit_code == 2 and "without seed 5" in result.output
    assert not (tmp_path / "five").exists()
    result = cli("train", "--plugins", "ita", "-o", tmp_path / "one",
                 "--set", f"ata_hrl.ita_from={seeds_dir}")
    assert result.exit_code == 2 and "is a folder of seeds" in result.output
    # a seed still training (no trained.json) is not started from: its best.pt still moves
    import shutil
    moving = tmp_path / "moving"
    shutil.copytree(seeds_dir, moving)
    (moving / "seed-1" / "trained.json").unlink()
    result = cli("train", "--plugins", "ita", "--seeds", "2", "-o", tmp_path / "early",
                 "--set", f"ata_hrl.ita_from={moving}")
    assert result.exit_code == 2 and "seed 1 of" in result.output \
        and "has not finished" in result.output


def test_seeds_are_added_to_a_folder_by_the_command_that_trained_it(seeds_dir, cli, tmp_path):
    """The same command with other seeds adds them (the seeds held are left as they were);
    another command's folder, or a seed it holds, is refused before any work."""
    import json
    import shutil
    folder = tmp_path / "seeds"
    shutil.copytree(seeds_dir, folder)
    before = (folder / "seed-0" / "log.csv").read_text()
    base = ["train", "--plugins", "ita", "--preset", "smoke", "-e", "serial", "-o", folder,
            *TINY]
    result = cli(*base, "--seeds", "1,0")
    assert result.exit_code == 2 and "holds every seed given already" in result.output
    result = cli(*base, "--seeds", "3,", "--set", "ata_hrl.lr=0.002")
    assert result.exit_code == 2 and "another command" in result.output \
        and "overrides" in result.output
    assert not (folder / "seed-3").exists()
    result = cli(*base, "--seeds", "1,3")          # 1 is held: 3 is added
    assert result.exit_code == 0, result.output
    assert json.loads((folder / "seeds.json").read_text())["seeds"] == [0, 1, 3]
    assert (folder / "seed-3" / "trained.json").is_file()
    assert (folder / "seed-0" / "log.csv").read_text() == before
    assert "seed 3" in (folder / "suite.toml").read_text()


def test_a_trained_folder_runs_each_cell_at_that_cells_team_and_level(seeds_dir, tmp_path):
    """A training folder's resolved mission names its team sizes and its level's fatigue
    variance and event probability; a suite cell of another setting or level runs that
    setting's team and that level's uncertainty, not the training mission's."""
    from ata.core.mission import TEAM_SETTINGS, UNCERTAINTY_LEVELS
    from ata.experiment.evaluate import plan
    suite = tmp_path / "suite.toml"
    suite.write_text(f'[suite]\nsettings = ["a", "b"]\nuncertainty = ["low", "high"]\n'
                     f'[[method]]\nname = "mine"\nmission = "{seeds_dir}"\n')
    _, jobs = plan([str(suite)], validate=False)
    assert len(jobs) == 2 * 2 * 2                   # two seeds, two settings, two levels
    for job in jobs:
        m = job.session.mission.settings
        team = TEAM_SETTINGS[job.setting]
        assert (m.humans, m.robots, m.tasks) == (team.humans, team.robots, team.tasks)
        assert (m.fatigue_variance, m.event_probability) == UNCERTAINTY_LEVELS[job.level]
