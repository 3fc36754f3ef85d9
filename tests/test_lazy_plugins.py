"""Lazy registration: naming a component in [components] loads the plugin declared to provide it
(entry-point group ``ata.components``), so ``[mission] plugins`` is optional; ``--plugins``
keeps working. A third-party declaration is honoured the same way."""

from __future__ import annotations

import csv
import importlib
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

from _support import assert_user_error
from ata.core import registry as registry_mod
from ata.core.errors import MissionError
from ata.core.mission import read_toml
from ata.core.registry import (Register, collect_components, declared_components,
                               get_plugin_manager, providers)
from ata.experiment import runner
from ata.session import Session, load_session, training_mission_for

ROOT = Path(__file__).resolve().parent.parent
EXAMPLES = ROOT / "examples" / "missions"
SHORT = ["mission.scenarios=2", "mission.batch_size=2", "mission.horizon_s=300",
         "mission.uncertainty='high'"]
"""Two scenarios of five epochs, with events: enough for every learned part to decide."""


def read_rows(run_dir: Path) -> list[dict]:
    with open(run_dir / "results.csv", newline="", encoding="utf-8") as f:
        return [{k: v for k, v in r.items() if "wall" not in k} for r in csv.DictReader(f)]


def rows(session: Session, workers: int = 1) -> list[dict]:
    result = runner.run_mission(session, workers=workers)
    return [{k: v for k, v in r.items() if "wall" not in k} for r in result.rows()]


# --- ata's own declarations ----------------------------------------------------------------------

def test_ata_declares_the_components_of_its_optional_plugins():
    assert declared_components() == {
        ("policy", "attention"): "ata.plugins.ata_hrl.ita",
        ("trainer", "ata_hrl"): "ata.plugins.ata_hrl.train",
        ("condition", "ctr"): "ata.plugins.ata_hrl.ctr",
        ("policy", "ctr"): "ata.plugins.ata_hrl.ctr",
        ("reconstructor", "aux"): "ata.plugins.ata_hrl.aux",
        ("policy", "tr_pomdp"): "ata.plugins.tr_pomdp",
        ("trainer", "tr_pomdp"): "ata.plugins.tr_pomdp",
    }
    assert providers(["greedy", "aux", "attention", "ctr", "tr_pomdp"]) == ["aux", "ita", "ctr",
                                                                            "trp"]


def test_no_built_in_or_example_mission_names_plugins():
    for path in [*sorted((ROOT / "ata" / "missions").glob("*.toml")),
                 *sorted(EXAMPLES.glob("*.toml"))]:
        assert "plugins" not in read_toml(path).get("mission", {}), path


def test_a_registry_loads_a_named_component_on_demand():
    pm = get_plugin_manager(entry_points=False)
    registry = collect_components(pm)
    assert pm.get_plugin("ata.plugins.ata_hrl.aux") is None
    assert "aux" not in registry.names("reconstructor")
    info = registry.get("reconstructor", "aux", "test")
    assert (info.kind, info.name, info.plugin) == ("reconstructor", "aux",
                                                   "ata.plugins.ata_hrl.aux")
    # aux brings the ITA policy along (its ATA_REQUIRES), loaded first, as --plugins aux does
    assert registry.loaded == ["ita", "aux"]
    assert registry.names("policy") == ["attention", "greedy", "keep", "milp", "random"]
    # a registry without a plugin manager (a test's own) loads nothing
    with pytest.raises(MissionError, match="reconstructor 'aux' is declared by the plugin "
                                           "ata.plugins.ata_hrl.aux, which this registry "
                                           "does not load"):
        Register().get("reconstructor", "aux", "test")


@pytest.mark.parametrize("mission, plugins, loaded", [
    ("ata_hrl_a", "ctr,aux", ["ita", "aux", "ctr"]),
    ("tr_pomdp_a", "trp", ["trp"]),
    ("atrl_tr_a", "ita,trp", ["ita", "trp"]),
])
def test_a_mission_without_plugins_runs_as_with_them(mission, plugins, loaded):
    path = str(EXAMPLES / f"{mission}.toml")
    lazy = load_session(path, SHORT)
    # the resolved mission names the plugins its components loaded, so that it reads back alone
    assert lazy.mission.settings.plugins == loaded
    named = load_session(path, SHORT, plugins.split(","))
    assert named.mission.settings.plugins == plugins.split(",")
    assert rows(lazy) == rows(named)


