"""`ata report`'s paired-difference figure of an evaluation and its learning curves of a
training run folder: the numbers against a hand computation, the files written, and bad input."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from _support import flat
from ata.experiment import curves, results
from ata.experiment import report as rep
from ata.experiment.evaluate import CORE_COLUMNS
from ata.experiment.runlog import write_csv
from ata.core.errors import MissionError
from ata.training import TrainRun

SCORES = {"ATA-HRL": [10, 20, 30, 40, 50], "greedy": [5, 20, 35, 10, 0],
          "random": [1, 2, 3, 4, 5]}
"""Per scenario 100..104 at (a, low); elsewhere shifted (below)."""


def score(method: str, setting: str, level: str, i: int) -> float:
    return SCORES[method][i] + (3 * i if setting == "b" else 0) + (7 if level == "high" else 0) \
        * (method == "ATA-HRL")


def write_results(path: Path, methods=tuple(SCORES)) -> None:
    """Every method at settings a and b, levels low and high, scenarios 100..104 of seed 0;
    greedy's rows come in reverse order and random lacks scenario 102, so the pairs must be
    matched by (seed, scenario id), not by position."""
    rows = []
    for method in methods:
        for setting in ("a", "b"):
            for level in ("low", "high"):
                block = [{"method": method, "setting": setting, "uncertainty": level,
                          "scenario": 100 + i, "seed": 0,
                          "score": score(method, setting, level, i), "upper_bound": 100.0,
                          "fraction_of_u": 0.1, "classified_share": 0.5, "reallocations": 1,
                          "wall_s": 0.1}
                         for i in range(5) if not (method == "random" and i == 2)]
                rows += block[::-1] if method == "greedy" else block
    path.parent.mkdir(parents=True, exist_ok=True)
    write_csv(path, CORE_COLUMNS, rows)


# -- paired differences -------------------------------------------------------------------------
def test_paired_differences_equal_a_hand_computation(tmp_path):
    write_results(tmp_path / "results.csv")
    res = results.read_results(tmp_path)
    assert rep.paired_reference(res) == "greedy"
    paired = {(p.method, p.setting, p.level): p
              for p in rep.paired_differences(res, "greedy")}
    assert sorted(paired) == sorted((m, s, lv) for m in ("ATA-HRL", "random") for s in "ab"
                                    for lv in ("low", "high"))
    # ATA-HRL - greedy at (a, low), scenario by scenario: 10-5, 20-20, 30-35, 40-10, 50-0
    p = paired[("ATA-HRL", "a", "low")]
    assert (p.method, p.reference, p.n) == ("ATA-HRL", "greedy", 5)
    assert p.mean == pytest.approx(np.mean([5, 0, -5, 30, 50])) == 16.0
    assert (p.mean, p.low, p.high) == results.bootstrap_ci([5, 0, -5, 30, 50])
    assert p.low < p.mean < p.high
    # (b, high): ATA-HRL scores 7 + 3i more, greedy 3i more: the differences gain 7
    assert paired[("ATA-HRL", "b", "high")].mean == pytest.approx(23.0)
    # random lacks scenario 102: four pairs, 1-5, 2-20, 4-10, 5-0 (by position it would pair
    # 1-0, 2-10, 4-35, 5-20)
    p = paired[("random", "a", "low")]
    assert p.n == 4 and p.mean == pytest.approx(np.mean([-4, -18, -6, 5]))
    # the tables' paired difference is the same on the other side of the minus sign
    cells = {(c.method, c.setting, c.level): c for c in rep.summarize(res, "greedy").cells}
    for key, p in paired.items():
        mean, low, high = cells[key].diff
        assert (p.mean, p.low, p.high) == pytest.approx((-mean, -high, -low))


def test_paired_reference_default_and_unknown(tmp_path):
    write_results(tmp_path / "results.csv", methods=("random", "ATA-HRL"))
    res = results.read_results(tmp_path)
    assert rep.paired_reference(res) == "random"              # no greedy: the first method
    assert rep.paired_reference(res, "ATA-HRL") == "ATA-HRL"
    with pytest.raises(MissionError, match="no method 'nobody'"):
        rep.paired_reference(res, "nobody")


def test_report_writes_the_paired_figure_and_lists_it(cli, tmp_path):
    pytest.importorskip("matplotlib")
    write_results(tmp_path / "results.csv")
    res = cli("report", tmp_path)
    assert res.exit_code == 0, res.output
    for ext in ("png", "svg"):
        assert (tmp_path / f"fig_paired.{ext}").stat().st_size > 1000
    md = (tmp_path / "report.md").read_text()
    assert "## Figures" in md and "![fig_paired](fig_paired.png)" in md
    assert "![fig_setting_a](fig_setting_a.png)" in md
    assert "method - greedy" in md
    res = cli("report", tmp_path, "--paired-reference", "random", "--out", tmp_path / "out")
    assert res.exit_code == 0, res.output
    assert "method - random" in (tmp_path / "out" / "report.md").read_text()
    assert (tmp_path / "out" / "fig_paired.png").exists()
    res = cli("report", tmp_path, "--paired-reference", "nobody")
    assert res.exit_code == 2 and "no method 'nobody'" in flat(res.output)


def test_no_paired_figure_for_one_method(tmp_path):
    pytest.importorskip("matplotlib")
    write_results(tmp_path / "results.csv", methods=("greedy",))
    _, written = rep.write_report(tmp_path)
    assert not (tmp_path / "fig_paired.png").exists()
    assert "fig_paired" not in (tmp_path / "report.md").read_text()
    assert tmp_path / "fig_setting_a.png" in written


# -- training curves ----------------------------------------------------------------------------
def hrl_log(run_dir: Path) -> Path:
    """A log.csv as the ata_hrl trainer writes it: aux steps 1..8, then ita and ctr, each from
    its step-0 validation, validated every 5 steps."""
    from ata.plugins.ata_hrl.trainer import LOG_FIELDS
    run = TrainRun(run_dir, "", LOG_FIELDS)
    for s in range(1, 9):
        run.log({"phase": "aux", "step": s, "loss": 1.0 / s, "aux_fatigue_mse": 0.5 / s,
                 "aux_latency_mse": 0.1 / s, "wall_s": 0.1 * s})
    for phase, steps, base in (("ita", 20, 300.0), ("ctr", 10, 360.0)):
        run.log({"phase": phase, "step": 0, "eval_score": base, "eval_expected": base + 5})
        for s in range(1, steps + 1):
            row = {"phase": phase, "step": s, "setting": "a", "episodes": 128 * s,
                   "episodes_per_s": 40.0, "loss": -1.0, "mean_score": base + s,
                   "R_ITA": base, "R_C": base, "R_TR": base, "reallocations": 0.0,
                   "wall_s": s}
            if s % 5 == 0:
                row.update(eval_score=base + 2 * s - (s == steps) * 50, eval_expected=base + s)
            run.log(row)
    return run_dir


def dqn_log(run_dir: Path, steps=range(1, 31)) -> Path:
    """A log.csv as the dqn trainer writes it: one phase, validated every 10 steps."""
    from ata.plugins.tr_pomdp.trainer import LOG_FIELDS
    run = TrainRun(run_dir, "", LOG_FIELDS)
    for s in steps:
        run.log({"phase": "dqn", "step": s, "episodes": 16 * s, "episodes_per_s": 30.0,
                 "loss": 1.0, "mean_score": 50.0 + s, "epsilon": 0.5,
                 "eval_score": 60.0 + s if s % 10 == 0 else "", "wall_s": s})
    return run_dir


@pytest.mark.parametrize("make", [hrl_log, dqn_log])
def test_training_folder_report_writes_its_curves(cli, tmp_path, make):
    pytest.importorskip("matplotlib")
    pytest.importorskip("torch")
    run = make(tmp_path / "run")
    assert curves.is_training_folder(run)
    res = cli("report", run)
    assert res.exit_code == 0, res.output
    for ext in ("png", "svg"):
        assert (run / f"fig_curves.{ext}").stat().st_size > 1000
    md = (run / "curves.md").read_text()
    assert "![fig_curves](fig_curves.png)" in md
    log = curves.read_log(run)
    assert set(log.panels()) == {"score", "held_out", "loss", "speed"}
    assert "mean_score" in flat(res.output)


def test_training_log_phases_and_summary(tmp_path):
    pytest.importorskip("torch")
    log = curves.read_log(hrl_log(tmp_path / "run"))
    assert [p[0] for p in log.phases] == ["aux", "ita", "ctr"]
    assert log.starts == [0.0, 8.0, 28.0]                   # each phase after the one before
    assert log.x[0] == 1.0 and log.x[8] == 8.0 and log.x[-1] == 38.0
    assert log.panels() == {"score": ["mean_score"], "held_out": ["eval_score", "eval_expected"],
                            "loss": ["loss", "aux_fatigue_mse", "aux_latency_mse"],
                            "speed": ["episodes_per_s"]}
    header, rows = curves.curves_rows(log)
    assert header[:2] == ["phase", "steps"]
    assert [r[:2] for r in rows] == [["aux", "1-8"], ["ita", "0-20"], ["ctr", "0-10"]]
    held = header.index("eval_score: first -> last (best at step)")
    # ita: 300 at 0, 310, 320, 330 at 5..15, 340 - 50 at 20
    assert rows[1][held] == "300.0 -> 290.0 (330.0 at 15)"
    assert rows[0][held] == "-"


def test_rows_logged_again_by_a_resumed_run_are_left_out(tmp_path):
    pytest.importorskip("torch")
    log = curves.read_log(dqn_log(tmp_path / "run", steps=[1, 2, 3, 4, 2, 3, 4, 5]))
    assert log.superseded == 3
    assert list(log.columns["step"]) == [1, 2, 3, 4, 5]
    assert list(log.columns["mean_score"]) == [51, 52, 53, 54, 55]


def test_moving_mean():
    assert list(curves.moving_mean(np.arange(5.0), 3)) == [0.5, 1.0, 2.0, 3.0, 3.5]
    assert list(curves.moving_mean(np.arange(3.0), 1)) == [0.0, 1.0, 2.0]


BAD_LOGS = [
    ("", "is empty"),
    ("phase,step,loss\n", "has no rows"),
    ("phase,step,loss\nita,1,0.5\nita,2\n", "line 3 has 2 fields, the header 3"),
    ("phase,step,loss\nita,1,0.5\nita,2,abc\n", "line 3: loss 'abc' is not a number"),
    ("phase,step,loss\nita,1,0.5\nita,,0.4\n", "line 3: no step"),
    ("a,b\n1,2\n", "not a training log: no column 'step'"),
    ("phase,step,epsilon\ndqn,1,0.5\n", "nothing to plot"),
    (b"\x80\x02\x8a\nphase,step\n", "not a readable CSV file"),
]


@pytest.mark.parametrize("text, expected", BAD_LOGS)
def test_bad_training_log_is_one_message_and_exit_2(cli, tmp_path, text, expected):
    (tmp_path / "run").mkdir()
    log = tmp_path / "run" / "log.csv"
    log.write_bytes(text if isinstance(text, bytes) else text.encode())
    res = cli("report", tmp_path / "run")
    assert res.exit_code == 2, res.output
    out = flat(res.output)
    assert out.startswith("error:") and out.count("error:") == 1
    assert expected in out and str(log) in out
    assert "Traceback" not in res.output


def test_neither_an_evaluation_nor_a_training_folder(cli, tmp_path):
    (tmp_path / "empty").mkdir()
    for path in (tmp_path / "empty", tmp_path / "missing"):
        res = cli("report", path)
        assert res.exit_code == 2
        out = flat(res.output)
        assert out.count("error:") == 1 and "Traceback" not in res.output
        assert f"{path}: no such results file or training log" in out
        assert "results.csv" in out and "log.csv" in out
    write_results(tmp_path / "eval" / "results.csv")
    (tmp_path / "train").mkdir()
    (tmp_path / "train" / "log.csv").write_text("phase,step,loss\nita,1,0.5\n")
    res = cli("report", tmp_path / "eval", tmp_path / "train")
    assert res.exit_code == 2 and "a training run folder is reported alone" in flat(res.output)


# --- bad results files: one message, exit 2 -------------------------------------------------------

GOOD = ("method,setting,uncertainty,scenario,seed,score,upper_bound,fraction_of_u,"
        "classified_share\n"
        "greedy,a,low,1000,0,300.0,600.0,0.5,0.9\n"
        "greedy,a,low,1001,0,310.0,620.0,0.5,0.9\n"
        "random,a,low,1000,0,100.0,600.0,0.16,0.5\n"
        "random,a,low,1001,0,90.0,620.0,0.15,0.5\n")


@pytest.mark.parametrize("text, eval_rows, message", [
    (GOOD[:-20], None, "line 5 has fewer fields than the header: the file is cut short or garbled"),
    (GOOD.replace("310.0", "lots"), None, "line 3: score is 'lots', not a number"),
    (GOOD.replace("1000,0,300.0", "1000,x,300.0"), None, "line 2: seed is 'x', not a number"),
    (GOOD.replace("0.16", "abc"), None, "line 4: fraction_of_u is 'abc', not a number"),
    (GOOD + "random,a,low,1002,0,1,2,3,4,5\n", None,
     "line 6 has more fields than the header: the file is cut short or garbled"),
    (GOOD, 6, "holds 4 rows where eval.json says 6: the file is incomplete or was changed"),
])
def test_a_broken_results_file_is_one_error(cli, tmp_path, text, eval_rows, message):
    folder = tmp_path / "eval"
    folder.mkdir()
    (folder / "results.csv").write_text(text)
    if eval_rows is not None:
        (folder / "eval.json").write_text(json.dumps({"rows": eval_rows}))
    result = cli("report", folder, "--no-figures")
    assert result.exit_code == 2, result.output
    assert "Traceback" not in result.output
    assert " ".join(result.output.split()) == f"error: {folder / 'results.csv'}: {message}"


def test_a_sound_results_file_is_read(cli, tmp_path):
    folder = tmp_path / "eval"
    folder.mkdir()
    (folder / "results.csv").write_text(GOOD)
    (folder / "eval.json").write_text(json.dumps({"rows": 4}))
    result = cli("report", folder, "--no-figures")
    assert result.exit_code == 0, result.output


def test_training_report_shows_every_value_at_80_columns(tmp_path):
    """The per-phase summary is split into tables that fit; no value is cut short."""
    pytest.importorskip("torch")
    from typer.testing import CliRunner

    from ata.cli import app
    run = hrl_log(tmp_path / "run")
    result = CliRunner(env={"COLUMNS": "80"}).invoke(app, ["report", str(run), "--no-figures"])
    assert result.exit_code == 0, result.output
    lines = result.output.splitlines()
    assert max(len(line) for line in lines) <= 80 and "…" not in result.output
    header, rows = curves.curves_rows(curves.read_log(run))
    assert len(header) == 7 and rows[1][4] == "300.0 -> 290.0 (330.0 at 15)"
    for value in (v for row in rows for v in row):
        assert any(value in line for line in lines), value
