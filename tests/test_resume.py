"""Nothing lost: `ata eval` saves each work unit as it finishes, a rerun into the same folder runs
only what is missing and ends with the rows of an uninterrupted run, a killed run leaves no
worker behind, and a folder of another plan is refused; a training run killed anywhere in its
phases resumes to the weights and log.csv rows of an uninterrupted one."""

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

from _support import assert_user_error

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
    assert err == (f"error: --out: {uninterrupted} holds the results of another plan (paths "
                   f"{suite} there, {other} here); choose another folder, or --force to start "
                   "it over there")
    assert len(rows(uninterrupted)) == 96            # untouched
    # the same suite in other work units: the message names the chunk size
    proc = ata_eval(suite, uninterrupted, "--executor", "serial", "--chunk-size", "3")
    assert proc.wait(timeout=300) == 2
    err = " ".join(proc.stderr.read().split())
    assert "holds the results of another plan (chunk_size 4 there, 3 here)" in err, err
    assert len(rows(uninterrupted)) == 96
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


def test_a_stopped_process_pool_leaves_no_thread_behind():
    # stopped mid-way (Ctrl-C, an error), the pool's manager thread must be gone before the
    # executor returns: left winding down, it races Python's exit hook on its wake-up pipe,
    # which then prints "Exception ignored ... Bad file descriptor" after the interrupt message
    import threading
    from concurrent.futures.process import _ExecutorManagerThread

    from ata.runtime.executors import ProcessExecutor

    results = ProcessExecutor(2).run(time.sleep, [0, 30, 30, 30])
    assert next(results) == (0, None)
    t0 = time.time()
    results.close()
    assert time.time() - t0 < 10
    assert not [t for t in threading.enumerate() if isinstance(t, _ExecutorManagerThread)]


def ata_run(out: Path, *extra: str) -> subprocess.Popen:
    from ata.session import BASELINE_MISSION   # greedy, on-event reallocation
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
    from ata.session import BASELINE_MISSION, load_session
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
    from ata.session import load_session
    from ata.experiment.runner import plan_key
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


# --- the training library's phase loop ------------------------------------------------------------

class Doubling:
    """A trainer of one tensor in two phases, run by ata.training's phase loop: phase "a" adds
    k + 1 at its step k (2 episodes a step), phase "b" doubles it; validation scores how close
    its sum is to 10."""

    fields = ["phase", "step", "episodes", "episodes_per_s", "value", "eval", "wall_s"]

    def __init__(self):
        import torch
        from ata.training import PhaseLoop
        self.x = torch.zeros(2)
        self.loop = PhaseLoop(["a", "b"], lambda name: {"kind": "toy", "x": self.x.clone(),
                                                        **self.loop.state()})

    def run(self, run, resume=False):
        from ata.training import Phase

        def add(k):
            self.x += k + 1
            return {"value": f"{self.x.sum():.1f}"}, 2

        def double(k):
            self.x *= 2
            return {"value": f"{self.x.sum():.1f}"}, 0

        def validate():
            score = -abs(float(self.x.sum()) - 10.0)
            return score, {"eval": f"{score:.1f}"}

        self.loop.run = run
        if resume and run.resumes:
            data = run.resume_checkpoint("toy")
            self.x = data["x"]
            self.loop.load_state(data)
        self.loop.run_phase(Phase("a", 4, add, checkpoint_every=2, eval_every=2,
                                  validate=validate, validate_first=True))
        self.loop.run_phase(Phase("b", 2, double, eval_every=1, validate=validate,
                                  validate_first=True, fresh_best=True))
        return self.loop.finish()


# by hand: a adds 1, 2, 3, 4 (sums 2, 6, 12, 20), validated at steps 0, 2 and 4 (the last);
# b doubles twice (40, 80), validated at every step; best.pt: a's step 2 (-4), until b's step 0
# starts afresh (-10: x = [10, 10]), which stays the best
DOUBLING_ROWS = [
    {"phase": "a", "step": "0", "episodes": "", "value": "", "eval": "-10.0"},
    {"phase": "a", "step": "1", "episodes": "2", "value": "2.0", "eval": ""},
    {"phase": "a", "step": "2", "episodes": "4", "value": "6.0", "eval": "-4.0"},
    {"phase": "a", "step": "3", "episodes": "6", "value": "12.0", "eval": ""},
    {"phase": "a", "step": "4", "episodes": "8", "value": "20.0", "eval": "-10.0"},
    {"phase": "b", "step": "0", "episodes": "", "value": "", "eval": "-10.0"},
    {"phase": "b", "step": "1", "episodes": "", "value": "40.0", "eval": "-30.0"},
    {"phase": "b", "step": "2", "episodes": "", "value": "80.0", "eval": "-70.0"}]


class Killed(Exception):
    pass


def doubling_run(folder: Path, *, resume=False, kill=None) -> "Doubling":
    from ata.training import TrainRun

    def on_row(row):
        if kill is not None and (row["phase"], str(row["step"])) == kill:
            raise Killed

    trainer = Doubling()
    run = TrainRun(folder, "", Doubling.fields, resume=resume, on_row=on_row)
    trainer.report = trainer.run(run, resume=resume)
    return trainer


