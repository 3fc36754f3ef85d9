"""`ata report`: the paired-difference figure of an evaluation and the learning curves of a
training run folder (the numbers against a hand computation, the files written, bad input), and
the report's tables, bootstrap intervals and beat probabilities."""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path

import numpy as np
import pytest

from _support import flat
from ata.results import curves, training_report
from ata.results import rows as results
from ata.results import report as rep
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
    assert training_report.is_training_folder(run)
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


# -- the tables of `ata report`: bootstrap CIs, beat probabilities, the command -----------------
def test_bootstrap_ci_known_answers():
    assert results.bootstrap_ci(np.full(50, 3.5)) == (3.5, 3.5, 3.5)
    mean, low, high = results.bootstrap_ci([7.0])
    assert mean == low == high == 7.0
    assert all(math.isnan(x) for x in results.bootstrap_ci([]))
    x = np.random.default_rng(1).normal(10.0, 2.0, 4000)
    mean, low, high = results.bootstrap_ci(x)
    half = 1.959964 * x.std(ddof=1) / math.sqrt(x.size)
    assert mean == pytest.approx(x.mean())
    assert low == pytest.approx(mean - half, abs=0.15 * half)
    assert high == pytest.approx(mean + half, abs=0.15 * half)
    assert results.bootstrap_ci(x) == (mean, low, high)        # a fixed seed: the same every time


def test_beat_probability():
    assert results.beat_probability([10, 20, 30, 40], [5, 20, 35, 10]) == 0.625
    assert results.beat_probability([1, 1], [1, 1]) == 0.5
    assert math.isnan(results.beat_probability([], []))




def write_three_methods(path: Path) -> None:
    """ATA-HRL, greedy and w/o.AUX at settings a and b, three levels, four scenarios; greedy's
    rows at (a, low) are written in reverse order, so pairs must be matched by scenario id."""
    rows = []
    scores = {"ATA-HRL": [10, 20, 30, 40], "greedy": [5, 20, 35, 10], "w/o.AUX": [0, 0, 50, 50]}
    for method, base in scores.items():
        for setting in ("a", "b"):
            for k, level in enumerate(("low", "medium", "high")):
                block = []
                for i, s in enumerate(base):
                    score = s - 2 * k if setting == "a" else s + 1
                    block.append({"method": method, "setting": setting, "uncertainty": level,
                                  "scenario": 100 + i, "seed": 0, "score": score,
                                  "upper_bound": 100.0, "fraction_of_u": score / 100.0,
                                  "classified_share": 0.5, "reallocations": 1, "wall_s": 0.1})
                if (method, setting, level) == ("greedy", "a", "low"):
                    block.reverse()
                rows += block
    write_csv(path, CORE_COLUMNS, rows)


def test_report_table_and_probabilities(tmp_path):
    write_three_methods(tmp_path / "results.csv")
    report = rep.summarize(results.read_results(tmp_path))
    assert report.reference == "ATA-HRL"
    assert report.groups() == [(s, lv) for s in "ab" for lv in ("low", "medium", "high")]
    cells = {(c.method, c.setting, c.level): c for c in report.cells}
    assert cells[("greedy", "a", "low")].beats == 0.625      # 1 + 0.5 + 0 + 1 of 4
    assert cells[("w/o.AUX", "a", "low")].beats == 0.5       # 1 + 1 + 0 + 0 of 4
    assert math.isnan(cells[("ATA-HRL", "a", "low")].beats)
    assert cells[("ATA-HRL", "b", "high")].mean == 26.0
    assert cells[("greedy", "a", "low")].fraction_of_u == pytest.approx(0.175)
    other = rep.summarize(results.read_results(tmp_path), reference="greedy")
    flipped = {(c.method, c.setting, c.level): c for c in other.cells}
    assert flipped[("ATA-HRL", "a", "low")].beats == 0.375
    # the paired difference, matched by scenario id (greedy's rows are reversed at (a, low)):
    # ATA-HRL - greedy = (10 - 5, 20 - 20, 30 - 35, 40 - 10) = (5, 0, -5, 30), mean 7.5, its
    # bootstrap CI within the differences' range
    mean, low, high = cells[("greedy", "a", "low")].diff
    assert mean == 7.5 and -5.0 <= low < mean < high <= 30.0
    assert all(math.isnan(x) for x in cells[("ATA-HRL", "a", "low")].diff)
    header, rows = rep.table_rows(report, "a", "low")
    assert "ATA-HRL - method, paired [95% CI]" in header
    assert rows[1][6].startswith("+7.5 [")


