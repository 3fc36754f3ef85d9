"""`--isolate` with a method from an installed package: the world's process never imports it.

The package here is installed the way pip leaves one (a package folder and a .dist-info record
with its entry points, on sys.path); its import-time code records where it ran. Its settings are
validated in the sandboxed process, the host records them, and the rows are those of the same
method run in-process."""

from __future__ import annotations

import hashlib
import os
import sys
import uuid
from pathlib import Path

import numpy as np
import pytest

from ata.core.errors import MissionError
from ata.isolation import require_sandbox
from ata.isolation import process as isolate
from ata.session import load_session
from ata.experiment.units import Unit, run_batch, run_unit, one_thread
from ata.runtime import sandbox

NO_SANDBOX = sandbox.unavailable()
pytestmark = pytest.mark.skipif(NO_SANDBOX is not None, reason=f"needs a sandbox: {NO_SANDBOX}")
SHORT = ["mission.scenarios=3", "mission.batch_size=3", "mission.horizon_s=600"]

PLUGIN = '''
import hashlib
import os
os.environ["{marker}"] = "imported in process %d" % os.getpid()

from dataclasses import dataclass

from ata import hookimpl
from ata.core.settings import param
from ata.plugins.policies.greedy import GreedyPolicy


@dataclass
class Settings:
    shift: int = param(0, min=0, help="unused: a setting to validate")


class Rotated(GreedyPolicy):
    Settings = Settings

    def __init__(self, settings, mission):
        super().__init__(GreedyPolicy.Settings(), mission)
        self.shift = settings.shift


class Noise:
    """An injector (a world component) this package does not declare."""

    @hookimpl
    def ata_inject(self, sim):
        pass


@hookimpl
def ata_register_components(register):
    register("policy", "{name}", Rotated)
    register("injector", "{name}_noise", Noise)
'''


@pytest.fixture
def installed(tmp_path, monkeypatch):
    """A package installed under a fresh name (so no earlier test imported it): its module
    name, the policy's name and the environment variable its import sets."""
    module = f"ata_installed_{uuid.uuid4().hex[:8]}"
    name, marker = f"rotated_{module[-8:]}", f"ATA_TEST_{module.upper()}"
    site = tmp_path / "site"
    (site / module).mkdir(parents=True)
    (site / module / "__init__.py").write_text(PLUGIN.format(marker=marker, name=name))
    info = site / f"{module}-0.1.dist-info"
    info.mkdir()
    (info / "METADATA").write_text(f"Metadata-Version: 2.1\nName: {module}\nVersion: 0.1\n")
    (info / "entry_points.txt").write_text(f"[ata]\n{module} = {module}\n")
    monkeypatch.syspath_prepend(str(site))
    monkeypatch.delenv(marker, raising=False)
    yield module, name, marker
    sys.modules.pop(module, None)


def test_the_host_never_imports_an_installed_method(installed):
    module, name, marker = installed
    iso = require_sandbox(60)
    over = [*SHORT, f"components.initial='{name}'", f"{name}.shift=2"]
    session = load_session("builtin:greedy", over, backend=iso)
    # its settings were validated apart, and the host records them as any component's
    assert f"[{name}]\nshift = 2" in session.mission.to_toml()
    assert session.registry.get("policy", name, "").dist == f"{module} 0.1"
    with one_thread():
        apart = run_batch(session.mission, session.registry, np.arange(3), backend=iso)
        # a worker process stands the method in the same way, importing none of it
        unit = run_unit(Unit(0, session.mission, np.arange(3), parallel=True, backend=iso))
    assert module not in sys.modules and marker not in os.environ
    inside_session = load_session("builtin:greedy", over)
    assert module in sys.modules and marker in os.environ    # the check above can fail
    with one_thread():
        inside = run_batch(inside_session.mission, inside_session.registry, np.arange(3))
    skip = ("warnings", "wall_s", f"m:{isolate.TIMEOUT_COLUMN}")
    keys = sorted(k for k in inside if k not in skip)
    assert "scenario" in keys and sorted(k for k in apart if k not in skip) == keys
    for key in keys:
        np.testing.assert_array_equal(np.asarray(inside[key]), np.asarray(apart[key]), key)
        np.testing.assert_array_equal(np.asarray(unit[key]), np.asarray(apart[key]), key)


