"""Nothing lost: `ata eval` saves each work unit as it finishes, a rerun into the same folder runs
only what is missing and ends with the rows of an uninterrupted run, a killed run leaves no
worker behind, and a folder of another plan is refused."""

from __future__ import annotations

import csv
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

SUITE = """\
[suite]
name = "small"
settings = ["a"]
uncertainty = ["low", "high"]
scenarios = {scenarios}
seed = 0

[[method]]
name = "greedy"
mission = "builtin:greedy"

[[method]]
name = "random"
mission = "{random}"
"""
RANDOM = Path(__file__).resolve().parent.parent / "examples" / "missions" / "random_baseline.toml"


@pytest.fixture
def suite(tmp_path):
    path = tmp_path / "suite.toml"
    path.write_text(SUITE.format(scenarios=24, random=RANDOM))
    return path


def rows(folder: Path) -> list[dict]:
    with open(folder / "results.csv", newline="") as f:
        return [{k: v for k, v in r.items() if k != "wall_s"} for r in csv.DictReader(f)]


def _sigint_as_in_a_terminal() -> None:
    """In the child: SIGINT at its default, as a terminal's Ctrl-C finds it. A test run started
    in the background by a non-interactive shell inherits SIGINT ignored, and Python then
    installs no handler for it."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def ata_eval(suite: Path, out: Path, *extra: str) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-c", "from ata.cli import app; app()", "eval",
                             str(suite), "--chunk-size", "4", "-o", str(out), "-q", *extra],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            preexec_fn=_sigint_as_in_a_terminal if os.name == "posix" else None)


def lines(path: Path) -> int:
    try:
        return path.read_bytes().count(b"\n")
    except FileNotFoundError:
        return 0


def children(pid: int) -> list[int]:
    out = []
    for task in Path(f"/proc/{pid}/task").iterdir():
        text = (task / "children").read_text().split()
        out += [int(c) for c in text]
    return out


@pytest.fixture
def uninterrupted(suite, tmp_path):
    out = tmp_path / "whole"
    proc = ata_eval(suite, out, "--executor", "serial")
    assert proc.wait(timeout=300) == 0, proc.stderr.read()
    return out


@pytest.mark.skipif(not Path("/proc/self/task").exists(), reason="needs Linux /proc")
def test_a_killed_eval_resumes_with_the_rows_of_an_uninterrupted_run(suite, tmp_path,
                                                                     uninterrupted):
    out = tmp_path / "killed"
    proc = ata_eval(suite, out, "--workers", "2")
    deadline = time.time() + 120
    while lines(out / "units.jsonl") < 3:
        assert proc.poll() is None and time.time() < deadline, "the run ended before the kill"
        time.sleep(0.05)
    workers = children(proc.pid)
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    saved = lines(out / "units.jsonl")
    assert 3 <= saved < 24 and not (out / "results.csv").exists()
    # no worker outlives its parent
    time.sleep(1.0)
    alive = [w for w in workers if Path(f"/proc/{w}").exists()
             and "multiprocessing" in Path(f"/proc/{w}/cmdline").read_text()]
    assert alive == []
    # a line cut short by the kill would be dropped: simulate one
    with open(out / "units.jsonl", "a") as f:
        f.write('{"unit": 11, "part": {"scen')
    again = ata_eval(suite, out, "--workers", "2")
    assert again.wait(timeout=300) == 0, again.stderr.read()
    err = again.stderr.read()
    assert f"resuming {out}: {saved} of 24 work units were done before; running the other " \
           f"{24 - saved}" in " ".join(err.split())
    assert json.loads((out / "eval.json").read_text())["arguments"]["resumed_units"] == saved
    assert lines(out / "units.jsonl") == 24
    assert rows(out) == rows(uninterrupted)


def test_a_finished_eval_rerun_runs_nothing_and_gives_the_same_rows(suite, uninterrupted):
    before = (uninterrupted / "units.jsonl").read_bytes()
    proc = ata_eval(suite, uninterrupted, "--executor", "serial")
    assert proc.wait(timeout=300) == 0, proc.stderr.read()
    assert f"resuming {uninterrupted}: all 24 work units were done before" in " ".join(proc.stderr.read().split())
    assert (uninterrupted / "units.jsonl").read_bytes() == before


def test_a_folder_of_another_plan_is_refused_unless_forced(suite, tmp_path, uninterrupted):
    other = tmp_path / "other.toml"
    other.write_text(SUITE.format(scenarios=8, random=RANDOM))
    proc = ata_eval(other, uninterrupted, "--executor", "serial")
    assert proc.wait(timeout=300) == 2
    err = " ".join(proc.stderr.read().split())
    assert err == (f"error: --out: {uninterrupted} holds the results of another plan; choose "
                   "another folder, or --force to start it over there")
    assert len(rows(uninterrupted)) == 96            # untouched
    proc = ata_eval(other, uninterrupted, "--executor", "serial", "--force")
    assert proc.wait(timeout=300) == 0, proc.stderr.read()
    assert len(rows(uninterrupted)) == 32
    assert sorted(p.name for p in (uninterrupted / "missions").iterdir()) == [
        "greedy__a__high.resolved.toml", "greedy__a__low.resolved.toml",
        "random__a__high.resolved.toml", "random__a__low.resolved.toml"]


@pytest.mark.skipif(os.name != "posix", reason="signals")
def test_ctrl_c_stops_at_once_saying_what_was_saved(tmp_path):
    # 96 work units, so that a loaded machine cannot finish them all before the signal
    suite = tmp_path / "suite.toml"
    suite.write_text(SUITE.format(scenarios=96, random=RANDOM))
    out = tmp_path / "interrupted"
    proc = ata_eval(suite, out, "--workers", "2")
    deadline = time.time() + 120
    while lines(out / "units.jsonl") < 2:
        assert proc.poll() is None and time.time() < deadline
        time.sleep(0.05)
    t0 = time.time()
    proc.send_signal(signal.SIGINT)
    assert proc.wait(timeout=30) == 130
    assert time.time() - t0 < 10
    saved = lines(out / "units.jsonl")
    assert " ".join(proc.stderr.read().split()) == (
        f"interrupted: {saved} of 96 work units are saved in {out}; run the same command with "
        f"--out {out} to go on")


def ata_run(out: Path, *extra: str) -> subprocess.Popen:
    from ata.experiment.runner import BASELINE_MISSION   # greedy, on-event reallocation
    return subprocess.Popen([sys.executable, "-c", "from ata.cli import app; app()", "run",
                             str(BASELINE_MISSION), "--set", "mission.scenarios=24",
                             "--set", "mission.batch_size=3", "-o", str(out), "-q", *extra],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def test_a_killed_run_resumes_with_the_results_of_an_uninterrupted_run(tmp_path):
    whole = tmp_path / "whole"
    proc = ata_run(whole)
    assert proc.wait(timeout=300) == 0, proc.stderr.read()
    out = tmp_path / "killed"
    proc = ata_run(out)
    deadline = time.time() + 120
    while lines(out / "units.jsonl") < 2:
        assert proc.poll() is None and time.time() < deadline, "the run ended before the kill"
        time.sleep(0.02)
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    saved = lines(out / "units.jsonl")
    assert 2 <= saved < 8 and not (out / "results.csv").exists()
    again = ata_run(out)
    assert again.wait(timeout=300) == 0, again.stderr.read()
    assert f"resuming {out}: {saved} of 8 batches were done before; running the other " in \
        " ".join(again.stderr.read().split())
    assert (out / "results.csv").read_text() == (whole / "results.csv").read_text()


def test_workers_are_honoured_even_for_one_batch():
    from ata.experiment.runner import BASELINE_MISSION, load_session
    from ata.experiment.units import chunks_of
    mission = load_session(str(BASELINE_MISSION), ["mission.scenarios=10"]).mission
    assert [c.size for c in chunks_of(mission, 1)] == [10]          # batch_size 500
    assert [c.size for c in chunks_of(mission, 2)] == [5, 5]
    assert [c.size for c in chunks_of(mission, 3)] == [4, 4, 2]


def test_plan_keys_change_with_the_content_of_the_weights_a_mission_names(tmp_path):
    """A folder of results made with one checkpoint is not resumed with another that has the
    same name: the plan keys of `ata run` and `ata eval` hold each named file's digest."""
    import shutil

    from ata.experiment import evaluate as ev
    from ata.experiment.runner import load_session, plan_key
    import numpy as np

    weights = tmp_path / "w.pt"
    shutil.copy(Path(__file__).resolve().parent.parent / "ata" / "weights" / "ata_hrl_a.pt",
                weights)
    mission = Path(__file__).resolve().parent.parent / "examples" / "missions" / "ata_hrl_a.toml"
    suite = tmp_path / "suite.toml"
    suite.write_text(f'[suite]\nname = "w"\nsettings = ["a"]\nuncertainty = ["low"]\n'
                     f'scenarios = 4\nseed = 0\n\n[[method]]\nname = "m"\nmission = "{mission}"\n'
                     f'set = ["ctr.checkpoint=\'{weights}\'"]\n')
    sets = [f"ctr.checkpoint='{weights}'"]

    def keys():
        session = load_session(str(mission), sets)
        _, jobs = ev.plan([str(suite)], validate=False)
        return plan_key(session, [np.arange(4)]), ev.plan_key(jobs, 2)

    first = keys()
    assert keys() == first                                   # stable while the file is
    # the digest is of the content, not the name: the copy's is the shipped file's
    assert load_session(str(mission), sets).inputs()["ctr.checkpoint"] == \
        load_session(str(mission)).inputs()["ctr.checkpoint"]
    weights.write_bytes(weights.read_bytes() + b"\0")        # same name, other content
    second = keys()
    assert second[0] != first[0] and second[1] != first[1]
