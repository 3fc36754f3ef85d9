"""The command line: `ata run`, `ata check`, `ata plugins`, and one clear message per bad input."""

from __future__ import annotations

import csv
import dataclasses
import json
import os
import subprocess
import sys
import tomllib

import pytest

from _support import assert_user_error, flat
from ata import __version__
from ata.session import load_session
from ata.core.mission import ComponentSlots, MissionSettings
from ata.core.registry import BUILTIN_PLUGINS, collect_components, get_plugin_manager

TINY = """\
[mission]
name = "tiny"
scenarios = 3
batch_size = 3
"""

BUILTIN_COMPONENTS = {
    "task_model:poi", "human_model:human", "robot_model:robot",
    "injector:fatigue_noise", "perturbation:attribute_change", "perturbation:robot_failure",
    "injector:latency", "reconstructor:identity", "policy:greedy", "policy:random",
    "condition:never", "condition:always", "condition:on_event",
}


@pytest.fixture
def tiny(tmp_path):
    path = tmp_path / "tiny.toml"
    path.write_text(TINY, encoding="utf-8")
    return path


def read_rows(path):
    with open(path, newline="", encoding="utf-8") as f:
        return list(csv.DictReader(f))


# --- run -----------------------------------------------------------------------------------------

def test_run_tiny_mission_writes_the_run_folder(cli, tiny, tmp_path):
    out = tmp_path / "run"
    result = cli("run", tiny, "--out", out, "--quiet")
    assert result.exit_code == 0, result.output
    text = flat(result.output)
    # no title: the method is named by its components
    assert "greedy / on_event / greedy: tiny" in text
    assert "method greedy / on_event / greedy" in text
    assert "team setting a: 6 humans, 8 robots, 60 POIs" in text
    assert "scenarios 3 (ids 0..2, root seed 0)" in text
    assert f"results: {out}" in text
    assert sorted(p.name for p in out.iterdir()) == [
        "mission.resolved.toml", "plan.json", "plugins.toml", "provenance.json", "results.csv",
        "summary.json", "units.jsonl"]

    rows = read_rows(out / "results.csv")
    assert [int(r["scenario"]) for r in rows] == [0, 1, 2]
    assert {"score", "upper_bound", "fraction_of_u", "reallocations"} <= set(rows[0])

    summary = json.loads((out / "summary.json").read_text())
    assert summary["scenarios"] == 3
    scores = [float(r["score"]) for r in rows]
    assert summary["score_mean"] == pytest.approx(sum(scores) / 3)

    versions = tomllib.loads((out / "plugins.toml").read_text())
    assert versions["ata"] == __version__
    assert versions["components"]["policy greedy"] == f"ata {__version__}"
    assert versions["components"]["injector latency"] == f"ata {__version__}"


def test_resolved_mission_reloads_with_every_default_filled_in(cli, tiny, tmp_path):
    out = tmp_path / "run"
    assert cli("run", tiny, "--out", out, "-q").exit_code == 0
    resolved_path = out / "mission.resolved.toml"
    resolved = tomllib.loads(resolved_path.read_text())

    # every [mission] and [components] key, the team filled in from setting (a)
    assert set(resolved["mission"]) == {f.name for f in dataclasses.fields(MissionSettings)}
    assert set(resolved["components"]) == {f.name for f in dataclasses.fields(ComponentSlots)}
    assert (resolved["mission"]["humans"], resolved["mission"]["robots"],
            resolved["mission"]["tasks"]) == (6, 8, 60)
    assert resolved["mission"]["event_probability"] == 0.2     # the medium level's p
    assert resolved["human"]["fatigue_floor"] == 0.4

    # it loads and validates as a mission in its own right, to the same mission
    session = load_session(str(resolved_path))
    assert session.mission.resolved() == resolved
    for name, st in session.mission.component_settings.items():
        expected = ({f.name for f in dataclasses.fields(st) if getattr(st, f.name) is not None}
                    if st is not None else set())
        assert set(resolved[name]) == expected, name


