"""The docs match the code: every mission key is documented, README commands are current."""

import re
from pathlib import Path

import pytest

from ata.core.mission import ComponentSlots, MissionSettings, loads_toml
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
    extras = "'.[test,plot,gym,sandbox,tensorboard]'"
    assert extras in readme and extras in ci


def test_example_missions_validate():
    from ata.experiment.evaluate import plan
    from ata.core.mission import read_toml
    from ata.session import load_session
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


# -- experiments/: every published number has a folder with its commands ------------------------
EXPERIMENTS = ROOT / "experiments"
OUTPUT = re.compile(r"(?:-o|--out)\s+(runs/[\w.-]+)")
RUNS_PATH = re.compile(r"(?<![\w/.-])(runs/[\w.-]+)")


def _experiment_folders() -> list[Path]:
    return sorted(p for p in EXPERIMENTS.iterdir() if p.is_dir())


def _commands(text: str) -> list[str]:
    return [line.strip() for line in text.splitlines() if line.strip().startswith("ata ")]


def _outputs(text: str) -> set[str]:
    return set(OUTPUT.findall(text))


def _suite_body(path: Path) -> str:
    """The suite without its comments: what `ata eval` reads."""
    return "\n".join(line.split("#", 1)[0] for line in path.read_text().splitlines())


@pytest.mark.parametrize("folder", _experiment_folders(), ids=lambda p: p.name)
def test_every_experiment_names_the_commands_that_make_and_read_it(folder):
    readme = (folder / "README.md").read_text()
    commands = _commands(readme)
    makes = [c for c in commands if c.startswith(("ata eval ", "ata train "))]
    reads = [c for c in commands if c.startswith(("ata report ", "ata compare "))]
    assert any(c.startswith("ata eval ") for c in makes), f"{folder.name}: no `ata eval` command"
    assert reads, f"{folder.name}: no `ata report` or `ata compare` command"
    assert "## What it produced" in readme, f"{folder.name}: README lacks what it produced"
    named = {tok for c in makes for tok in c.split() if tok.endswith(".toml")}
    for suite in named:
        assert (ROOT / suite).is_file(), f"{folder.name}: {suite} does not exist"
    # a mission file of the folder is run by a command or named by a suite one runs
    missions = {str((ROOT / suite).parent.joinpath(m["mission"]).resolve().relative_to(ROOT))
                for suite in named for m in loads_toml((ROOT / suite).read_text()).get(
                    "method", []) if not m["mission"].startswith(("builtin:", "published:"))}
    for suite in folder.glob("*.toml"):
        assert str(suite.relative_to(ROOT)) in named | missions, \
            f"{suite.name} is run by no command"


@pytest.mark.parametrize("folder", _experiment_folders(), ids=lambda p: p.name)
def test_an_experiment_reads_no_path_it_does_not_write(folder):
    """A run folder an experiment reads (a checkpoint, an evaluation) is one its own commands
    write with -o; nothing else outside the repository."""
    readme = (folder / "README.md").read_text()
    written = _outputs(readme)
    read = set(RUNS_PATH.findall(readme))
    for suite in folder.glob("*.toml"):
        read |= set(RUNS_PATH.findall(_suite_body(suite)))
    assert read <= written, f"{folder.name} reads {sorted(read - written)}, which it never writes"


def test_every_experiment_suite_loads():
    from ata.experiment.evaluate import plan
    suites = sorted(EXPERIMENTS.glob("*/*.toml"))
    assert suites
    for path in suites:
        # a suite that reads checkpoints its experiment trains is read, not built
        needs_runs = bool(RUNS_PATH.search(_suite_body(path)))
        _, jobs = plan([str(path)], validate=not needs_runs)
        assert jobs, path


def test_the_results_and_findings_read_only_what_an_experiment_writes():
    written = set().union(*(_outputs((f / "README.md").read_text())
                            for f in _experiment_folders()))
    for doc in ("RESULTS.md", "findings.md"):
        read = set(RUNS_PATH.findall((ROOT / "docs" / doc).read_text()))
        assert read <= written, f"docs/{doc} names {sorted(read - written)}"


LINK = re.compile(r"\]\(([^)#\s]+)(?:#[^)]*)?\)")


@pytest.mark.parametrize("doc", ["README.md", "docs/RESULTS.md", "docs/findings.md",
                                 "docs/architecture.md", "experiments/README.md",
                                 *[str(p.relative_to(ROOT)) for p in
                                   sorted(EXPERIMENTS.glob("*/README.md"))]])
def test_relative_links_point_to_files(doc):
    path = ROOT / doc
    for target in LINK.findall(path.read_text()):
        if "://" in target:
            continue
        assert (path.parent / target).exists(), f"{doc} links to {target}, which does not exist"
