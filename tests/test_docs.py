"""The docs match the code: every mission key is documented, README commands are current."""

import re
from pathlib import Path

import pytest

from ata.core.mission import ComponentSlots, MissionSettings
from ata.core.registry import OPTIONAL_PLUGINS, collect_components, get_plugin_manager
from ata.core.settings import describe

ROOT = Path(__file__).resolve().parent.parent
MISSIONS_DOC = (ROOT / "docs" / "missions.md").read_text()


def _tables():
    reg = collect_components(get_plugin_manager(optional=OPTIONAL_PLUGINS, entry_points=False))
    yield "mission", MissionSettings
    yield "components", ComponentSlots
    for info in reg.components.values():
        yield info.name, getattr(info.factory, "Settings", None)


@pytest.mark.parametrize("table, cls", list(_tables()), ids=lambda x: str(getattr(x, "__name__", x)))
def test_every_key_is_documented(table, cls):
    match = re.search(rf"^#+ `\[{table}\]`.*$", MISSIONS_DOC, flags=re.M)
    assert match, f"docs/missions.md lacks a section for [{table}]"
    section = MISSIONS_DOC[match.end():].split("\n#", 1)[0]
    keys = [row[0] for row in describe(cls)] if cls is not None else []
    for key in keys:
        assert f"| `{key}` |" in section, f"[{table}] key {key!r} is not in docs/missions.md"
    documented = re.findall(r"^\| `([a-z_0-9]+)` \|", section, flags=re.M)
    assert sorted(documented) == sorted(keys), "docs/missions.md lists keys the code lacks"


def test_readme_commands_match_ci():
    readme = (ROOT / "README.md").read_text()
    ci = (ROOT / ".ci" / "run").read_text()
    assert "pip install torch==2.13.0" in readme and "torch==2.13.0" in ci
    test_cmd = "python -m pytest -q -n 2"
    assert test_cmd in readme and test_cmd in ci
    assert "'.[test,plot,gym]'" in readme and "'.[test,plot,gym]'" in ci


def test_example_missions_validate():
    from ata.experiment.evaluate import plan
    from ata.core.mission import read_toml
    from ata.experiment.runner import load_session
    suites = 0
    for path in sorted((ROOT / "examples").rglob("*.toml")):
        if path.name == "pyproject.toml" or "third_party" in str(path):
            continue
        if "suite" in read_toml(str(path)):
            # every job of a suite builds, its checkpoints included (no scenario is run)
            _, jobs = plan([str(path)], validate=True)
            assert jobs
            suites += 1
        else:
            load_session(str(path))
    assert suites >= 1