def test_run_without_a_mission_uses_the_built_in_default(cli, tmp_path):
    out = tmp_path / "run"
    result = cli("run", "--set", "mission.scenarios=2", "--out", out, "-q")
    assert result.exit_code == 0, result.output
    assert "ATA-HRL: default method attention / ctr / ctr + aux team setting a:" in flat(result.output)
    assert len(read_rows(out / "results.csv")) == 2
    resolved = tomllib.loads((out / "mission.resolved.toml").read_text())
    assert resolved["mission"]["name"] == "default"
    assert resolved["mission"]["scenarios"] == 2


def test_set_overrides_mission_and_component_keys(cli, tiny, tmp_path):
    out = tmp_path / "run"
    result = cli("run", tiny, "--out", out, "-q", "--set", "mission.seed=7",
                 "--set", "mission.scenarios=2", "--set", "components.condition=never",
                 "-s", "latency.probability=0.5")
    assert result.exit_code == 0, result.output
    assert "seed 7" in flat(result.output)
    # the reallocation policy never runs under "never": the label leaves it out
    assert "method greedy / never team" in flat(result.output)
    resolved = tomllib.loads((out / "mission.resolved.toml").read_text())
    assert resolved["mission"]["seed"] == 7
    assert resolved["components"]["condition"] == "never"
    assert resolved["latency"]["probability"] == 0.5
    rows = read_rows(out / "results.csv")
    assert len(rows) == 2
    assert [int(r["reallocations"]) for r in rows] == [0, 0]   # `never` never reallocates


def test_set_changes_the_results(cli, tiny, tmp_path):
    a, b = tmp_path / "a", tmp_path / "b"
    assert cli("run", tiny, "--out", a, "-q").exit_code == 0
    assert cli("run", tiny, "--out", b, "-q", "--set", "mission.seed=1").exit_code == 0
    assert read_rows(a / "results.csv") != read_rows(b / "results.csv")


# --- check ---------------------------------------------------------------------------------------

def test_check_a_valid_file(cli, tiny):
    result = cli("check", tiny)
    assert result.exit_code == 0, result.output
    text = flat(result.output)
    assert f"ok: {tiny}: setting a (6 humans, 8 robots, 60 POIs), 3 scenarios" in text
    assert "fatigue variance 0.1, event probability 0.2" in text


def test_check_show_prints_the_resolved_mission(cli, tiny):
    result = cli("check", tiny, "--show", "--set", "mission.seed=5")
    assert result.exit_code == 0, result.output
    assert "seed = 5" in result.output
    assert "[greedy]" in result.output


def test_check_an_invalid_file(cli, tmp_path):
    path = tmp_path / "bad.toml"
    path.write_text('[mission]\nseed = -3\n', encoding="utf-8")
    result = cli("check", path)
    assert result.exit_code == 2
    assert "ok:" not in result.output
    assert f"{path}: [mission] key 'seed': -3 is below the minimum" in flat(result.output)


# --- plugins -------------------------------------------------------------------------------------

def test_plugins_lists_every_built_in_component(cli):
    result = cli("plugins")
    assert result.exit_code == 0, result.output
    registry = collect_components(get_plugin_manager())
    listed = {f"{c.kind}:{c.name}" for c in registry.components.values()}
    assert BUILTIN_COMPONENTS <= listed
    rows = [ln.split() for ln in result.output.splitlines()]
    shown = {f"{r[1]}:{r[0]}": r for r in rows if len(r) >= 5}
    for component in listed:
        assert component in shown
    for info in registry.components.values():
        row = shown[f"{info.kind}:{info.name}"]
        assert "ata.plugins." + row[2] == info.plugin
        assert row[3:5] == ["ata", __version__]
    assert {info.plugin for info in registry.components.values()} == set(BUILTIN_PLUGINS)


