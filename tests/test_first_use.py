"""What a newcomer meets first: pictures in the default install, help that reads as sentences at
80 columns, a changed team size named a custom team, and plugin docs whose examples run."""

from __future__ import annotations

import re
import subprocess
import sys
import tomllib
from importlib import metadata
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from ata import hookimpl
from ata.cli import app
from ata.core.state import Allocation
from ata.session import BASELINE_MISSION
from ata.plugins import humans, robots, tasks
from ata.testing import check_component

ROOT = Path(__file__).resolve().parent.parent
PLUGINS_DOC = (ROOT / "docs" / "plugins.md").read_text(encoding="utf-8")
PLUGIN_PAGES = PLUGINS_DOC + "".join((ROOT / "docs" / name).read_text(encoding="utf-8")
                                     for name in ("hooks.md", "decisions.md"))
"""The guide and the hook reference of a plugin author."""


def at_80(*args: str):
    return CliRunner(env={"COLUMNS": "80"}).invoke(app, [str(a) for a in args])


# --- matplotlib in the default install -----------------------------------------------------------

def test_matplotlib_is_a_dependency_of_the_default_install():
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    assert "matplotlib>=3.7" in project["dependencies"]
    assert project["optional-dependencies"]["plot"] == []      # kept: old commands still work
    # what pip installed: matplotlib required without an extra
    assert any(r.startswith("matplotlib") and "extra" not in r
               for r in metadata.requires("ata"))
    readme = (ROOT / "README.md").read_text()
    assert "pip install -e . && ata run" in readme and "ata show" in readme


# --- help texts ----------------------------------------------------------------------------------

def early_breaks(text: str, width: int = 80) -> list[tuple[str, str]]:
    """(line, next word) where a help paragraph breaks although the next word would have fit:
    in the description after "Usage:" and in the commands panel."""
    lines = text.splitlines()
    start = next(i for i, line in enumerate(lines) if "Usage:" in line) + 1
    body = []
    for line in lines[start:]:
        if line.lstrip().startswith("╭"):
            break
        body.append(line.rstrip())
    found = [(a.strip(), b.split()[0]) for a, b in zip(body, body[1:])
             if a.strip() and b.strip() and len(a) + 1 + len(b.split()[0]) <= width - 1]
    if "╭─ Commands" in text:
        panel = text.split("╭─ Commands", 1)[1].split("╰", 1)[0].splitlines()[1:]
        inner = [line[1:-1] for line in panel]
        text_column = re.match(r" \S+\s+", inner[0]).end()
        for a, b in zip(inner, inner[1:]):
            if not b[:text_column].strip() and \
                    len(a.rstrip()) + 1 + len(b.split()[0]) <= len(inner[0]) - 1:
                found.append((a.strip(), b.split()[0]))
    return found


@pytest.mark.parametrize("command", ["", "run", "train", "check", "plugins", "eval", "report",
                                     "show"])
def test_help_paragraphs_break_only_where_a_line_is_full(command):
    result = at_80(*([command] if command else []), "--help")
    assert result.exit_code == 0, result.output
    assert early_breaks(result.output) == []
    assert max(len(line) for line in result.output.splitlines()) <= 80


# --- a team size other than the setting's --------------------------------------------------------

def test_a_size_other_than_the_settings_makes_a_custom_team(tmp_path):
    out = tmp_path / "run"
    result = at_80("run", BASELINE_MISSION, "--set", "mission.humans=4", "--set",
                   "mission.scenarios=2", "--set", "mission.horizon_s=300", "-q", "--out", out)
    assert result.exit_code == 0, result.output
    assert "team               setting custom: 4 humans, 8 robots, 60 POIs" in result.output
    resolved = tomllib.loads((out / "mission.resolved.toml").read_text())["mission"]
    assert [resolved[k] for k in ("setting", "humans", "robots", "tasks")] == \
        ["custom", 4, 8, 60]
    # the resolved mission reads back as the same team
    check = at_80("check", out / "mission.resolved.toml")
    assert check.exit_code == 0, check.output
    assert "setting custom (4 humans, 8 robots, 60 POIs)" in " ".join(check.output.split())


