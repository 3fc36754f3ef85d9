"""A third-party plugin package found through its `ata` entry point, and a misspelt hook caught at
start-up. The example package in examples/third_party_plugin is registered here without pip:
a dist-info folder on sys.path declares its entry point, as an installed package's would."""

from __future__ import annotations

import importlib
import sys
import tomllib
import types
from pathlib import Path

import numpy as np
import pluggy
import pytest

from ata import hookimpl
from ata.session import load_session
from ata.core.kernel import Simulation
from ata.core.registry import collect_components, get_plugin_manager, plugin_version

EXAMPLE = Path(__file__).resolve().parent.parent / "examples" / "third_party_plugin"


def fake_install(site: Path, monkeypatch, dist: str, module: str) -> None:
    """Make `module` an entry point of the `ata` group of distribution `dist` 0.1.0."""
    info = site / f"{dist.replace('-', '_')}-0.1.0.dist-info"
    info.mkdir()
    (info / "METADATA").write_text(f"Metadata-Version: 2.1\nName: {dist}\nVersion: 0.1.0\n")
    (info / "entry_points.txt").write_text(f"[ata]\n{module} = {module}\n")
    monkeypatch.syspath_prepend(str(site))
    monkeypatch.delitem(sys.modules, module, raising=False)
    importlib.invalidate_caches()


@pytest.fixture
def dropout(tmp_path, monkeypatch):
    """The example package, findable through its entry point; its module name."""
    site = tmp_path / "site"
    site.mkdir()
    monkeypatch.syspath_prepend(str(EXAMPLE))
    fake_install(site, monkeypatch, "ata-dropout", "ata_dropout")
    return "ata_dropout"


def write_mission(path: Path, probability: float, fill: float = 0.25,
                  injectors: str = '"sensor_dropout"') -> Path:
    path.write_text(f"""\
[mission]
name = "dropout"
setting = "custom"
humans = 4
robots = 4
tasks = 12
scenarios = 4
batch_size = 4
horizon_s = 300.0

[components]
injectors = [{injectors}]
condition = "never"

[sensor_dropout]
probability = {probability}
fill = {fill}
""", encoding="utf-8")
    return path


# --- the entry point -----------------------------------------------------------------------------

def test_entry_point_plugin_is_loaded(dropout):
    pm = get_plugin_manager()
    plugin = pm.get_plugin(dropout)
    assert isinstance(plugin, types.ModuleType)
    assert Path(plugin.__file__).parent == EXAMPLE / "ata_dropout"
    assert plugin_version(pm, plugin) == "ata-dropout 0.1.0"

    info = collect_components(pm).get("injector", "sensor_dropout", "test")
    assert (info.plugin, info.dist) == ("ata_dropout", "ata-dropout 0.1.0")
    assert info.factory is plugin.SensorDropout


def test_without_entry_points_it_is_not_loaded(dropout):
    pm = get_plugin_manager(entry_points=False)
    assert pm.get_plugin(dropout) is None
    assert ("injector", "sensor_dropout") not in collect_components(pm).components


def test_cli_plugins_lists_it_with_its_version(dropout, cli):
    result = cli("plugins")
    assert result.exit_code == 0, result.output
    row = next(line for line in result.output.splitlines() if " ata_dropout " in line)
    assert row.split() == ["sensor_dropout", "injector", "ata_dropout", "ata-dropout", "0.1.0"]

    verbose = " ".join(cli("plugins", "--verbose").output.split())
    assert "[sensor_dropout] injector, from ata_dropout; hooks: ata_inject" in verbose
    assert "probability = 0.2 (a number, 0.0 to 1.0)" in verbose


# --- the injector --------------------------------------------------------------------------------

def run_epochs(mission_path: Path, n: int):
    """(truth, observed) of the first n epochs of the mission's batch."""
    session = load_session(str(mission_path))
    sim = Simulation(session.mission, session.registry, np.arange(4))
    sim.reset()
    seen = []
    for _ in range(n):
        sim.step_epoch()
        seen.append((sim.last_truth, sim.last_context.observed))
    return seen


def test_sensor_dropout_replaces_lost_fatigue_readings(dropout, tmp_path):
    seen = run_epochs(write_mission(tmp_path / "m.toml", probability=0.5, fill=0.25), 3)
    lost_all = []
    for truth, observed in seen:
        lost = observed.extras["fatigue_dropout"]
        assert lost.shape == (4, 4) and lost.dtype == bool
        true_f, seen_f = truth["humans"].col("fatigue"), observed["humans"].col("fatigue")
        assert np.all(seen_f[lost] == 0.25)
        assert np.array_equal(seen_f[~lost], true_f[~lost])
        assert np.all(true_f >= 0.4)                   # the truth is untouched (F_f >= floor)
        # only the fatigue column changes, and no human leaves the observation
        others = [i for i, n in enumerate(observed["humans"].names) if n != "fatigue"]
        assert np.array_equal(observed["humans"].features[..., others],
                              truth["humans"].features[..., others])
        assert observed["humans"].mask.all()
        lost_all.append(lost)
    share = np.mean(lost_all)
    assert 0.3 < share < 0.7                           # 48 draws at p = 0.5
    assert not np.array_equal(lost_all[0], lost_all[1])   # fresh draws every epoch