def test_plugins_verbose_lists_settings(cli):
    result = cli("plugins", "--verbose")
    assert result.exit_code == 0, result.output
    text = flat(result.output)
    assert "[latency] injector, from ata.plugins.uncertainty.latency; hooks: ata_inject" in text
    assert ("groups = ['robots', 'tasks'] (a list of strings, one of 'humans', 'robots', "
            "'tasks') entity groups that lag") in text
    # ranges and choices are shown
    assert "probability = None (a number or nothing, 0.0 to 1.0)" in text


def test_plugins_lists_the_optional_plugins_unloaded(cli):
    result = cli("plugins")
    assert result.exit_code == 0, result.output
    rows = {ln.split()[0] + " " + ln.split()[1]: ln for ln in result.output.splitlines()
            if len(ln.split()) > 2}
    assert "(--plugins ita)" in rows["attention policy"]
    assert "(--plugins trp)" in rows["tr_pomdp policy"]
    assert "(--plugins aux)" in rows["aux reconstructor"]
    assert "(--plugins ctr)" in rows["ctr condition"]
    assert "not loaded now: aux, ctr, ita, trp" in flat(result.output)


@pytest.mark.parametrize("args", [["run", "--help"], ["eval", "--help"], ["report", "--help"],
                                  ["compare", "--help"], ["plugins"],
                                  ["run", "--set", "mission.scenarios=2", "-q"]])
def test_output_fits_80_columns_without_type_tags(tmp_path, monkeypatch, args):
    from typer.testing import CliRunner

    from ata.cli import app
    monkeypatch.chdir(tmp_path)
    result = CliRunner(env={"COLUMNS": "80"}).invoke(app, args)
    assert result.exit_code == 0, result.output
    lines = result.output.splitlines()
    assert max(len(ln) for ln in lines) <= 80
    for tag in ("<bool>", "<list[", "<str>", "<path>", "<int"):
        assert tag not in result.output
    # nothing a user must read or type is cut short
    assert "…" not in result.output
    if args[0] == "run" and "--help" not in args:
        assert "ATA-HRL: default" in result.output
        assert "method" in result.output and "team performance" in result.output


# --- bad input: one message naming the file, the key and what is allowed; exit 2 -----------------

BAD_FILES = {
    "toml_syntax": ("[mission\nscenarios = 3\n",
                    ["TOML syntax error", "line 1"]),
    "unknown_component": ('[components]\ninitial = "greddy"\n',
                          ["[components] key 'initial': unknown policy 'greddy'; registered:",
                           "greedy", "(see: ata plugins)"]),
    "unknown_mission_key": ("[mission]\nscenarioes = 3\n",
                            ["[mission] key 'scenarioes': unknown key; allowed keys:",
                             "scenarios", "seed"]),
    "unknown_component_key": ("[latency]\nprobabilty = 0.1\n",
                              ["[latency] key 'probabilty': unknown key; allowed keys: groups, "
                               "probability"]),
    "unknown_table": ("[nothere]\nx = 1\n",
                      ["[nothere]: names no chosen component; tables allowed:", "[mission]",
                       "[components]", "[latency]"]),
    "wrong_type": ('[mission]\nscenarios = "ten"\n',
                   ["[mission] key 'scenarios': 'ten' is not an integer"]),
    "negative_team": ("[mission]\nhumans = -1\n",
                      ["[mission] key 'humans': -1 is below the minimum; allowed: 1 to 1000"]),
    "probability_above_1": ("[latency]\nprobability = 1.5\n",
                            ["[latency] key 'probability': 1.5 is above the maximum; "
                             "allowed: 0.0 to 1.0"]),
    "zero_pois": ("[mission]\ntasks = 0\n",
                  ["[mission] key 'tasks': 0 is below the minimum; allowed: 1 to 10000"]),
    "bad_choice": ('[mission]\nuncertainty = "extreme"\n',
                   ["[mission] key 'uncertainty': 'extreme' is not allowed; choose one of "
                    "'none', 'low', 'medium', 'high', 'custom'"]),
    "list_expected": ('[components]\ninjectors = "latency"\n',
                      ["[components] key 'injectors': 'latency' is not a list of strings"]),
    "settings_for_settingless": ("[on_event]\nx = 1\n",
                                 ["[on_event] key 'x': this component takes no settings"]),
    "not_a_table": ("mission = 3\n", ["[mission]: must be a table"]),
}