def training_rows(folder: Path) -> list[dict]:
    with open(folder / "log.csv", newline="") as f:
        return [{k: v for k, v in r.items() if k not in ("wall_s", "episodes_per_s")}
                for r in csv.DictReader(f)]


@pytest.mark.parametrize("kill", [("a", "0"),     # before any checkpoint.pt: starts over
                                  ("a", "3"),     # after step 2's checkpoint
                                  ("b", "1")])    # in the second phase
def test_the_phase_loop_resumes_a_killed_run_to_the_same_weights_and_log(tmp_path, kill):
    import torch
    from ata.training import read_checkpoint
    whole = doubling_run(tmp_path / "whole")
    assert training_rows(tmp_path / "whole") == DOUBLING_ROWS
    assert whole.x.tolist() == [40.0, 40.0]
    assert whole.report["counters"] == {"a": 4, "b": 2, "episodes": 8}
    assert whole.report["best_eval"] == -10.0
    assert read_checkpoint(tmp_path / "whole" / "best.pt")["x"].tolist() == [10.0, 10.0]
    with pytest.raises(Killed):
        doubling_run(tmp_path / "broken", kill=kill)
    again = doubling_run(tmp_path / "broken", resume=True)
    assert training_rows(tmp_path / "broken") == DOUBLING_ROWS
    assert torch.equal(again.x, whole.x) and again.report["counters"] == whole.report["counters"]
    assert torch.equal(read_checkpoint(tmp_path / "broken" / "best.pt")["x"],
                       torch.tensor([10.0, 10.0]))


@pytest.mark.skipif(os.name != "posix", reason="flock and signals")
def test_a_run_under_way_keeps_a_second_one_out(cli, tmp_path):
    """A real `ata run` process holds its folder: a second run on it is refused (exit 2)
    naming the first, and the folder is free again once the first is stopped."""
    out = tmp_path / "both"
    # the loops compiled and cached first (numba), so that the interrupted run below is
    # stepping, not compiling, when its SIGINT lands (one that lands in the compiler stops the
    # run only at the next epoch: test_a_ctrl_c_lost_where_it_landed_still_stops_the_run);
    # this test is about the folder's lock
    warm = cli("run", "builtin:greedy", "-q", "--set", "mission.scenarios=2", "-o",
               tmp_path / "warm")
    assert warm.exit_code == 0, warm.output
    first = subprocess.Popen([sys.executable, "-c", "from ata.cli import app; app()", "run",
                              "builtin:greedy", "-q", "--set", "mission.scenarios=2000",
                              "--chunk-size", "20", "-o", str(out)],
                             stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                             preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    try:
        deadline = time.time() + 120
        while not (out / ".ata-lock").exists() or \
                str(first.pid) not in (out / ".ata-lock").read_text():
            assert first.poll() is None and time.time() < deadline, first.stderr.read()
            time.sleep(0.05)
        second = cli("run", "builtin:greedy", "-q", "--set", "mission.seed=5", "-o", out)
        assert_user_error(second, f"--out: {out} is in use by another run (pid {first.pid}, "
                                  "started ", "run builtin:greedy -q")
    finally:
        first.send_signal(signal.SIGINT)
        first.wait(timeout=60)
    assert first.returncode == 130, first.stderr.read()
    assert not (out / ".ata-lock").exists()
    assert not (out / "mission.resolved.toml").exists()       # the first run wrote no result
    assert json.loads((out / "plan.json").read_text())["scenarios"] == 2000


@pytest.mark.skipif(os.name != "posix", reason="signals")
def test_a_ctrl_c_lost_where_it_landed_still_stops_the_run(cli, tmp_path, monkeypatch,
                                                           sigint_at_python_default):
    # a SIGINT that lands inside a C library's callback (llvmlite's, while numba compiles a
    # hot loop on a machine's first run) raises there and is dropped: the run must still stop,
    # at the next epoch, saying what was saved
    from ata.experiment import units
    from ata.session import BASELINE_MISSION
    real, sent = units.run_unit, []

    def lost_interrupt(unit, on_epoch=None):
        if not sent:
            sent.append(1)
            try:
                os.kill(os.getpid(), signal.SIGINT)
                time.sleep(1.0)
            except KeyboardInterrupt:
                pass                                     # lost, as in the callback
        return real(unit, on_epoch=on_epoch)

    monkeypatch.setattr(units, "run_unit", lost_interrupt)
    out = tmp_path / "run"
    r = cli("run", BASELINE_MISSION, "--set", "mission.scenarios=6",
            "--set", "mission.batch_size=3", "-o", out, "-q")
    assert sent and r.exit_code == 130, r.output
    assert " ".join(r.output.split()) == (
        f"interrupted: 0 of 2 batches are saved in {out}; run the same command with --out "
        f"{out} to go on")
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler    # put back
