"""A broken third-party plugin is reported and left out, as stevedore's load-failure callback
does: one warning line names the package, the entry point and why; every other command works;
`ata plugins` lists it as broken; a mission naming one of its components fails with that line."""

from __future__ import annotations

import importlib
import sys
from pathlib import Path

import pytest

from _support import assert_user_error, flat
from ata.core import registry as registry_mod
from ata.core.registry import broken_plugins, collect_components, get_plugin_manager

CLASH = '''\
from ata import hookimpl


class Mine:
    def __init__(self, settings, mission):
        pass


@hookimpl
def ata_register_components(register):
    register("policy", "mine", Mine)
    register("policy", "greedy", Mine)
'''

RAISES = '''\
from ata import hookimpl


@hookimpl
def ata_register_components(register):
    raise RuntimeError("boom in registration")


@hookimpl
def ata_setup(sim):
    raise AssertionError("the hooks of a plugin left out must not run")
'''

BROKEN = {
    "import": ("ata", "ata_broken = ata_broken", "import no_such_module_xyz\n",
               "ModuleNotFoundError: No module named 'no_such_module_xyz'"),
    "clash": ("ata", "ata_broken = ata_broken", CLASH,
              "ValueError: plugin ata_broken: component name 'greedy' is already registered "
              "(policy) by ata.plugins.policies.greedy"),
    "raises": ("ata", "ata_broken = ata_broken", RAISES, "RuntimeError: boom in registration"),
    "declared": ("ata.components", "policy.mine = ata_broken",
                 "raise ImportError('cannot import this one')\n",
                 "ImportError: cannot import this one"),
}


def install(tmp_path: Path, monkeypatch, group: str, entry: str, source: str) -> None:
    """An installed distribution ata-broken 0.1.0 whose one entry point is `entry`."""
    site = tmp_path / "site"
    site.mkdir()
    (site / "ata_broken.py").write_text(source, encoding="utf-8")
    info = site / "ata_broken-0.1.0.dist-info"
    info.mkdir()
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: ata-broken\nVersion: 0.1.0\n")
    (info / "entry_points.txt").write_text(f"[{group}]\n{entry}\n")
    monkeypatch.syspath_prepend(str(site))
    monkeypatch.setenv("PYTHONPATH", str(site))
    monkeypatch.delitem(sys.modules, "ata_broken", raising=False)
    importlib.invalidate_caches()


@pytest.fixture(params=sorted(BROKEN))
def broken(request, tmp_path, monkeypatch):
    """The line that reports the broken plugin, once installed."""
    group, entry, source, why = BROKEN[request.param]
    install(tmp_path, monkeypatch, group, entry, source)
    return (f"plugin package ata-broken 0.1.0, entry point {entry} (group {group!r}) failed "
            f"to load and is left out: {why}")


def test_a_broken_plugin_is_left_out_and_reported_once(broken, monkeypatch):
    seen = []
    monkeypatch.setattr(registry_mod, "on_load_failure", seen.append)
    registry_mod.reset_reports()
    pm = get_plugin_manager()
    registry = collect_components(pm, declared=True)
    assert [b.line() for b in broken_plugins(pm)] == [broken]
    assert [b.line() for b in seen] == [broken]
    assert "mine" not in registry.names("policy")
    assert registry.get("policy", "greedy", "test").plugin == "ata.plugins.policies.greedy"
    collect_components(get_plugin_manager(), declared=True)
    assert len(seen) == 1                               # reported once per command


def test_every_other_command_keeps_working(broken, cli, tmp_path):
    listed = cli("plugins")
    assert listed.exit_code == 0, listed.output
    assert f"warning: {broken}" in flat(listed.output)
    assert "(broken)" in listed.output
    assert "greedy" in listed.output
    out = tmp_path / "run"
    result = cli("run", "builtin:greedy", "--set", "mission.scenarios=2", "-q", "-o", out)
    assert result.exit_code == 0, result.output
    # a declared plugin loads only when a mission names one of its components
    lazy = "ata.components" in broken
    assert flat(result.output).count(f"warning: {broken}") == (0 if lazy else 1)
    assert (out / "results.csv").exists()


def test_a_mission_naming_its_component_fails_with_that_line(broken, cli, tmp_path):
    mission = tmp_path / "m.toml"
    mission.write_text('[mission]\nscenarios = 2\n\n[components]\ninitial = "mine"\n',
                       encoding="utf-8")
    result = cli("check", mission)
    assert result.exit_code == 2, result.output
    assert "Traceback" not in result.output
    error = [line for line in result.output.splitlines() if line.startswith("error:")]
    assert len(error) == 1 and broken in error[0], result.output
    assert error[0].startswith(f"error: {mission}: [components] key 'initial': ")


def test_a_broken_plugin_in_the_worker_processes_is_reported_by_the_command_alone(cli,
                                                                                   tmp_path,
                                                                                   monkeypatch):
    group, entry, source, _ = BROKEN["raises"]
    install(tmp_path, monkeypatch, group, entry, source)
    result = cli("run", "builtin:greedy", "--set", "mission.scenarios=4", "--chunk-size", 2,
                 "-w", 2, "-q",
                 "-o", tmp_path / "run")
    assert result.exit_code == 0, result.output
    assert result.output.count("boom in registration") == 1


def test_a_misspelt_hook_still_fails_at_start_up(tmp_path, monkeypatch, cli):
    install(tmp_path, monkeypatch, "ata", "ata_broken = ata_broken",
            "from ata import hookimpl\n\n\n@hookimpl\ndef ata_setpu(sim):\n    pass\n")
    assert_user_error(cli("plugins"), "error: a plugin failed validation: unknown hook "
                                      "'ata_setpu'")
