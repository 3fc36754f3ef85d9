"""A worker process that dies (a component calling os._exit or crashing, the system killing it)
ends the command with one error line that says what to do, exit status 1, and the units that
finished kept; it was a `BrokenProcessPool` traceback."""

from __future__ import annotations

DIES = """\
import multiprocessing
import os

from ata import hookimpl
from ata.plugins.policies.greedy import GreedyPolicy


class Dies(GreedyPolicy):
    name = "dies"

    @hookimpl
    def ata_initial_allocation(self, ctx):
        if multiprocessing.parent_process() is not None:     # in a worker process
            os._exit(3)
        return super().ata_initial_allocation(ctx)
"""

MISSION = """\
[mission]
name = "dies"
setting = "a"
uncertainty = "medium"
scenarios = 4

[components]
initial = "./dies.py:Dies"
"""


def test_a_worker_that_dies_is_one_line_that_says_what_to_do(cli, tmp_path):
    (tmp_path / "dies.py").write_text(DIES)
    (tmp_path / "m.toml").write_text(MISSION)
    result = cli("run", tmp_path / "m.toml", "-n", 4, "-w", 2, "-e", "process",
                 "-o", tmp_path / "out", "-q")
    assert result.exit_code == 1, result.output
    assert "Traceback" not in result.output and "BrokenProcessPool" not in result.output
    assert "error: a worker process ended without an answer" in result.output
    assert "same --out resumes the rest" in result.output
