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
    # declared: the lazily registered components too (the trainers)
    reg = collect_components(get_plugin_manager(optional=OPTIONAL_PLUGINS, entry_points=False),
                             declared=True)
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
    extras = "'.[test,plot,gym,sandbox,tensorboard,ray]'"
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
OUTPUT = re.compile(r"(?:-o|--out|>)\s+(runs/[\w.-]+)")
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


def test_every_relative_link_of_the_docs_points_to_a_file_and_a_heading():
    """Every docs page, README.md and every experiment's README: a link names a file that exists
    and, after `#`, a heading of that file (as GitHub makes a heading's anchor)."""
    pages = [*sorted((ROOT / "docs").glob("*.md")), ROOT / "README.md",
             ROOT / "experiments" / "README.md", *sorted(EXPERIMENTS.glob("*/README.md"))]
    broken = []
    for page in pages:
        for target in re.findall(r"\]\(([^)\s]+)\)", page.read_text(encoding="utf-8")):
            if "://" in target:
                continue
            path, _, anchor = target.partition("#")
            dest = (page.parent / path) if path else page
            where = f"{page.relative_to(ROOT)} -> {target}"
            if not dest.exists():
                broken.append(f"{where}: no such file")
            elif anchor and dest.suffix == ".md" and anchor not in _anchors(dest):
                broken.append(f"{where}: no such heading")
    assert not broken, "\n".join(broken)


def _anchors(page: Path) -> set[str]:
    """The anchors of a markdown file's headings, as GitHub makes them."""
    out, fenced = set(), False
    for line in page.read_text(encoding="utf-8").splitlines():
        if line.lstrip().startswith("```"):
            fenced = not fenced
        elif not fenced and line.startswith("#"):
            title = re.sub(r"[^a-z0-9 _-]", "", line.lstrip("#").strip().lower())
            out.add(title.replace(" ", "-"))
    return out


# -- the docs describe the product as it is ------------------------------------------------------
PAGE_LINES = 400
"""The most lines a docs page holds: a longer one serves two readers and is split."""
COMMIT = re.compile(r"\b(?=[0-9a-f]*[0-9])(?=[0-9a-f]*[a-f])[0-9a-f]{7,40}\b")
"""A commit hash: a word of 7 to 40 hex digits with both a digit and a letter."""


@pytest.mark.parametrize("page", sorted((ROOT / "docs").glob("*.md")), ids=lambda p: p.name)
def test_every_docs_page_is_at_most_400_lines(page):
    lines = len(page.read_text(encoding="utf-8").splitlines())
    assert lines <= PAGE_LINES, (f"docs/{page.name} has {lines} lines: split it where it serves "
                                 f"two readers (at most {PAGE_LINES} a page)")


def _text_files() -> list[Path]:
    """The docs, the README, the experiments' READMEs and suites, the tests, the benchmarks and
    the examples: every text a reader or a test reads, but the tests' data."""
    files = [*(ROOT / "docs").glob("*.md"), ROOT / "README.md", *EXPERIMENTS.rglob("*.md"),
             *EXPERIMENTS.rglob("*.toml"), *(ROOT / "benchmarks").rglob("*.py")]
    files += [p for p in (ROOT / "tests").rglob("*.py") if "data" not in p.parts]
    files += [p for p in (ROOT / "examples").rglob("*")
              if p.suffix in (".py", ".md", ".toml") and "egg-info" not in str(p)]
    return sorted(p for p in files if "__pycache__" not in p.parts)


def test_no_commit_hash_outside_the_provenance_lines():
    """History lives in git: no docs page, test, benchmark or example names a commit. The one
    exception is the provenance line of docs/RESULTS.md and of each experiment's README, which
    says which code made the rows: at most one line of such a file may name commits."""
    provenance = {ROOT / "docs" / "RESULTS.md", *EXPERIMENTS.glob("*/README.md")}
    found = []
    for path in _text_files():
        hits = [f"{path.relative_to(ROOT)}:{i}: {line.strip()}"
                for i, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1)
                if COMMIT.search(line)]
        if path in provenance and len(hits) <= 1 and all("commit" in h for h in hits):
            continue
        found += hits
    assert not found, "commit hashes outside a provenance line:\n" + "\n".join(found)


def test_the_hash_pattern_finds_hashes_and_nothing_else():
    short, full = "d34e" + "1de", "5e84" + "457a0b"          # split, so that this file holds none
    assert COMMIT.search(f"made at commit {short}.") and COMMIT.search(f"git show {full}:x")
    for text in ("1234567", "deadbeef", "0x9e3779b97f4a7c15", "e85c", "a" * 41 + "1"):
        assert not COMMIT.search(text), text
