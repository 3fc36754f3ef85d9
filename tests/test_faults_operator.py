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
