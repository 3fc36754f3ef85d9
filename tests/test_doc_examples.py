"""Every ```python block of the docs (docs/*.md, README.md) runs, unless it is marked a fragment.

A block is a fragment when the line before its fence (blank lines aside) is the HTML comment
``<!-- fragment: why -->``: the reason says what the block lacks (a method body shown out of
its class, a call that runs for minutes). Every other block runs.

The blocks of one file run in order in one namespace, so a later block may use what an earlier
one defined (a class, then the check that runs it). Each file runs in a fresh Python process
whose working folder is a fresh temporary one that holds links to the repository's ``examples``,
``experiments``, ``docs`` and ``benchmarks`` folders: a relative path such as
``examples/missions/x.toml`` works as it does from the repository root, and whatever an example
writes (a ``runs/`` folder) lands in the temporary folder. A failure names the doc file and the
line in it.

Beside the examples, the tables of docs/model.md and docs/library.md (P_rc, t_bar, F_d, image
quality, the levels, the team settings, the default constants) are checked against the code's.
"""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
DOCS = sorted((ROOT / "docs").glob("*.md")) + [ROOT / "README.md"]
LINKED = ("examples", "experiments", "docs", "benchmarks")
"""Repository folders the examples may name by a relative path."""
TIMEOUT_S = 120
"""The most one file's blocks may take together."""
NEEDS = {"docs/gym.md": "gymnasium"}
"""Docs whose examples need an optional extra: skipped where it is not installed, as the tests
of that extra are (CI installs every extra)."""

FENCE = re.compile(r"^(\s*)```python[ \t]*$")
FRAGMENT = re.compile(r"^\s*<!--\s*fragment:\s*\S.*-->\s*$")


@dataclass(frozen=True)
class Block:
    """One ```python block: its first code line (1-based) in `path`, its code, and whether it is
    marked a fragment."""

    path: Path
    line: int
    code: str
    fragment: bool


def blocks(path: Path) -> list[Block]:
    """The ```python blocks of a markdown file, in order."""
    lines = path.read_text(encoding="utf-8").splitlines()
    out, i = [], 0
    while i < len(lines):
        match = FENCE.match(lines[i])
        if not match:
            i += 1
            continue
        indent = len(match.group(1))
        before = i - 1
        while before >= 0 and not lines[before].strip():
            before -= 1
        fragment = before >= 0 and bool(FRAGMENT.match(lines[before]))
        start = i + 1
        end = start
        while end < len(lines) and lines[end].strip() != "```":
            end += 1
        if end == len(lines):
            raise AssertionError(f"{path.relative_to(ROOT)}:{i + 1}: a ```python block "
                                 "without its closing fence")
        code = "\n".join(line[indent:] for line in lines[start:end]) + "\n"
        out.append(Block(path, start + 1, code, fragment))
        i = end + 1
    return out


RUNNER = r"""
import json, sys, traceback
blocks = json.loads(sys.stdin.read())
namespace = {"__name__": "__main__"}
for name, line, code in blocks:
    # the code at its own line numbers in the doc file: a traceback names the doc and the line
    try:
        exec(compile("\n" * (line - 1) + code, name, "exec"), namespace)
    except BaseException:
        print(f"FAILED: the block at {name}:{line}", file=sys.stderr)
        traceback.print_exc()
        sys.exit(1)
"""


def _files() -> list[Path]:
    return [p for p in DOCS if any(not b.fragment for b in blocks(p))]


def test_the_collector_finds_the_blocks_and_their_markers(tmp_path):
    doc = tmp_path / "x.md"
    doc.write_text("text\n\n```python\na = 1\n```\n\n<!-- fragment: a method alone -->\n\n"
                   "```python\n    def f(self): ...\n```\n\n  ```python\n  b = a + 1\n  ```\n")
    found = blocks(doc)
    assert [(b.line, b.code, b.fragment) for b in found] == [
        (4, "a = 1\n", False), (10, "    def f(self): ...\n", True), (14, "b = a + 1\n", False)]


def test_every_fragment_marker_has_a_reason_and_a_block():
    # a marker without a reason, or one that no ```python block follows, marks nothing
    for path in DOCS:
        lines = path.read_text(encoding="utf-8").splitlines()
        for i, line in enumerate(lines):
            if not (line.lstrip().startswith("<!--") and "fragment" in line):
                continue
            where = f"{path.relative_to(ROOT)}:{i + 1}"
            assert FRAGMENT.match(line), f"{where}: write the marker <!-- fragment: why -->"
            after = next((x for x in lines[i + 1:] if x.strip()), "")
            assert FENCE.match(after), f"{where}: no ```python block follows the marker"


