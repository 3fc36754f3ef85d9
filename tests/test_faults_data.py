"""What an operator's folders and files can hold that a command must not trust: a folder another
kind of command wrote, a shipped weight file whose bytes changed, a run log edited by hand or
holding a non-finite total, and non-finite values in the columns `ata report` and `ata compare`
read."""

from __future__ import annotations

import csv
import json
import math
import shutil
from pathlib import Path

import pytest

from _support import assert_user_error, flat, small_mission
from ata.runtime import folders

SMALL = small_mission(4)


@pytest.fixture
def small(tmp_path):
    path = tmp_path / "small.toml"
    path.write_text(SMALL, encoding="utf-8")
    return path


@pytest.fixture
def run(cli, small, tmp_path):
    """A finished `ata run` folder, in batches of two scenarios."""
    out = tmp_path / "run"
    assert cli("run", small, "-q", "--chunk-size", 2, "-o", out).exit_code == 0
    return out


def snapshot(folder: Path) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in sorted(folder.iterdir()) if p.is_file()}


def edit_csv(path: Path, line: int, column: str, text: str) -> None:
    """Set `column` of the row on `line` (the header is line 1) of a CSV file to `text`."""
    with open(path, newline="", encoding="utf-8") as f:
        rows = list(csv.DictReader(f))
    rows[line - 2][column] = text
    with open(path, "w", newline="", encoding="utf-8") as f:
        writer = csv.DictWriter(f, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)


# --- 1. a folder another kind of command wrote ----------------------------------------------------

def test_train_refuses_a_run_folder_and_leaves_it_whole(cli, run):
    before = snapshot(run)
    assert_user_error(cli("train", "--plugins", "ita", "-q", "-o", run),
                      f"error: --out: {run} is the folder of a run (summary.json); choose "
                      f"another folder, or go on with it with ata run --out {run}")
    assert snapshot(run) == before


def test_run_refuses_an_evaluation_folder_even_with_force(cli, small, run, tmp_path):
    evaluation = tmp_path / "eval"
    assert cli("eval", small, "-e", "serial", "-n", 2, "--no-cache", "-q",
               "-o", evaluation).exit_code == 0
    before = snapshot(evaluation)
    assert_user_error(cli("run", small, "-q", "--force", "-o", evaluation),
                      f"error: --out: {evaluation} is the folder of an evaluation (eval.json); "
                      f"choose another folder, or go on with it with ata eval --out "
                      f"{evaluation}")
    assert_user_error(cli("eval", small, "-e", "serial", "-q", "--force", "-o", run),
                      f"{run} is the folder of a run (summary.json)")
    assert snapshot(evaluation) == before


def test_show_and_report_refuse_folders_of_other_commands(cli, small, run, tmp_path):
    pictures = tmp_path / "pictures"
    assert cli("show", small, "-n", 0, "-o", pictures).exit_code == 0
    assert_user_error(cli("show", small, "-n", 0, "-o", run),
                      f"{run} is the folder of a run (summary.json)")
    assert_user_error(cli("report", run, "--no-figures", "-o", pictures),
                      f"{pictures} is the folder of the pictures of ata show (show_map.png")
    assert_user_error(cli("run", small, "-q", "-o", pictures),
                      "replace them with ata show --out")
    # a report goes into the folder it reads, and a folder of its own
    assert cli("report", run, "--no-figures").exit_code == 0
    assert cli("report", run, "--no-figures", "-o", tmp_path / "rep").exit_code == 0


def test_an_unfinished_folder_is_known_by_its_plan(tmp_path):
    (tmp_path / "plan.json").write_text(json.dumps({"key": "k", "command": "eval"}))
    assert folders.folder_kind(tmp_path) == ("eval", ["plan.json"])
    (tmp_path / "plan.json").write_text(json.dumps({"key": "k", "mission": "m"}))  # older
    assert folders.folder_kind(tmp_path) == ("run", ["plan.json"])
    assert folders.folder_kind(tmp_path / "missing") is None


# --- 4. the shipped weights' digests ---------------------------------------------------------------

def test_every_shipped_checkpoint_is_pinned_and_matches():
    from ata.runtime import inputs
    shipped = sorted(p.name for p in inputs.WEIGHTS.glob("*.pt"))
    assert sorted(inputs.pinned()) == shipped
    assert all(inputs.shipped_mismatch(inputs.WEIGHTS / name) is None for name in shipped)