def test_worker_processes_load_what_the_mission_named():
    session = load_session(str(EXAMPLES / "tr_pomdp_a.toml"),
                                  [*SHORT, "mission.batch_size=1"])
    assert rows(session, workers=2) == rows(session)


def test_the_help_and_missions_that_name_no_learned_part_never_import_torch(tmp_path):
    """torch costs seconds a process: `ata --help` and a greedy, ITA-MILP or random mission
    load none of it (nor does the process that runs them)."""
    missions = [ROOT / "ata" / "missions" / "greedy.toml", EXAMPLES / "milp_a.toml",
                EXAMPLES / "random_baseline.toml"]
    code = ("import sys\n"
            "from typer.testing import CliRunner\n"
            "from ata.cli import app\n"
            "assert CliRunner().invoke(app, ['--help']).exit_code == 0\n"
            f"for i, m in enumerate({[str(m) for m in missions]!r}):\n"
            "    r = CliRunner().invoke(app, ['run', m, '-q', '--out', "
            f"{str(tmp_path)!r} + f'/run{{i}}', "
            f"*[x for kv in {[*SHORT, 'mission.scenarios=1']!r} for x in ('--set', kv)]])\n"
            "    assert r.exit_code == 0, r.output\n"
            "print(sorted(m for m in sys.modules if m.split('.')[0] in ('torch', 'ata')))\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout
    assert "'ata.plugins.policies.milp'" in out      # it did run them
    assert "torch" not in out


def test_cli_runs_a_mission_that_names_no_plugins(cli, tmp_path):
    out = tmp_path / "run"
    result = cli("run", EXAMPLES / "ata_hrl_wo_c_a.toml", "-q", "--out", out,
                 *[x for kv in SHORT for x in ("--set", kv)])
    assert result.exit_code == 0, result.output
    resolved = tomllib.loads((out / "mission.resolved.toml").read_text())
    assert resolved["mission"]["plugins"] == ["ita", "aux", "ctr"]
    assert resolved["components"]["reconstructors"] == ["aux"]


def test_the_promised_train_plugins_pick_their_missions():
    expected = {"ctr,aux": "train_ata_hrl.toml", "ctr": "train_ata_hrl_wo_aux.toml",
                "ita": "train_ita.toml", "trp": "train_tr_pomdp.toml",
                "ita,trp": "train_atrl_tr.toml"}
    for plugins, name in expected.items():
        assert training_mission_for(plugins.split(",")).name == name
    with pytest.raises(MissionError, match="no built-in training mission for ctr,ita,trp"):
        training_mission_for(["trp", "ctr"])


# --- unknown names -------------------------------------------------------------------------------

REGISTERED_POLICIES = "attention, ctr, greedy, keep, milp, random, tr_pomdp"


@pytest.mark.parametrize("override, message", [
    ("components.initial='atention'",
     f"unknown policy 'atention'; registered: {REGISTERED_POLICIES} (see: ata plugins); "
     "did you mean 'attention'?"),
    ("components.initial='ita'",
     f"unknown policy 'ita'; registered: {REGISTERED_POLICIES} (see: ata plugins); 'ita' is an "
     "optional plugin, not a component: it provides attention"),
    ("components.initial='aux'",
     f"unknown policy 'aux'; registered: {REGISTERED_POLICIES} (see: ata plugins); 'aux' is "
     "registered as a reconstructor, which goes in another [components] slot"),
])
def test_an_unknown_name_fails_listing_what_is_registered(cli, override, message):
    result = cli("check", EXAMPLES / "setting_a.toml", "--set", override)
    assert_user_error(result, f"error: --set {override}: [components] key 'initial': "
                              f"{message}")


# --- a third-party declaration -------------------------------------------------------------------

LAZY_PLUGIN = '''\
"""A policy that sends every POI to robot 0, declared in ata.components (never in ata)."""
import numpy as np

from ata import hookimpl
from ata.core.state import Allocation


class ToRobot0:
    def __init__(self, settings, mission):
        pass

    @hookimpl
    def ata_initial_allocation(self, ctx):
        B, P = ctx.reallocatable.shape
        return Allocation(np.zeros((B, P), np.int64), np.full((B, P), -1), np.full((B, P), -1))


@hookimpl
def ata_register_components(register):
    register("policy", "to_robot_0", ToRobot0)
'''


@pytest.fixture
def lazy_package(tmp_path, monkeypatch):
    """An installed distribution whose one plugin is declared to provide policy to_robot_0."""
    site = tmp_path / "site"
    site.mkdir()
    (site / "ata_lazy.py").write_text(LAZY_PLUGIN)
    info = site / "ata_lazy-0.2.0.dist-info"
    info.mkdir()
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: ata-lazy\nVersion: 0.2.0\n")
    (info / "entry_points.txt").write_text("[ata.components]\npolicy.to_robot_0 = ata_lazy\n")
    monkeypatch.syspath_prepend(str(site))
    monkeypatch.setenv("PYTHONPATH", str(site))   # for the worker processes
    monkeypatch.delitem(sys.modules, "ata_lazy", raising=False)
    importlib.invalidate_caches()
    return site


def test_a_third_party_declaration_is_honoured(lazy_package, tmp_path, cli):
    assert declared_components()[("policy", "to_robot_0")] == "ata_lazy"
    pm = get_plugin_manager()
    assert pm.get_plugin("ata_lazy") is None          # not loaded until a mission names it
    assert "to_robot_0" not in collect_components(pm).names("policy")
    mission = tmp_path / "m.toml"
    mission.write_text('[mission]\nscenarios = 4\nbatch_size = 2\n\n[components]\n'
                       'initial = "to_robot_0"\ncondition = "never"\n', encoding="utf-8")
    session = load_session(str(mission))
    info = session.registry.get("policy", "to_robot_0", "test")
    assert (info.plugin, info.dist) == ("ata_lazy", "ata-lazy 0.2.0")
    # no optional name to record: the resolved mission loads it on demand again
    assert session.mission.settings.plugins == []
    assert registry_mod.plugin_label("ata_lazy") == "ata_lazy"
    for workers in ("1", "2"):
        out = tmp_path / f"run{workers}"
        result = cli("run", mission, "-q", "--workers", workers, "--out", out)
        assert result.exit_code == 0, result.output
        versions = tomllib.loads((out / "plugins.toml").read_text())
        assert versions["components"]["policy to_robot_0"] == "ata-lazy 0.2.0"
    assert read_rows(tmp_path / "run1") == read_rows(tmp_path / "run2")
    assert [r["reallocations"] for r in read_rows(tmp_path / "run1")] == ["0"] * 4
    listed = cli("plugins")
    row = next(line for line in listed.output.splitlines() if line.split()[:1] == ["to_robot_0"])
    assert row.split() == ["to_robot_0", "policy", "ata_lazy", "ata-lazy", "0.2.0"]


def test_a_declared_plugin_with_a_misspelt_hook_fails_when_loaded(lazy_package, tmp_path, cli):
    (lazy_package / "ata_lazy.py").write_text(LAZY_PLUGIN + "\n\n@hookimpl\ndef ata_setpu(sim):\n"
                                                          "    pass\n")
    mission = tmp_path / "m.toml"
    mission.write_text('[components]\ninitial = "to_robot_0"\n', encoding="utf-8")
    assert cli("check", EXAMPLES / "setting_a.toml").exit_code == 0   # not named: not loaded
    result = cli("check", mission)
    assert_user_error(result, "error: a plugin failed validation: unknown hook 'ata_setpu' in "
                              "plugin <module 'ata_lazy'", "did you mean 'ata_setup'?")


def test_a_declared_plugin_requiring_a_missing_plugin_is_one_message(lazy_package, tmp_path,
                                                                      cli):
    (lazy_package / "ata_lazy.py").write_text(LAZY_PLUGIN + '\nATA_REQUIRES = ("nope",)\n')
    mission = tmp_path / "m.toml"
    mission.write_text('[components]\ninitial = "to_robot_0"\n', encoding="utf-8")
    assert_user_error(cli("check", mission),
                      f"error: {mission}: plugin ata_lazy requires the optional plugin 'nope', "
                      "which is not installed; available: aux, ctr, ita, trp")