@pytest.mark.parametrize("command", ["check", "run"])
@pytest.mark.parametrize("case", sorted(BAD_FILES))
def test_bad_mission_file(cli, tmp_path, command, case):
    content, fragments = BAD_FILES[case]
    path = tmp_path / "bad.toml"
    path.write_text(content, encoding="utf-8")
    args = [command, path] + (["--out", tmp_path / "run", "-q"] if command == "run" else [])
    result = cli(*args)
    assert_user_error(result, f"error: {path}: ", *fragments)
    assert not (tmp_path / "run").exists()


@pytest.mark.parametrize("command", ["check", "run"])
def test_missing_file(cli, tmp_path, command):
    path = tmp_path / "nope.toml"
    assert_user_error(cli(command, path), f"error: {path}: no such file")


def test_directory_instead_of_a_file(cli, tmp_path):
    assert_user_error(cli("check", tmp_path), f"error: {tmp_path}: a folder, not a mission file")


@pytest.mark.parametrize("override, fragments", [
    ("mission.event_probability=1.5",
     ["[mission] key 'event_probability': 1.5 is above the maximum; allowed: 0.0 to 1.0"]),
    ("mission.scenarios=ten", ["[mission] key 'scenarios': 'ten' is not an integer"]),
    ("components.initial=greddy", ["[components] key 'initial': unknown policy 'greddy'; "
                                   "registered:", "did you mean 'greedy'?"]),
    ("mission.humanz=4", ["[mission] key 'humanz': unknown key; allowed keys:"]),
    ("greddy.x=1", ["[greddy]: names no chosen component; tables allowed:"]),
])
def test_bad_set_is_blamed_on_the_set(cli, tiny, override, fragments):
    """A bad value given with --set names that --set, not the mission file it overrides."""
    result = cli("check", tiny, "--set", override)
    assert_user_error(result, f"error: --set {override}: ", *fragments)
    assert str(tiny) not in result.output


@pytest.mark.parametrize("override, fragments", [
    ("mission.seed", ["error: --set: 'mission.seed' is not of the form table.key=value"]),
    ("seed=3", ["error: --set: 'seed' must name a table and a key, e.g. mission.seed=3"]),
])
def test_malformed_set(cli, tiny, override, fragments):
    assert_user_error(cli("check", tiny, "--set", override), *fragments)


def test_a_bad_key_in_the_file_is_still_blamed_on_the_file(cli, tmp_path):
    path = tmp_path / "m.toml"
    path.write_text(TINY.replace("scenarios = 3", "scenarios = 0"), encoding="utf-8")
    # --set of another key leaves the blame with the file; of the same key, the last one wins
    assert_user_error(cli("check", path, "--set", "mission.seed=1"),
                      f"error: {path}: [mission] key 'scenarios': 0 is below the minimum")
    assert_user_error(cli("check", path, "--set", "mission.scenarios=-1", "--set",
                          "mission.scenarios=-2"),
                      "error: --set mission.scenarios=-2: [mission] key 'scenarios': -2 is "
                      "below the minimum")


def test_bad_set_on_the_built_in_mission(cli):
    result = cli("run", "--set", "mission.humans=-1", "-q")
    assert_user_error(result, "error: --set mission.humans=-1: [mission] key 'humans': -1 is "
                              "below the minimum")
    assert "default.toml" not in result.output


@pytest.mark.parametrize("command", ["check", "run", "plugins"])
def test_unknown_optional_plugin(cli, tiny, command):
    args = ["plugins", "--plugins", "nope"] if command == "plugins" \
        else [command, tiny, "--plugins", "nope"]
    assert_user_error(cli(*args), "error: --plugins: unknown optional plugin 'nope'; available:")