def test_a_bad_setting_of_an_installed_method_is_named_from_the_sandbox(installed):
    module, name, marker = installed
    iso = require_sandbox(60)
    with pytest.raises(MissionError, match=rf"\[{name}\].*nope.*unknown key"):
        load_session("builtin:greedy", [*SHORT, f"components.initial='{name}'",
                                        f"{name}.nope=1"], backend=iso)
    assert module not in sys.modules and marker not in os.environ


def test_a_built_in_method_beside_an_installed_package_never_imports_it(installed):
    module, name, marker = installed
    iso = require_sandbox(60)
    session = load_session("builtin:greedy", SHORT, backend=iso)
    with one_thread():
        run_unit(Unit(0, session.mission, np.arange(3), parallel=True, backend=iso))
    assert module not in sys.modules and marker not in os.environ


def test_an_undeclared_world_component_is_found_and_loaded_as_the_world(installed):
    module, name, marker = installed
    iso = require_sandbox(60)
    session = load_session("builtin:greedy", [*SHORT, f"components.injectors=['{name}_noise']"],
                           backend=iso)
    # the world's code runs in the world's process: found by importing each package alone in
    # a sandbox, then loaded here
    assert session.registry.get("injector", f"{name}_noise", "").dist == f"{module} 0.1"
    assert module in sys.modules


def test_a_method_whose_package_also_gives_the_world_is_refused(installed):
    module, name, marker = installed
    iso = require_sandbox(60)
    with pytest.raises(MissionError, match=rf"cannot keep policy '{name}' apart"):
        load_session("builtin:greedy", [*SHORT, f"components.injectors=['{name}_noise']",
                                        f"components.initial='{name}'"], backend=iso)
    with pytest.raises(MissionError, match=r"no installed package provides it.*ata\.components"):
        load_session("builtin:greedy", [*SHORT, "components.injectors=['nowhere_noise']"],
                     backend=iso)


# -- a method in a file of its own, named by reference ---------------------------------------------
EXAMPLE = Path(__file__).resolve().parent.parent / "examples" / "policies"


def test_a_method_in_a_file_runs_apart_and_the_host_never_loads_it(tmp_path, monkeypatch):
    marker = f"ATA_TEST_FILE_{uuid.uuid4().hex[:8].upper()}"
    monkeypatch.delenv(marker, raising=False)
    code = (EXAMPLE / "nearest_capable.py").read_text()
    policy = tmp_path / "nearest_capable.py"
    policy.write_text(f'import os\nos.environ["{marker}"] = "loaded"\n' + code)
    mission = tmp_path / "mine.toml"
    mission.write_text((EXAMPLE / "nearest_capable.toml").read_text())
    iso = require_sandbox(60)
    loaded = set(sys.modules)
    session = load_session(str(mission), SHORT + ["nearest_capable.any_type=true"], backend=iso)
    resolved = session.mission.to_toml()
    assert 'initial = "nearest_capable"' in resolved and "any_type = true" in resolved
    assert f'source = "{policy.resolve()}:NearestCapable"' in resolved
    digest = hashlib.sha256(policy.read_bytes()).hexdigest()
    assert f'sha256 = "{digest}"' in resolved
    assert session.code()["policy nearest_capable"] == digest
    with one_thread():
        apart = run_batch(session.mission, session.registry, np.arange(3), backend=iso)
        unit = run_unit(Unit(0, session.mission, np.arange(3), parallel=True, backend=iso))
    assert marker not in os.environ
    assert not [m for m in set(sys.modules) - loaded if "nearest_capable" in m]
    # the resolved mission runs apart again, and refuses the file once it has changed
    again = tmp_path / "resolved.toml"
    again.write_text(resolved)
    assert load_session(str(again), backend=iso).mission.to_toml() == resolved
    inside_session = load_session(str(mission), SHORT + ["nearest_capable.any_type=true"])
    assert marker in os.environ                     # the check above can fail
    with one_thread():
        inside = run_batch(inside_session.mission, inside_session.registry, np.arange(3))
    skip = ("warnings", "wall_s", f"m:{isolate.TIMEOUT_COLUMN}")
    for key in (k for k in inside if k not in skip):
        np.testing.assert_array_equal(np.asarray(inside[key]), np.asarray(apart[key]), key)
        np.testing.assert_array_equal(np.asarray(unit[key]), np.asarray(apart[key]), key)
    policy.write_text(policy.read_text() + "\n# edited\n")
    with pytest.raises(MissionError, match="has changed since this mission was resolved"):
        load_session(str(again), backend=iso)
