"""A method named by file that imports a helper module of its own folder: the helper is part
of the method's code. Editing it changes the method's code digest, so a run made with the old
helper is not resumed with the new one (it was: the digest covered the file alone, and a
results.csv held rows of both versions)."""

from __future__ import annotations

import shutil
from pathlib import Path

from ata.core import references

POLICY = """\
from ata.plugins.policies.greedy import GreedyPolicy
from {helper} import SCALE


class HelpedGreedy(GreedyPolicy):
    name = "helped_greedy"
    scale = SCALE
"""

MISSION = """\
[mission]
name = "helped"
setting = "a"
uncertainty = "medium"
scenarios = 2

[components]
initial = "./helped.py:HelpedGreedy"
condition = "on_event"
reallocation = "./helped.py:HelpedGreedy"
"""


def _folder(tmp_path: Path, helper: str) -> Path:
    folder = tmp_path / "method"
    folder.mkdir()
    (folder / "helped.py").write_text(POLICY.format(helper=helper))
    (folder / f"{helper}.py").write_text("SCALE = 1.0\n")
    (folder / "mission.toml").write_text(MISSION)
    return folder


def test_the_helper_of_a_file_method_is_in_its_code_digest(tmp_path):
    folder = _folder(tmp_path, "helper_digest_a")
    factory, _, _ = references.load("./helped.py:HelpedGreedy", "test", folder)
    files = references.code_files(factory)
    assert folder / "helper_digest_a.py" in files
    before = references.code_digest(factory)
    (folder / "helper_digest_a.py").write_text("SCALE = 2.0\n")
    references._CLOSURES.clear()                   # a new process computes it afresh
    assert references.code_digest(factory) != before


def test_a_run_is_not_resumed_after_its_helper_changed(cli, tmp_path):
    folder = _folder(tmp_path, "helper_resume_b")
    out = tmp_path / "out"
    first = cli("run", folder / "mission.toml", "-n", 2, "-o", out, "-q")
    assert first.exit_code == 0, first.output
    (folder / "helper_resume_b.py").write_text("SCALE = 3.0\n")
    references._CLOSURES.clear()
    again = cli("run", folder / "mission.toml", "-n", 2, "-o", out, "-q")
    assert again.exit_code != 0
    assert "other code" in again.output and "helped_greedy" in again.output
    shutil.rmtree(out)
    fresh = cli("run", folder / "mission.toml", "-n", 2, "-o", out, "-q")
    assert fresh.exit_code == 0, fresh.output