def test_real_entry_point_prints_one_line_without_traceback(tmp_path):
    """Outside CliRunner too: the installed command's stderr is the one message."""
    path = tmp_path / "nope.toml"
    proc = subprocess.run([sys.executable, "-m", "ata.cli", "check", str(path)],
                          capture_output=True, text=True,
                          env={**os.environ, "COLUMNS": "200"})
    assert proc.returncode == 2
    assert proc.stdout == ""
    assert "Traceback" not in proc.stderr
    assert flat(proc.stderr) == f"error: {path}: no such file"


@pytest.mark.parametrize("key, value", [
    ("mission.horizon_s", "nan"), ("mission.tick_s", "inf"), ("mission.event_probability", "nan"),
    ("mission.fatigue_variance", "inf"), ("robot.uav_speed", "nan"), ("poi.area_m", "-inf"),
    ("greedy.human_time_cost", "nan"),
])
def test_non_finite_numbers_are_refused(cli, tiny, key, value):
    for command in ("check", "run"):
        result = cli(command, tiny, "--set", f"{key}={value}", *(["-q"] if command == "run" else []))
        table, name = key.split(".")
        assert_user_error(result, f"[{table}] key '{name}': {value} is not allowed; a finite "
                                  "number is needed")


def test_a_latency_group_that_does_not_exist_is_refused_by_check(cli, tiny):
    assert_user_error(cli("check", tiny, "--set", "latency.groups=['bogus']"),
                      "[latency] key 'groups': 'bogus' is not allowed; choose one of 'humans', "
                      "'robots', 'tasks'")


def test_an_output_folder_under_a_file_is_refused_before_any_work(cli, tiny, tmp_path,
                                                                   monkeypatch):
    from ata.experiment import execute
    ran = []
    monkeypatch.setattr(execute, "run_units", lambda *a, **k: ran.append(1))
    blocker = tmp_path / "file"
    blocker.write_text("")
    assert_user_error(cli("run", tiny, "-q", "--out", blocker / "sub"),
                      f"--out: cannot write to {blocker / 'sub'}: Not a directory")
    assert ran == []


def test_two_runs_in_the_same_second_get_two_folders(tiny, tmp_path, monkeypatch):
    from ata.experiment import runner
    from ata.runtime import folders
    monkeypatch.setenv("ATA_RUNS", str(tmp_path))
    monkeypatch.setattr(folders.time, "strftime", lambda fmt: "20260101-000000")
    mission = load_session(str(tiny)).mission
    first, second = runner.default_out_dir(mission), runner.default_out_dir(mission)
    assert first.name == "tiny-20260101-000000"
    assert second.name == "tiny-20260101-000000-2"
    assert first.is_dir() and second.is_dir()


def test_train_into_the_folder_of_an_old_run_is_refused(cli, tmp_path):
    from ata.training import TrainRun
    old = tmp_path / "old"
    TrainRun(old, "", ["step"])                       # an earlier run's folder
    (old / "best.pt").write_bytes(b"x")
    result = cli("train", "--plugins", "ita", "-q", "--out", old)
    assert_user_error(result, f"--out: {old} holds a training run already (best.pt, log.csv): "
                              f"resume it with --resume {old}, or choose another folder")
    assert (old / "best.pt").read_bytes() == b"x"


def test_a_perturbation_listed_as_an_injector_is_pointed_to_its_slot(cli, tiny):
    assert_user_error(cli("check", tiny, "--set",
                          "components.injectors=['fatigue_noise', 'attribute_change']"),
                      "[components] key 'injectors': unknown injector 'attribute_change'",
                      "'attribute_change' is registered as a perturbation, which goes in another "
                      "[components] slot")


def test_routing_in_components_is_pointed_to_the_robot_model(cli, tiny):
    assert_user_error(cli("check", tiny, "--set", "components.routing=nearest"),
                      "[components] key 'routing': routing is a setting of the robot model: "
                      "write it as [robot] routing (see: ata plugins --verbose)")


# --- one run path: builtin missions, batches that save, the output folder's checks ---------------

