"""The operator's faults: a full disk or an unwritable file is one message saying what was saved,
a mission name never places a folder outside runs/, a run folder's record is checked line by
line on resume, a cut-short resolved mission is refused, an interrupted training says how to go
on, a mission too large for memory is cut or refused before any work starts."""

from __future__ import annotations

import csv
import errno
import os
import resource
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from _support import assert_user_error, flat, small_mission
from ata.experiment import runlog, runner, training
from ata.session import load_session
from ata.runtime import folders
from ata.model import greedy_planner
from ata.runtime import memory

SMALL = small_mission(6)


@pytest.fixture
def small(tmp_path):
    path = tmp_path / "small.toml"
    path.write_text(SMALL, encoding="utf-8")
    return path


def rows(folder: Path) -> list[dict]:
    with open(folder / "results.csv", newline="", encoding="utf-8") as f:
        return [{k: v for k, v in r.items() if k != "wall_s"} for r in csv.DictReader(f)]


@pytest.fixture
def whole(cli, small, tmp_path):
    """The rows of an uninterrupted run, in batches of two."""
    out = tmp_path / "whole"
    assert cli("run", small, "-q", "--chunk-size", 2, "-o", out).exit_code == 0
    return rows(out)


# --- I/O errors ---------------------------------------------------------------------------------

def test_a_file_size_limit_says_what_was_saved_and_the_rerun_goes_on(cli, small, whole,
                                                                     tmp_path):
    out = tmp_path / "out"
    first, second = (tmp_path / "whole" / "units.jsonl").read_bytes().splitlines(True)[:2]
    limit = len(first) + len(second) // 2          # one batch's line fits, not two

    def limited() -> None:
        resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))

    done = subprocess.run([sys.executable, "-m", "ata.cli", "run", str(small), "-q",
                           "--chunk-size", "2", "-o", str(out)], capture_output=True,
                          text=True, preexec_fn=limited,
                          env={**os.environ, "COLUMNS": "200"})
    assert done.returncode == 2, done.stderr
    assert "Traceback" not in done.stderr
    kept = (out / "units.jsonl").read_bytes()
    assert len(kept.splitlines()) == 1 and kept.endswith(b"\n")       # no half line
    assert flat(done.stderr) == (
        f"error: cannot write {out / 'units.jsonl'}: File too large; 1 of 3 batches are "
        f"saved in {out}: make room (or make it writable), then run the same command with "
        f"--out {out} to go on")
    result = cli("run", small, "-q", "--chunk-size", 2, "-o", out)
    assert result.exit_code == 0, result.output
    assert f"resuming {out}: 1 of 3 batches were done before; running the other 2" \
        in flat(result.output)
    assert rows(out) == whole