@pytest.mark.parametrize("overrides, expected", [
    (["mission.humans=6", "mission.tasks=60"], "setting a (6 humans, 8 robots, 60 POIs)"),
    (["mission.setting='b'", "mission.robots=16"], "setting b (12 humans, 16 robots, 130 POIs)"),
    (["mission.setting='b'", "mission.robots=8"], "setting custom (12 humans, 8 robots, 130 "
                                                  "POIs)"),
])
def test_the_settings_own_sizes_keep_its_name(overrides, expected):
    result = at_80("check", BASELINE_MISSION, *[x for o in overrides for x in ("--set", o)])
    assert result.exit_code == 0, result.output
    assert expected in " ".join(result.output.split())


# --- docs/plugins.md, hooks.md, decisions.md -----------------------------------------------------

def code_block(doc: str, holding: str) -> str:
    """The one ```python block of `doc` that holds `holding`."""
    blocks = [b for b in re.findall(r"```python\n(.*?)```", doc, flags=re.S) if holding in b]
    assert len(blocks) == 1, holding
    return blocks[0]


@pytest.mark.parametrize("kind, name", [("policy", "RoundRobin"),
                                        ("condition", "EveryFifthEpoch")])
def test_the_decision_examples_pass_the_check_as_written(kind, name):
    namespace: dict = {"np": np, "hookimpl": hookimpl, "Allocation": Allocation}
    exec(code_block(PLUGIN_PAGES, f"class {name}"), namespace)
    check_component(kind, namespace[name])


def test_every_shared_column_is_defined():
    # the bullets after the paragraph that says "What each column holds"
    section = PLUGIN_PAGES.split("What each column holds", 1)[1].split("\n\n")[1]
    items = re.split(r"^\* ", section, flags=re.M)[1:]
    defined = {}
    for item in items:
        group, part = re.match(r"`(\w+)` ([IS]):", item).groups()
        defined[(group, part)] = " ".join(item.split())
    columns = {("humans", "I"): humans.HUMAN_INHERENT, ("humans", "S"): humans.HUMAN_STATE,
               ("robots", "I"): robots.ROBOT_INHERENT, ("robots", "S"): robots.ROBOT_STATE,
               ("tasks", "I"): tasks.TASK_INHERENT, ("tasks", "S"): tasks.TASK_STATE}
    assert set(defined) == set(columns)
    for key, names in columns.items():
        for name in names:
            assert f"`{name}`" in defined[key], (key, name)
    assert "`working` 1 while the robot has not failed, 0 from its failure on" in \
        defined[("robots", "S")]


def test_the_working_column_is_one_until_the_robot_fails():
    from ata.session import load_session
    from ata.core.kernel import Simulation
    session = load_session(str(BASELINE_MISSION), [
        "mission.uncertainty='custom'", "mission.fatigue_variance=0.0",
        "mission.event_probability=1.0", "components.injectors=[]",
        "components.perturbations=['robot_failure']"])
    sim = Simulation(session.mission, session.registry, np.arange(2))
    sim.reset()
    fail_time = sim.sim.group("robots").fail_time
    for _ in range(session.mission.clock.n_epochs):
        sim.step_epoch()
        working = sim.last_truth["robots"].col("working")
        assert np.array_equal(working, (fail_time > sim.last_context.time).astype(float))
    assert (fail_time < session.mission.settings.horizon_s).any()


def test_check_component_docs_say_pytest_is_not_in_the_run_install():
    section = PLUGINS_DOC.split("## Checking a component", 1)[1].split("\n## ", 1)[0]
    assert "written for pytest, which the run install\n(`pip install -e .`) does not bring: " \
           "`pip install pytest`" in section
    assert "A\nplain script works without it: `check_component(...)` returns None or raises." \
        in section


SHADOWED = "ImportError: cannot import name 'hookimpl' from 'ata' (unknown location)"


def test_a_folder_named_ata_shadows_the_package_as_the_docs_say(tmp_path):
    """Python run from a folder holding a checkout named ata imports that folder: the docs
    quote the message it gives."""
    (tmp_path / "ata" / "ata").mkdir(parents=True)
    (tmp_path / "ata" / "pyproject.toml").write_text("")
    proc = subprocess.run([sys.executable, "-c", "from ata import hookimpl"], cwd=tmp_path,
                          capture_output=True, text=True)
    trouble = PLUGINS_DOC.split("## Troubleshooting", 1)[1]
    assert f"**`{SHADOWED}`**" in trouble
    assert "named `ata`: that folder would shadow the package" in \
        (ROOT / "README.md").read_text()
    if proc.returncode == 0:
        pytest.skip("this install puts the package before the current folder on the path")
    assert proc.stderr.strip().splitlines()[-1] == SHADOWED