def test_run_and_check_take_a_built_in_mission_by_name(cli, tmp_path):
    out = tmp_path / "run"
    result = cli("run", "builtin:greedy", "--set", "mission.scenarios=2", "-q", "-o", out)
    assert result.exit_code == 0, result.output
    resolved = tomllib.loads((out / "mission.resolved.toml").read_text())
    assert resolved["mission"]["name"] == "greedy" and resolved["mission"]["scenarios"] == 2
    assert cli("check", "builtin:greedy").exit_code == 0
    assert_user_error(cli("run", "builtin:nope", "-q"), "error: builtin:nope: no built-in "
                      "mission 'nope'; there are: builtin:default, builtin:greedy,")


def test_a_long_run_is_saved_in_batches_of_at_most_100_scenarios():
    from ata.session import BASELINE_MISSION, load_session
    from ata.experiment.runner import RUN_CHUNK, mission_plan
    assert RUN_CHUNK == 100
    session = load_session(str(BASELINE_MISSION), ["mission.scenarios=250"])
    plan = mission_plan(session, 1)
    assert [c.size for c in plan.chunks[0]] == [100, 100, 50]
    assert (plan.units, plan.scenarios, plan.unit_name) == (3, 250, "batches")
    assert [c.size for c in mission_plan(session, 1, 120).chunks[0]] == [120, 120, 10]
    # batch_size caps the batches too; several workers share them out
    small = load_session(str(BASELINE_MISSION), ["mission.scenarios=250",
                                                 "mission.batch_size=60"])
    assert [c.size for c in mission_plan(small, 1).chunks[0]] == [60, 60, 60, 60, 10]
    assert [c.size for c in mission_plan(session, 4).chunks[0]] == [63, 63, 63, 61]


def test_run_help_names_the_default_batch(cli):
    from ata.experiment.units import RUN_CHUNK
    assert f"default {RUN_CHUNK}" in flat(cli("run", "--help").output)


@pytest.mark.parametrize("command", ["run", "eval"])
def test_a_second_run_on_a_folder_in_use_is_refused_naming_the_first(cli, tiny, tmp_path,
                                                                     command):
    from ata.experiment.runlog import FolderLock
    out = tmp_path / "busy"
    out.mkdir()
    args = [command, tiny, "-q", "-o", out] + (["-e", "serial"] if command == "eval" else [])
    with FolderLock(out):
        result = cli(*args)
        assert_user_error(result, f"error: --out: {out} is in use by another run (pid "
                                  f"{os.getpid()}, started ", "); wait for it to end, or "
                                  "choose another folder")
        assert sorted(p.name for p in out.iterdir()) == [".ata-lock"]
    assert not (out / ".ata-lock").exists()           # let go: the folder is free again
    result = cli(*args)
    assert result.exit_code == 0, result.output
    assert (out / "results.csv").exists() and not (out / ".ata-lock").exists()


@pytest.mark.parametrize("command", ["run", "eval"])
def test_run_and_eval_refuse_a_training_run_folder(cli, tiny, tmp_path, command):
    from ata.training import TrainRun
    folder = tmp_path / "train"
    TrainRun(folder, "[mission]\nname = 'trained'\n", ["step"])
    before = (folder / "mission.resolved.toml").read_text()
    args = [command, tiny, "-q", "-o", folder] + (["-e", "serial"] if command == "eval" else [])
    assert_user_error(cli(*args, "--force"), f"error: --out: {folder} is the folder of a "
                                             "training run (log.csv); choose another folder")
    assert (folder / "mission.resolved.toml").read_text() == before
    assert sorted(p.name for p in folder.iterdir()) == ["log.csv", "mission.resolved.toml"]


def test_a_swapped_component_shows_in_the_display_name(cli, tmp_path):
    from ata.session import load_session
    mission = load_session(None, ["components.condition='always'"]).mission
    assert mission.display_name() == "ATA-HRL [condition=always]"
    assert load_session(None, ["components.condition='always'",
                               "mission.title='w/o.C'"]).mission.display_name() == "w/o.C"
    assert load_session(None).mission.display_name() == "ATA-HRL"