def test_sensor_dropout_probability_zero_changes_nothing(dropout, tmp_path):
    for truth, observed in run_epochs(write_mission(tmp_path / "m.toml", probability=0.0), 2):
        assert not observed.extras["fatigue_dropout"].any()
        assert np.array_equal(observed["humans"].features, truth["humans"].features)


def test_mission_with_sensor_dropout_runs_from_the_cli(dropout, tmp_path, cli):
    path = write_mission(tmp_path / "m.toml", probability=1.0,
                         injectors='"fatigue_noise", "latency", "sensor_dropout"')
    out = tmp_path / "run"
    result = cli("run", path, "--out", out, "-q")
    assert result.exit_code == 0, result.output
    versions = tomllib.loads((out / "plugins.toml").read_text())
    assert versions["components"]["injector sensor_dropout"] == "ata-dropout 0.1.0"
    resolved = tomllib.loads((out / "mission.resolved.toml").read_text())
    assert resolved["components"]["injectors"] == ["fatigue_noise", "latency", "sensor_dropout"]
    assert resolved["sensor_dropout"] == {"probability": 1.0, "fill": 0.25}
    # at probability 1 every reading is lost, after the noise: the observed fatigue is the fill
    _, observed = run_epochs(path, 1)[0]
    assert np.all(observed["humans"].col("fatigue") == 0.25)


def test_sensor_dropout_settings_are_validated(dropout, tmp_path, cli):
    path = write_mission(tmp_path / "m.toml", probability=1.5)
    result = cli("check", path)
    assert result.exit_code == 2
    assert (f"{path}: [sensor_dropout] key 'probability': 1.5 is above the maximum; "
            "allowed: 0.0 to 1.0") in " ".join(result.output.split())


def test_example_mission_checks(dropout, cli):
    result = cli("check", EXAMPLE / "dropout_mission.toml")
    assert result.exit_code == 0, result.output
    assert "ok:" in result.output


# --- a misspelt hook fails at start-up -----------------------------------------------------------

def misspelt_plugin() -> types.ModuleType:
    module = types.ModuleType("misspelt")

    @hookimpl
    def ata_setpu(sim):
        pass

    module.ata_setpu = ata_setpu
    return module


def test_misspelt_hook_name_fails_at_start_up():
    with pytest.raises(pluggy.PluginValidationError,
                       match=r"unknown hook 'ata_setpu' .*did you mean 'ata_setup'\?"):
        get_plugin_manager(entry_points=False, extra=[misspelt_plugin()])


def test_misspelt_hook_in_an_installed_plugin_exits_2(tmp_path, monkeypatch, cli):
    site = tmp_path / "site"
    site.mkdir()
    (site / "ata_misspelt.py").write_text(
        "from ata import hookimpl\n\n\n@hookimpl\ndef ata_setpu(sim):\n    pass\n")
    fake_install(site, monkeypatch, "ata-misspelt", "ata_misspelt")
    with pytest.raises(pluggy.PluginValidationError):
        get_plugin_manager()
    for args in (["plugins"], ["run", "--set", "mission.scenarios=1", "-q"]):
        result = cli(*args)
        assert result.exit_code == 2, result.output
        assert result.exception is None or isinstance(result.exception, SystemExit)
        assert "Traceback" not in result.output
        text = " ".join(result.output.split())
        assert text.startswith("error: a plugin failed validation: unknown hook 'ata_setpu' in "
                               "plugin <module 'ata_misspelt'")
        assert "did you mean 'ata_setup'?" in text


# --- a component that breaks the kernel's contract: one message naming it, exit 2 ---------------

BROKEN_POLICY = '''\
import numpy as np

from ata import hookimpl
from ata.core.state import Allocation


class Transposed:
    """Returns (POIs, scenarios) instead of (scenarios, POIs)."""

    def __init__(self, settings, mission):
        pass

    @hookimpl
    def ata_initial_allocation(self, ctx):
        B, P = ctx.reallocatable.shape
        zeros = np.zeros((P, B), dtype=np.int64)
        return Allocation(zeros, zeros - 1, zeros - 1)


@hookimpl
def ata_register_components(register):
    register("policy", "transposed", Transposed)
'''


@pytest.mark.parametrize("workers", ["1", "2"])
def test_a_policy_of_the_wrong_shape_exits_2_with_one_message(tmp_path, monkeypatch, cli,
                                                              workers):
    site = tmp_path / "site"
    site.mkdir()
    (site / "ata_transposed.py").write_text(BROKEN_POLICY)
    fake_install(site, monkeypatch, "ata-transposed", "ata_transposed")
    monkeypatch.setenv("PYTHONPATH", str(site))   # for the worker processes
    mission = tmp_path / "m.toml"
    mission.write_text('[mission]\nscenarios = 4\nbatch_size = 2\n\n[components]\n'
                       'initial = "transposed"\ncondition = "never"\nreallocation = "greedy"\n')
    result = cli("run", mission, "-q", "--workers", workers, "--out", tmp_path / "out")
    assert result.exit_code == 2, result.output
    assert "Traceback" not in result.output
    lines = [ln for ln in result.output.splitlines() if ln.strip()]
    assert len(lines) == 1, result.output
    assert lines[0] == ("error: a component broke the kernel's contract: initial policy "
                        "'transposed': robot has shape (60, 2), expected (2, 60) (scenarios, "
                        "POIs)")