def test_a_failed_append_leaves_the_units_before_it(cli, small, whole, tmp_path, monkeypatch):
    out = tmp_path / "out"
    real_write, calls = os.write, []

    def write(fd, data):
        if not fd_is_log(fd):
            return real_write(fd, data)
        calls.append(len(data))
        if len(calls) == 1:
            return real_write(fd, data)
        if len(calls) == 2:                   # half of the second line, then the disk is full
            return real_write(fd, bytes(data[:len(data) // 2]))
        raise OSError(errno.ENOSPC, "No space left on device")

    def fd_is_log(fd) -> bool:
        return os.readlink(f"/proc/self/fd/{fd}").endswith("units.jsonl")

    monkeypatch.setattr(runlog.os, "write", write)
    result = cli("run", small, "-q", "--chunk-size", 2, "-o", out)
    assert_user_error(result, f"error: cannot write {out / 'units.jsonl'}: No space left on "
                              f"device; 1 of 3 batches are saved in {out}: make room (or make "
                              f"it writable), then run the same command with --out {out} to "
                              "go on")
    assert len((out / "units.jsonl").read_bytes().splitlines(keepends=True)) == 1
    monkeypatch.setattr(runlog.os, "write", real_write)
    result = cli("run", small, "-q", "--chunk-size", 2, "-o", out)
    assert "1 of 3 batches were done before" in flat(result.output)
    assert rows(out) == whole


def test_an_unreadable_record_is_one_message(cli, small, tmp_path):
    out = tmp_path / "out"
    assert cli("run", small, "-q", "--chunk-size", 2, "-o", out).exit_code == 0
    (out / "units.jsonl").unlink()
    (out / "units.jsonl").mkdir()
    result = cli("run", small, "-q", "--chunk-size", 2, "-o", out)
    assert_user_error(result, f"error: cannot write {out / 'units.jsonl'}: Is a directory; "
                              "nothing was run")


def test_results_that_cannot_be_written_are_kept_in_the_record(cli, small, whole, tmp_path,
                                                               monkeypatch):
    out = tmp_path / "out"

    def full(path, *args):
        raise OSError(errno.ENOSPC, "No space left on device", str(path))

    with monkeypatch.context() as patch:
        patch.setattr(runlog, "write_csv", full)
        result = cli("run", small, "-q", "--chunk-size", 2, "-o", out)
    assert_user_error(result, f"error: cannot write {out / 'results.csv'}: No space left on "
                              f"device; all 3 batches are saved in {out / 'units.jsonl'}: make "
                              f"room (or make it writable), then run the same command with "
                              f"--out {out} to write the results")
    result = cli("run", small, "-q", "--chunk-size", 2, "-o", out)
    assert f"resuming {out}: all 3 batches were done before" in flat(result.output)
    assert rows(out) == whole


def test_report_and_show_refuse_an_out_they_cannot_write(cli, small, tmp_path):
    run = tmp_path / "run"
    assert cli("run", small, "-q", "-o", run).exit_code == 0
    blocker = tmp_path / "file"
    blocker.write_text("")
    for command in (["report", run], ["show", run]):
        assert_user_error(cli(*command, "-o", blocker),
                          f"error: --out: cannot write to {blocker}: it is a file")
        assert_user_error(cli(*command, "-o", blocker / "sub"),
                          f"error: --out: cannot write to {blocker / 'sub'}: Not a directory")
    assert not (run / "report.md").exists()


def test_a_report_that_cannot_be_written_is_one_message(cli, small, tmp_path, monkeypatch):
    run = tmp_path / "run"
    assert cli("run", small, "-q", "-o", run).exit_code == 0

    def full(self, *args, **kwargs):
        raise OSError(errno.ENOSPC, "No space left on device", str(self))

    monkeypatch.setattr(Path, "write_text", full)
    assert_user_error(cli("report", run, "--no-figures"),
                      f"error: cannot write {run / 'report.md'}: No space left on device")


# --- mission names as paths ---------------------------------------------------------------------

@pytest.mark.parametrize("name, folder", [("/elsewhere/x", "elsewhere_x"), ("../../x", "x"),
                                          ("w/o.AUX", "w_o.AUX"), ("..", "run")])
def test_folder_names_stay_in_runs(name, folder):
    assert folders.safe_name(name) == folder


def test_a_mission_named_as_a_path_runs_in_runs(cli, small, tmp_path, monkeypatch):
    root = tmp_path / "runs"
    monkeypatch.setenv("ATA_RUNS", str(root))
    monkeypatch.setattr(folders.time, "strftime", lambda fmt: "20260101-000000")
    for name in ("/elsewhere/x", "../../x"):
        result = cli("run", small, "-q", "--set", f'mission.name="{name}"')
        assert result.exit_code == 0, result.output
    assert sorted(p.name for p in root.iterdir()) == ["elsewhere_x-20260101-000000",
                                                      "x-20260101-000000"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["runs", "small.toml"]
    # the folder `ata train` picks (cli's call) goes through the same naming
    session = load_session(str(small), ['mission.name="../../x"'])
    assert runner.default_out_dir(session.mission, prefix="train-") == \
        root / "train-_x-20260101-000000"


# --- the record checked on resume ---------------------------------------------------------------

def test_record_lines_that_do_not_fit_the_plan_are_dropped_and_run_again(cli, small, whole,
                                                                        tmp_path):
    import json
    out = tmp_path / "out"
    assert cli("run", small, "-q", "--chunk-size", 2, "-o", out).exit_code == 0
    (out / "results.csv").unlink()
    lines = [json.loads(x) for x in (out / "units.jsonl").read_text().splitlines()]
    lines[1]["unit"] = 0                               # relabelled: unit 0 twice, 1 missing
    del lines[2]["part"]["total"]
    lines[2]["digest"] = runlog.rows_digest(lines[2]["part"])   # as a writer of its own would
    (out / "units.jsonl").write_text("".join(json.dumps(x) + "\n" for x in lines)
                                     + "not json\n")
    result = cli("run", small, "-q", "--chunk-size", 2, "-o", out)
    assert result.exit_code == 0, result.output
    assert (f"3 line(s) of {out / 'units.jsonl'} did not fit the plan and were dropped, "
            "their work units to run again: line 2: unit 0 holds other scenarios than the "
            "plan's (0 to 1); line 3: unit 2 lacks total; line 4: not a unit's record") \
        in flat(result.output)
    assert f"resuming {out}: 1 of 3 batches were done before; running the other 2" \
        in flat(result.output)
    assert rows(out) == whole
    units = [json.loads(x)["unit"] for x in (out / "units.jsonl").read_text().splitlines()]
    assert sorted(units) == [0, 1, 2]


# --- a cut-short resolved mission ---------------------------------------------------------------

def test_show_refuses_a_resolved_mission_cut_short(cli, small, tmp_path):
    run = tmp_path / "run"
    assert cli("run", small, "-q", "-o", run).exit_code == 0
    path = run / "mission.resolved.toml"
    text = path.read_text(encoding="utf-8")
    path.write_text(text[:text.index("condition = ")], encoding="utf-8")  # at a line's end
    result = cli("show", run, "-o", tmp_path / "pictures")
    assert_user_error(result, f"error: {path}: not a whole resolved mission: [components] "
                              "condition, [components] reallocation, [components] trainer and "
                              "6 more missing (the file was cut short, or written by another "
                              "version of ata); a replay would fill them with defaults and "
                              "show another mission than the run's")
    assert not (tmp_path / "pictures").exists()


# --- training interrupted, the skill_speed error ------------------------------------------------

def test_an_interrupted_training_says_what_was_saved(cli, tmp_path, monkeypatch):
    out = tmp_path / "train"

    class Trainer:
        log_fields = ["step"]

        def total_steps(self):
            return 10

        def done_steps(self):
            return 0

        def run(self, run, resume=False):
            if saved:
                run.save({"step": 1})
                os.utime(run.dir / "checkpoint.pt", (1767225600, 1767225600))
            raise KeyboardInterrupt

    monkeypatch.setattr(training, "build_trainer", lambda session: Trainer())
    saved = False
    result = cli("train", "--plugins", "ita", "-q", "-o", out)
    assert result.exit_code == 130
    assert flat(result.output) == (f"interrupted before the first checkpoint: nothing to "
                                   f"resume in {out}; run the same command again to start over")
    saved = True
    result = cli("train", "--plugins", "ita", "-q", "-o", tmp_path / "again")
    assert result.exit_code == 130
    stamp = __import__("time").strftime("%Y-%m-%d %H:%M:%S",
                                        __import__("time").localtime(1767225600))
    assert flat(result.output) == (
        f"interrupted: the last checkpoint, saved {stamp}, is "
        f"{tmp_path / 'again' / 'checkpoint.pt'}; run ata train --resume {tmp_path / 'again'} "
        "to go on from it (the steps after it run again)")


def test_a_ctrl_c_lost_in_a_training_step_still_stops_the_training(cli, tmp_path, monkeypatch,
                                                                   sigint_at_python_default):
    # a SIGINT raised and dropped inside a C library's callback (numba compiling a loop in the
    # first rollout) must still stop `ata train`, at the next row the trainer logs
    import signal
    import time
    logged = []

    class Trainer:
        log_fields = ["phase", "step"]

        def total_steps(self):
            return 10

        def done_steps(self):
            return len(logged)

        def run(self, run, resume=False):
            for step in range(1, 11):
                if step == 2:
                    try:
                        os.kill(os.getpid(), signal.SIGINT)
                        time.sleep(1.0)
                    except KeyboardInterrupt:
                        pass                             # lost, as in the callback
                logged.append(step)
                run.log({"phase": "ita", "step": step})
            return {"wall_s": 0.0, "best_eval": 0.0}

    monkeypatch.setattr(training, "build_trainer", lambda session: Trainer())
    out = tmp_path / "train"
    result = cli("train", "--plugins", "ita", "-q", "-o", out)
    assert result.exit_code == 130, result.output
    assert logged == [1, 2]
    assert flat(result.output) == (f"interrupted before the first checkpoint: nothing to "
                                   f"resume in {out}; run the same command again to start over")
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler    # put back


def test_the_skill_speed_error_names_the_file(cli, small):
    small.write_text(SMALL + "\n[robot]\nskill_speed = [1.0]\n", encoding="utf-8")
    assert_user_error(cli("check", small), f"error: {small}: [robot] key 'skill_speed': needs "
                                           "exactly three factors (low, medium, high skill)")
    assert_user_error(cli("check", small, "--set", "robot.skill_speed=[1.0,2.0]"),
                      "error: --set robot.skill_speed=[1.0,2.0]: [robot] key 'skill_speed'")


# --- memory -------------------------------------------------------------------------------------

def test_the_planner_estimate():
    assert greedy_planner.peak_bytes(10, 6, 8, 10_000) == 8 * 10 * (
        16 * 14 * 10_000 + 64 * 10_000)


def test_a_batch_too_big_for_memory_is_cut_smaller(cli, small, whole, tmp_path, monkeypatch):
    session = load_session(str(small))
    limit = memory.batch_peak(session.mission, 2)
    monkeypatch.setattr(memory, "memory_limit", lambda: limit)
    out = tmp_path / "out"
    result = cli("run", small, "-q", "-o", out)
    assert result.exit_code == 0, result.output
    assert (f"batches of 2 scenarios, not 6: a bigger batch would need more than the "
            f"{limit / 2**30:.1f} GiB a run may use here (75% of the memory free now)") \
        in flat(result.output)
    assert rows(out) == whole


def test_a_mission_too_big_for_memory_is_refused_before_any_work(cli, small, tmp_path,
                                                                 monkeypatch):
    session = load_session(str(small))
    limit = memory.batch_peak(session.mission, 1) - 1
    monkeypatch.setattr(memory, "memory_limit", lambda: limit)
    out = tmp_path / "out"
    result = cli("run", small, "-q", "-o", out)
    assert_user_error(result, f"error: {small}: [mission] key 'tasks': one scenario of 10 POIs, "
                              "3 robots and 2 humans needs about 0.0 GiB of memory (the "
                              "planner's arrays and the components' own grow with the POIs), "
                              "more than the 0.0 GiB a run may use here (75% of the memory free "
                              "now); run fewer POIs")
    assert not out.exists()


def test_eval_units_too_big_for_memory_are_refused(cli, small, tmp_path, monkeypatch):
    session = load_session(str(small))
    limit = memory.batch_peak(session.mission, 2)
    monkeypatch.setattr(memory, "memory_limit", lambda: limit)
    result = cli("eval", small, "-e", "serial", "-n", 6, "--chunk-size", 6, "--no-cache",
                 "-q", "-o", tmp_path / "out")
    assert_user_error(result, "error: --chunk-size: batches of 6 scenarios of 'small' need "
                              "about 0.0 GiB of memory, more than the 0.0 GiB a run may use "
                              "here (75% of the memory free now); give a --chunk-size of at "
                              "most 2")
    assert not (tmp_path / "out" / "units.jsonl").exists()


# --- the animation ------------------------------------------------------------------------------

def test_animate_writes_one_frame_per_epoch(cli, small, tmp_path):
    pytest.importorskip("matplotlib")
    from PIL import Image

    from ata.viz.animate import poi_states, robot_at
    from ata.viz.record import UNVISITED, replay

    out = tmp_path / "pictures"
    result = cli("show", small, "-n", 2, "-o", out, "--animate")
    assert result.exit_code == 0, result.output
    assert str(out / "show_map.gif") in flat(result.output)
    with Image.open(out / "show_map.gif") as gif:
        assert (gif.format, gif.n_frames, gif.size) == ("GIF", 30, (640, 512))
        assert gif.info["duration"] == 400 and gif.info["loop"] == 0
    session = load_session(str(small))
    ep = replay(session.mission, session.registry, 2)
    assert (poi_states(ep, 0.0) == UNVISITED).all()
    assert np.array_equal(poi_states(ep, ep.horizon_s), ep.outcome)
    for leg in ep.legs:
        assert robot_at(ep, leg.robot, leg.end)[0] == pytest.approx(leg.dest, abs=1e-9)


# --- checkpoints: non-finite weights, and no unsafe advice ---------------------------------------

class _NotPlainData:
    """An object a weights-only load refuses."""


def test_a_checkpoint_with_non_finite_weights_is_refused_at_load_naming_the_tensor(tmp_path):
    import torch

    from ata.training import CheckpointError, read_checkpoint
    from ata.runtime.inputs import WEIGHTS
    data = torch.load(WEIGHTS / "ata_hrl_a.pt", map_location="cpu", weights_only=True)
    name = next(k for k, v in data["model"].items() if v.is_floating_point())
    data["model"][name] = data["model"][name].clone()
    data["model"][name].view(-1)[0] = float("nan")
    torch.save(data, tmp_path / "nan.pt")
    with pytest.raises(CheckpointError, match=f"non-finite values \\(NaN or inf\\) in "
                                              f"model.{name}:"):
        read_checkpoint(tmp_path / "nan.pt")
    data["model"][name].view(-1)[0] = float("inf")
    torch.save(data, tmp_path / "inf.pt")
    with pytest.raises(CheckpointError, match=f"in model.{name}:"):
        read_checkpoint(tmp_path / "inf.pt")
    # the shipped file itself loads
    assert read_checkpoint(WEIGHTS / "ata_hrl_a.pt")["kind"] == data["kind"]


def test_a_checkpoint_holding_objects_is_refused_without_the_unsafe_advice(tmp_path):
    import torch

    from ata.training import CheckpointError, read_checkpoint
    torch.save({"kind": "ata_hrl", "thing": _NotPlainData()}, tmp_path / "obj.pt")
    with pytest.raises(CheckpointError) as info:
        read_checkpoint(tmp_path / "obj.pt")
    text = str(info.value)
    assert "holds objects other than tensors and plain data" in text
    assert "weights_only" not in text


def test_a_file_that_is_no_checkpoint_is_refused_without_the_unsafe_advice(tmp_path):
    from ata.training import CheckpointError, read_checkpoint
    (tmp_path / "bad.pt").write_bytes(b"not a checkpoint")
    with pytest.raises(CheckpointError) as info:
        read_checkpoint(tmp_path / "bad.pt")
    text = str(info.value)
    assert "cannot be read as a checkpoint (UnpicklingError: not a file of tensors and plain " \
           "data: Unsupported operand 110)" in text
    assert "weights_only" not in text


def test_an_aux_checkpoint_whose_aux_part_was_never_trained_is_refused(tmp_path):
    from ata.plugins.ata_hrl.components import AuxReconstructor
    from ata.training import CheckpointError
    with pytest.raises(CheckpointError, match="ata_hrl_wo_aux_a.pt: checkpoint: trained no aux "
                                              "module \\(the aux reconstructor needs one that "
                                              "did"):
        AuxReconstructor(AuxReconstructor.Settings(checkpoint="builtin:ata_hrl_wo_aux_a"), None)
    # the full method's file trained it: accepted
    aux = AuxReconstructor(AuxReconstructor.Settings(checkpoint="builtin:ata_hrl_a"), None)
    assert aux.from_checkpoint
