"""The faults an operator still meets (issue 59): a folder of seeds is a folder kind with
bounded seeds, an error raised in a worker arrives as the same one-line refusal, `ata publish`
writes a set whole or not at all, an optional extra that fails is one warning, and the small
ones: each one line and exit 2, or working."""

from __future__ import annotations

import os
import resource
import subprocess
import sys
from pathlib import Path

import pytest

from _support import assert_user_error, flat

RANDOM = ('[mission]\nname = "random"\nhorizon_s = 600.0\n\n[components]\ninitial = "random"\n'
          'condition = "never"\n')
SUITE = ('[suite]\nname = "refs"\nsettings = ["a"]\nuncertainty = ["low"]\nscenarios = 3\n'
         '[[method]]\nname = "random"\nmission = "random.toml"\n')


def snapshot(folder: Path) -> dict[str, bytes]:
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*"))
            if p.is_file()}


# --- 11. ata publish writes a set whole or not at all ---------------------------------------------

@pytest.fixture
def evaluated(cli, tmp_path, monkeypatch):
    """A tiny `ata eval` folder (one method, 3 scenarios of 600 s) in a fresh working folder."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "random.toml").write_text(RANDOM, encoding="utf-8")
    (tmp_path / "refs.toml").write_text(SUITE, encoding="utf-8")
    result = cli("eval", "refs.toml", "-o", "refs", "-e", "serial", "-q")
    assert result.exit_code == 0, result.output
    return tmp_path / "refs"


def test_publish_refuses_a_file_or_a_folder_of_other_files(cli, evaluated, tmp_path):
    (tmp_path / "afile").write_text("mine", encoding="utf-8")
    assert_user_error(cli("publish", evaluated, "-o", tmp_path / "afile"), "it is a file")
    assert (tmp_path / "afile").read_text(encoding="utf-8") == "mine"
    before = snapshot(evaluated)
    assert_user_error(cli("publish", evaluated, "-o", evaluated), "holds other files",
                      "choose another folder")
    assert snapshot(evaluated) == before


def test_a_full_disk_leaves_no_half_set_and_the_good_set_untouched(cli, evaluated, tmp_path):
    out = tmp_path / "pub"

    def publish_with_a_small_disk(limit: int) -> subprocess.CompletedProcess:
        return subprocess.run(
            [sys.executable, "-m", "ata.cli", "publish", str(evaluated), "-o", str(out)],
            capture_output=True, text=True, env={**os.environ, "COLUMNS": "200"},
            preexec_fn=lambda: resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit)))

    done = publish_with_a_small_disk(1000)       # rows.csv.gz fits, manifest.json does not
    assert done.returncode == 2 and "Traceback" not in done.stderr, done.stderr
    assert "File too large" in flat(done.stderr)
    assert not out.exists()
    assert sorted(p.name for p in tmp_path.iterdir() if p.name.startswith(".")) == []
    result = cli("publish", evaluated, "-o", out)
    assert result.exit_code == 0, result.output
    good = snapshot(out)
    done = publish_with_a_small_disk(1000)       # republished over a good set: it stays good
    assert done.returncode == 2 and "Traceback" not in done.stderr, done.stderr
    assert "left as it was" in flat(done.stderr)
    assert snapshot(out) == good
    result = cli("publish", evaluated, "-o", out)       # and replaced when the disk has room
    assert result.exit_code == 0, result.output
    assert snapshot(out) == good


# --- 9. a folder of seeds is a folder kind, with bounded seeds ------------------------------------

@pytest.fixture
def no_training(monkeypatch):
    """Training refused outright: what the commands below do must be refused before it."""
    from ata.experiment import training

    def trained(*args, **kwargs):
        raise AssertionError("a training started")
    monkeypatch.setattr(training, "train_one", trained)
    monkeypatch.setattr(training, "train_seeds", trained)


def test_seeds_and_a_training_run_never_write_over_each_other(cli, tmp_path, no_training):
    run = tmp_path / "run"
    run.mkdir()
    for name in ("checkpoint.pt", "log.csv", "mission.resolved.toml"):
        (run / name).write_text("kept", encoding="utf-8")
    result = cli("train", "--plugins", "trp", "--seeds", "2", "-o", run)
    assert_user_error(result, f"{run} is the folder of a training run", "--resume")
    assert sorted(p.name for p in run.iterdir()) == \
        ["checkpoint.pt", "log.csv", "mission.resolved.toml"]
    seeds = tmp_path / "seeds"
    seeds.mkdir()
    (seeds / "seeds.json").write_text('{"seeds": [0]}', encoding="utf-8")
    result = cli("train", "--plugins", "trp", "-o", seeds)
    assert_user_error(result, f"{seeds} is the folder of training seeds (seeds.json)",
                      f"ata train --resume {seeds}")
    assert sorted(p.name for p in seeds.iterdir()) == ["seeds.json"]
    result = cli("run", "-q", "-o", seeds)
    assert_user_error(result, f"{seeds} is the folder of training seeds")


@pytest.mark.parametrize("seeds, message", [
    ("", "'': give a count (3) or a list of seeds (1,2,5)"),
    (",", "',': give a count (3) or a list of seeds (1,2,5)"),
    ("1000000000", "the count must be 1 to 1,000"),
    (",".join(map(str, range(1001))), "1,001 seeds: at most 1,000"),
    ("9" * 30_000, "at most 1,000 seeds"),
])
def test_seeds_are_bounded_before_any_work(cli, tmp_path, no_training, seeds, message):
    assert_user_error(cli("train", "--plugins", "trp", "--seeds", seeds, "-o", tmp_path / "o"),
                      message)
    assert not (tmp_path / "o").exists()


# --- 10. errors in workers cross as plain data ----------------------------------------------------

EDITS = '''"""A policy that edits its own file once a worker process has used it: the next unit's
worker resolves the file again and refuses it (a method file edited mid-run)."""
import multiprocessing

import numpy as np

from ata import hookimpl
from ata.core.state import Allocation


class Edits:
    name = "edits"

    def __init__(self, settings, mission):
        pass

    @hookimpl
    def ata_initial_allocation(self, ctx):
        if multiprocessing.parent_process() is not None:
            with open(__file__, "a", encoding="utf-8") as f:
                f.write("# edited\\n")
        zeros = np.zeros(ctx.inherent["tasks"].col("kind").shape, dtype=np.int64)
        return Allocation(zeros, zeros - 1, zeros.copy())
'''


def test_a_refusal_in_a_worker_is_the_same_line_and_the_units_before_it_are_saved(cli,
                                                                                 tmp_path):
    (tmp_path / "edits.py").write_text(EDITS, encoding="utf-8")
    mission = tmp_path / "m.toml"
    mission.write_text('[mission]\nname = "small"\nsetting = "custom"\nhumans = 2\nrobots = 3\n'
                       'tasks = 10\nscenarios = 6\nhorizon_s = 600.0\n[components]\n'
                       'initial = "./edits.py:Edits"\ncondition = "never"\n', encoding="utf-8")
    out = tmp_path / "out"
    result = cli("run", mission, "-q", "--chunk-size", 2, "-e", "process", "-w", 1, "-o", out)
    assert_user_error(result, f"[references] key 'edits': {tmp_path / 'edits.py'} changed while "
                              "the run was under way", "run it again")
    assert len((out / "units.jsonl").read_bytes().splitlines()) == 1      # the first batch


class Unpicklable(Exception):
    def __init__(self, a, b):
        super().__init__(f"{a} and {b}")


def fails_for_one(unit: int) -> int:
    """A unit run in a worker: unit 1 raises an error that cannot be unpickled, unit 2 a
    refusal."""
    from ata.core.errors import MissionError
    if unit == 1:
        raise Unpicklable("this", "that")
    if unit == 2:
        raise MissionError("[mission]", "seed", "a refusal", file="m.toml")
    return unit * 10


def test_any_error_in_a_worker_arrives_named_after_the_units_finished_first():
    from ata.core.errors import MissionError
    from ata.runtime.executors import ProcessExecutor, WorkerError

    with ProcessExecutor(1) as ex:
        got = []
        with pytest.raises(WorkerError, match="Unpicklable: this and that"):
            for i, value in ex.run(fails_for_one, [0, 1, 3]):
                got.append(value)
        assert got[0] == 0 and set(got) <= {0, 30}   # what finished first is yielded
        with pytest.raises(MissionError) as caught:
            list(ex.run(fails_for_one, [2]))
        assert str(caught.value) == "m.toml: [mission] key 'seed': a refusal"
        assert sorted(ex.run(fails_for_one, [0, 3])) == [(0, 0), (1, 30)]


def test_resuming_seeds_with_a_seed_folder_missing_is_one_line(cli, tmp_path, no_training):
    seeds = tmp_path / "seeds"
    (seeds / "seed-0").mkdir(parents=True)
    (seeds / "seed-0" / "mission.resolved.toml").write_text("", encoding="utf-8")
    (seeds / "seeds.json").write_text('{"seeds": [0, 1]}', encoding="utf-8")
    result = cli("train", "--resume", seeds, "-e", "process", "-w", 2)
    assert_user_error(result, f"{seeds} is a folder of 2 seeds, but seed-1 holds no "
                              "mission.resolved.toml")


# --- 12. optional extras fail soft on any exception -----------------------------------------------

@pytest.fixture
def broken_extra(tmp_path, monkeypatch):
    """`broken_extra("tensorboard")`: a package of that name, first on the path, whose import
    raises a TypeError (as a protobuf mismatch makes TensorBoard's)."""
    def install(name: str) -> None:
        folder = tmp_path / "site" / name
        folder.mkdir(parents=True)
        (folder / "__init__.py").write_text(
            'raise TypeError("Descriptors cannot be created directly.\\nIf this call came '
            'from a _pb2.py file, your generated code is out of date")\n', encoding="utf-8")
        monkeypatch.syspath_prepend(str(tmp_path / "site"))
        for module in [m for m in sys.modules if m == name or m.startswith(name + ".")]:
            monkeypatch.delitem(sys.modules, module)
    return install


def test_a_broken_tensorboard_is_one_warning_and_the_training_goes_on(tmp_path, broken_extra,
                                                                     capsys):
    import warnings

    from ata.cli import terminal
    from ata.runtime.extras import ExtraWarning
    from ata.training import TrainRun
    broken_extra("tensorboard")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        run = TrainRun(tmp_path / "run", "", ["phase", "step", "loss"])
        run.log({"phase": "ita", "step": 1, "loss": "0.5"})
        run.log({"phase": "ita", "step": 2, "loss": "0.4"})
        run.save({"step": 2})
        run.close()
    assert (tmp_path / "run" / "checkpoint.pt").is_file()
    assert len((tmp_path / "run" / "log.csv").read_text().splitlines()) == 3
    assert [w.category for w in caught] == [ExtraWarning]
    message = str(caught[0].message)
    assert message == ("tensorboard failed loading it (TypeError: Descriptors cannot be created "
                       "directly.); going on without it")
    with warnings.catch_warnings():             # as the CLI shows it: one line
        terminal.one_line_warnings()
        warnings.warn(message, ExtraWarning)
    assert capsys.readouterr().err.splitlines() == [f"warning: {message}"]


def test_a_broken_ray_is_one_line(cli, tmp_path, broken_extra):
    broken_extra("ray")
    (tmp_path / "m.toml").write_text('[mission]\nname = "m"\nscenarios = 2\n', encoding="utf-8")
    assert_user_error(cli("run", tmp_path / "m.toml", "-e", "ray", "-o", tmp_path / "o"),
                      "--executor ray needs ray", "the ray installed fails to load (TypeError: "
                      "Descriptors cannot be created directly.)", "pip install")


# --- 13. the small ones ---------------------------------------------------------------------------

@pytest.mark.parametrize("text, message", [
    ("[1, 2]", "manifest.json: the manifest of published rows is not a JSON object but a list"),
    ("nope", "manifest.json: the manifest of published rows is not JSON"),
])
def test_a_manifest_that_is_not_a_json_object_is_one_line(cli, evaluated, tmp_path, text,
                                                          message):
    assert cli("publish", evaluated, "-o", tmp_path / "pub").exit_code == 0
    (tmp_path / "pub" / "manifest.json").write_text(text, encoding="utf-8")
    assert_user_error(cli("compare", evaluated, f"published:{tmp_path / 'pub'}"), message)


def test_missing_pinned_digests_say_to_reinstall(tmp_path, monkeypatch):
    from ata.core.errors import MissionError
    from ata.runtime import inputs
    monkeypatch.setattr(inputs, "PINNED", tmp_path / "digests.json")
    shipped = next(inputs.WEIGHTS.glob("*.pt"))
    with pytest.raises(MissionError, match="cannot read the pinned digests of ata's shipped "
                                           "checkpoints: No such file or directory: reinstall"):
        inputs.shipped_mismatch(shipped)


def test_an_infinite_decision_timeout_is_refused(cli, tmp_path):
    result = cli("run", "--isolate", "--decision-timeout", "inf", "-o", tmp_path / "o")
    assert result.exit_code == 2 and "Traceback" not in result.output
    assert "--decision-timeout" in result.output and "86400" in result.output


def test_no_width_still_prints(tmp_path):
    from typer.testing import CliRunner

    from ata.cli import app
    runner = CliRunner(env={"COLUMNS": "0"})
    result = runner.invoke(app, ["run", str(tmp_path / "missing.toml")])
    assert result.exit_code == 2
    assert flat(result.output) == f"error: {tmp_path / 'missing.toml'}: no such file"


@pytest.mark.parametrize("env", [{"LC_ALL": "C", "LANG": "C", "PYTHONUTF8": "0"},
                                 {"PYTHONIOENCODING": "ascii"}])
def test_an_ascii_terminal_gets_its_table_of_a_non_ascii_name(tmp_path, env):
    mission = tmp_path / "x.toml"
    mission.write_text('[mission]\nname = "café — x"\nscenarios = 1\n', encoding="utf-8")
    base = {k: v for k, v in os.environ.items()
            if k not in ("LC_ALL", "LANG", "PYTHONIOENCODING", "PYTHONUTF8")}
    done = subprocess.run([sys.executable, "-m", "ata.cli", "run", str(mission), "-q", "-o",
                           str(tmp_path / "o")], capture_output=True,
                          env={**base, "COLUMNS": "100", **env})
    assert done.returncode == 0, done.stderr
    assert b"results: " in done.stdout and b"Traceback" not in done.stderr


def test_sys_exit_at_import_in_a_method_file_is_one_line(cli, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "ex.py").write_text("import sys\nsys.exit(3)\n", encoding="utf-8")
    (tmp_path / "ex.toml").write_text('[mission]\nname = "x"\nscenarios = 1\n[components]\n'
                                      'initial = "./ex.py:X"\n', encoding="utf-8")
    for args in (("run", "ex.toml", "-q", "-o", "o"), ("check", "--component", "policy",
                                                        "./ex.py:X")):
        assert_user_error(cli(*args), "error: code the command loaded called sys.exit(3)")