def test_a_shipped_checkpoint_with_flipped_bits_is_refused_naming_it(cli, small, tmp_path,
                                                                    monkeypatch):
    pytest.importorskip("torch")
    from ata.runtime import inputs
    weights = tmp_path / "weights"
    shutil.copytree(inputs.WEIGHTS, weights)
    data = bytearray((weights / "ata_hrl_a.pt").read_bytes())
    data[len(data) // 2] ^= 0x10                      # one bit, inside a tensor's bytes
    (weights / "ata_hrl_a.pt").write_bytes(bytes(data))
    monkeypatch.setattr(inputs, "WEIGHTS", weights)
    result = cli("run", small, "-q", "--set", "components.initial='attention'",
                 "--set", "attention.checkpoint='builtin:ata_hrl_a'", "-o", tmp_path / "out")
    assert_user_error(result, f"error: {weights / 'ata_hrl_a.pt'}: checkpoint: is not the file "
                              "ata shipped: its sha256 is", "reinstall ata")
    assert not (tmp_path / "out").exists()


# --- 5. the run log's digest and non-finite totals -------------------------------------------------

@pytest.mark.parametrize("value", [lambda x: x + 1.0, lambda x: float("nan")],
                         ids=["a finite score edited", "nan"])
def test_a_record_line_edited_after_it_was_written_is_dropped_and_redone(cli, small, run, value):
    why = "unit 1's results do not match the digest written with them"
    whole = (run / "results.csv").read_text()
    lines = [json.loads(x) for x in (run / "units.jsonl").read_text().splitlines()]
    totals = lines[1]["part"]["total"]["__array__"]
    totals[0] = value(totals[0])
    (run / "units.jsonl").write_text("".join(json.dumps(x) + "\n" for x in lines))
    (run / "results.csv").unlink()
    result = cli("run", small, "-q", "--chunk-size", 2, "-o", run)
    assert result.exit_code == 0, result.output
    assert f"1 line(s) of {run / 'units.jsonl'} did not fit the plan and were dropped, their " \
           f"work units to run again: line 2: {why}" in flat(result.output)
    assert "nan" not in flat(result.output)
    strip = [{k: v for k, v in r.items() if k != "wall_s"} for r in
             csv.DictReader(whole.splitlines())]
    again = [{k: v for k, v in r.items() if k != "wall_s"} for r in
             csv.DictReader((run / "results.csv").read_text().splitlines())]
    assert again == strip


def test_a_non_finite_total_is_dropped_even_with_a_matching_digest(cli, small, run):
    from ata.experiment import runlog
    lines = [json.loads(x) for x in (run / "units.jsonl").read_text().splitlines()]
    lines[0]["part"]["total"]["__array__"][1] = float("inf")
    lines[0]["digest"] = runlog.rows_digest(lines[0]["part"])
    (run / "units.jsonl").write_text("".join(json.dumps(x) + "\n" for x in lines))
    result = cli("run", small, "-q", "--chunk-size", 2, "-o", run)
    assert result.exit_code == 0, result.output
    assert "line 1: unit 0's total holds a value that is not a finite number" \
        in flat(result.output)
    assert math.isfinite(json.loads((run / "summary.json").read_text())["score_mean"])


# --- 7. non-finite values in the columns report and compare read ----------------------------------

def test_compare_refuses_a_column_holding_nan_naming_the_line(cli, run, tmp_path):
    other = tmp_path / "other"
    shutil.copytree(run, other)
    edit_csv(run / "results.csv", 3, "expected_score", "nan")
    for extra in ([], ["--means"]):
        assert_user_error(cli("compare", run, other, "-c", "expected_score", *extra),
                          "error: --column: 'expected_score' is not a finite number in 1 "
                          f"row(s) of the results of", f"(the first: {run / 'results.csv'} "
                          "line 3, method small)")


@pytest.mark.parametrize("column, text", [("fraction_of_u", "nan"), ("classified_share", "inf"),
                                          ("upper_bound", ""), ("expected_score", "-inf")])
def test_report_refuses_non_finite_values_in_any_column(cli, run, column, text):
    edit_csv(run / "results.csv", 2, column, text)
    result = cli("report", run, "--no-figures")
    assert_user_error(result, f"error: {run / 'results.csv'}: line 2: {column} is {text!r}, "
                              "not a finite number")