def test_the_reference_docs_have_examples_that_run():
    for name in ("model.md", "methods.md", "hooks.md", "decisions.md", "api.md",
                 "results-columns.md"):
        assert any(not b.fragment for b in blocks(ROOT / "docs" / name)), name


@pytest.mark.parametrize("doc", _files(), ids=lambda p: str(p.relative_to(ROOT)))
def test_the_python_blocks_of_the_doc_run(doc, tmp_path):
    needs = NEEDS.get(str(doc.relative_to(ROOT)))
    if needs:
        pytest.importorskip(needs)
    for name in LINKED:
        if (ROOT / name).is_dir():
            os.symlink(ROOT / name, tmp_path / name)
    runnable = [(str(b.path.relative_to(ROOT)), b.line, b.code) for b in blocks(doc)
                if not b.fragment]
    env = dict(os.environ, MPLBACKEND="Agg", PYTHONPATH=str(ROOT),
               ATA_CACHE=str(tmp_path / "cache"))
    env.pop("ATA_RUNS", None)                  # default run folders go to runs/ in tmp_path
    try:
        proc = subprocess.run([sys.executable, "-c", RUNNER], input=json.dumps(runnable),
                              capture_output=True, text=True, cwd=tmp_path, env=env,
                              timeout=TIMEOUT_S)
    except subprocess.TimeoutExpired:
        pytest.fail(f"the ```python blocks of {doc.relative_to(ROOT)} took more than "
                    f"{TIMEOUT_S} s: make them smaller, or mark a long one "
                    "<!-- fragment: why -->", pytrace=False)
    if proc.returncode != 0:
        pytest.fail(f"a ```python block of {doc.relative_to(ROOT)} failed (mark a block that "
                    f"cannot run alone with <!-- fragment: why -->):\n{proc.stderr[-6000:]}",
                    pytrace=False)


# -- the tables of docs/model.md and docs/library.md are the code's -----------------------------

def _rows(text: str, first: str) -> list[list[str]]:
    """The cells of every markdown table row whose first cell is `first`, in order."""
    out = []
    for line in text.splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if line.strip().startswith("|") and cells[0] == first:
            out.append(cells[1:])
    return out


def test_the_model_page_tables_are_the_code_tables():
    import numpy as np

    from ata.core.mission import TEAM_SETTINGS, UNCERTAINTY_LEVELS
    from ata.model import fatigue, tables, team

    # the model's tables, then the library's (the default constants)
    text = "\n".join((ROOT / "docs" / name).read_text(encoding="utf-8")
                      for name in ("model.md", "library.md"))
    # P_RC, T_BAR and F_D, in that order: a row per quality, a column per difficulty
    for i, table in enumerate((tables.P_RC, tables.T_BAR, tables.F_D)):
        shown = [[float(x) for x in _rows(text, q)[i]] for q in tables.QUALITIES]
        assert np.allclose(shown, table, atol=5e-4), i
    for robot, r in (("UAV", tables.UAV), ("UGV", tables.UGV)):
        for kind, k in (("air", tables.AIR), ("ground", tables.GROUND)):
            row = next(cells for cells in _rows(text, robot) if cells[0] == kind)
            assert row[1:] == [tables.QUALITIES[q] for q in tables.QUALITY[r, k]], (robot, kind)
    for level, (variance, p) in UNCERTAINTY_LEVELS.items():
        assert [float(x) for x in _rows(text, level)[-1]] == [variance, p], level
    for name, size in TEAM_SETTINGS.items():
        assert [int(x) for x in _rows(text, name)[0]] == [size.humans, size.robots, size.tasks]
    constants = {"`FATIGUE_FLOOR`": team.FATIGUE_FLOOR, "`WINDOW_S`": team.WINDOW_S,
                 "`SA_DROP`": team.SA_DROP, "`SA_RECOVERY_PER_MIN`": team.SA_RECOVERY_PER_MIN,
                 "`SWITCH_COST_S`": team.SWITCH_COST_S, "`REBRIEF_S`": team.REBRIEF_S,
                 "`CAPTURE_S`": team.CAPTURE_S, "`REPLAN_S`": team.REPLAN_S,
                 "`ata.model.fatigue.FATIGUE_SPREAD`": fatigue.FATIGUE_SPREAD}
    for name, value in constants.items():
        shown = _rows(text, name)[0][0].split()[0]
        assert float(shown) == value, name
    assert tables.POINTS.tolist() == [15, 25, 35] and "= 15, 25, 35" in text