def test_report_command_writes_markdown_and_figures(cli, tmp_path):
    pytest.importorskip("matplotlib")
    write_three_methods(tmp_path / "results.csv")
    res = cli("report", tmp_path)
    assert res.exit_code == 0, res.output
    text = flat(res.output)
    assert "setting a, low uncertainty" in text and "P(ATA-HRL beats)" in text
    assert "0.625" in text
    md = (tmp_path / "report.md").read_text()
    assert "## Setting b, high uncertainty" in md
    assert "| greedy | 4 | 17.5 [" in md and "| 0.625 |" in md
    figs = sorted(p.name for p in tmp_path.glob("fig_*"))
    assert figs == sorted(f"{stem}.{ext}" for stem in ("fig_setting_a", "fig_setting_b",
                                                       "fig_ablations", "fig_paired")
                          for ext in ("png", "svg"))
    assert all((tmp_path / f).stat().st_size > 1000 for f in figs)


def test_report_options_and_errors(cli, tmp_path):
    write_three_methods(tmp_path / "results.csv")
    res = cli("report", tmp_path, "--no-figures", "--reference", "greedy")
    assert res.exit_code == 0, res.output
    assert "P(greedy beats)" in flat(res.output)
    assert not list(tmp_path.glob("fig_*"))
    res = cli("report", tmp_path, "--no-figures", "--reference", "nobody")
    assert res.exit_code == 2 and "no method 'nobody'" in flat(res.output)
    res = cli("report", tmp_path / "missing")
    assert res.exit_code == 2 and "no such results file" in flat(res.output)


def test_report_skips_absent_figures(tmp_path):
    pytest.importorskip("matplotlib")
    write_three_methods(tmp_path / "all.csv")
    with open(tmp_path / "all.csv", newline="") as f:
        rows = [r for r in csv.DictReader(f) if r["setting"] == "a" and r["method"] != "w/o.AUX"]
    write_csv(tmp_path / "results.csv", CORE_COLUMNS, rows)
    rep.write_report(tmp_path)
    assert sorted(p.name for p in tmp_path.glob("fig_*")) == ["fig_paired.png",
                                                             "fig_paired.svg",
                                                             "fig_setting_a.png",
                                                             "fig_setting_a.svg"]


def test_report_reads_several_evaluations_together(cli, tmp_path):
    write_three_methods(tmp_path / "all.csv")
    with open(tmp_path / "all.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    for name, keep in (("one", lambda r: r["method"] != "greedy"),
                       ("two", lambda r: r["method"] == "greedy")):
        (tmp_path / name).mkdir()
        write_csv(tmp_path / name / "results.csv", CORE_COLUMNS, [r for r in rows if keep(r)])
    merged = rep.summarize(results.read_results([tmp_path / "one", tmp_path / "two"]))
    whole = rep.summarize(results.read_results(tmp_path / "all.csv"))
    key = lambda c: (c.method, c.setting, c.level)  # noqa: E731
    assert sorted(map(key, merged.cells)) == sorted(map(key, whole.cells))
    assert {key(c): c.beats for c in merged.cells if c.method == "greedy"} == \
        {key(c): c.beats for c in whole.cells if c.method == "greedy"}
    res = cli("report", tmp_path / "one", tmp_path / "two", "--no-figures")
    assert res.exit_code == 0 and (tmp_path / "one" / "report.md").exists()
    res = cli("report", tmp_path / "one", tmp_path / "one", "--no-figures")
    assert res.exit_code == 2 and f"{tmp_path / 'one'}: is named twice" in flat(res.output)
