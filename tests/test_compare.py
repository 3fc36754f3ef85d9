"""Result folders read as one (a later folder's cells replacing an earlier one's), `ata compare`
(paired differences on any column, the scenarios a CI needs, column means; one folder or two,
evaluations or plain runs), `ata report --markdown` (the tables of docs/RESULTS.md), and every
table whole at 80 columns. Exact answers on small hand-made folders."""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from _support import assert_user_error, flat
from ata.cli import app
from ata.core.errors import MissionError
from ata.results import compare as cmp
from ata.results import report as rep
from ata.experiment.evaluate import CORE_COLUMNS
from ata.results.rows import bootstrap_ci, read_results

HEADER = CORE_COLUMNS + ["expected_score"]


def folder(path: Path, rows: list[tuple], pairs: list | None = None) -> Path:
    """An evaluation folder: rows (method, setting, level, scenario, score[, expected]); the
    upper bound is 100, so the fraction of U is score / 100."""
    path.mkdir(parents=True)
    with open(path / "results.csv", "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(HEADER)
        for m, s, lv, sc, score, *expected in rows:
            w.writerow([m, s, lv, sc, 0, score, 100.0, score / 100.0, 0.5, sc % 3, 0.1,
                        expected[0] if expected else score])
    meta = {"rows": len(rows)}
    if pairs is not None:
        meta["suites"] = [{"path": "s.toml", "name": "s",
                           "content": {"suite": {"pairs": pairs}}}]
    (path / "eval.json").write_text(json.dumps(meta))
    return path


def run_folder(path: Path, name: str, scores: list[float], uncertainty: str = "medium") -> Path:
    """A plain `ata run` folder: results.csv without method columns, and its resolved mission."""
    path.mkdir(parents=True)
    with open(path / "results.csv", "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["scenario", "score", "upper_bound", "fraction_of_u", "reallocations"])
        for i, score in enumerate(scores):
            w.writerow([i, score, 100.0, score / 100.0, i])
    (path / "mission.resolved.toml").write_text(
        f'[mission]\nname = "{name}"\nsetting = "a"\nuncertainty = "{uncertainty}"\n'
        'seed = 0\n')
    return path


def cli80(*args) -> tuple[int, str]:
    result = CliRunner(env={"COLUMNS": "80"}).invoke(app, [str(a) for a in args])
    return result.exit_code, result.output


# -- several folders read as one ------------------------------------------------------------------
def test_a_later_folder_replaces_its_cells_in_place(cli, tmp_path):
    base = folder(tmp_path / "base", [("A", "a", "low", i, 10.0) for i in range(3)]
                  + [("A", "b", "low", i, 20.0) for i in range(3)]
                  + [("B", "b", "low", i, 30.0) for i in range(3)])
    new = folder(tmp_path / "new", [("A", "b", "low", i, 25.0 + i) for i in range(2)]
                 + [("C", "a", "low", 0, 1.0)])
    res = read_results([base, new])
    c = res.columns
    got = list(zip(c["method"], c["setting"], c["scenario"].tolist(), c["score"].tolist()))
    assert got == [("A", "a", 0, 10.0), ("A", "a", 1, 10.0), ("A", "a", 2, 10.0),
                   ("A", "b", 0, 25.0), ("A", "b", 1, 26.0),          # the rerun, in place
                   ("B", "b", 0, 30.0), ("B", "b", 1, 30.0), ("B", "b", 2, 30.0),
                   ("C", "a", 0, 1.0)]                                 # a new cell: added
    assert res.replaced == [("A", "b", "low")]
    assert res.methods == ["A", "B", "C"]
    out = cli("report", base, new, "--no-figures", "--reference", "A")
    assert out.exit_code == 0, out.output
    assert "cells taken from a later folder: A (b, low)" in flat(out.output)
    assert "| A | 2 | 25.5 [25.0, 26.0] |" in (base / "report.md").read_text()
    assert "Cells taken from a later folder read together with the first: A (b, low)." in \
        (base / "report.md").read_text()


def test_a_folder_named_twice_or_a_row_twice_is_an_error(cli, tmp_path):
    one = folder(tmp_path / "one", [("A", "a", "low", 0, 1.0)])
    assert_user_error(cli("report", one, one, "--no-figures"), f"error: {one}: is named twice")
    two = folder(tmp_path / "two", [("A", "a", "low", 0, 1.0), ("A", "a", "low", 0, 2.0)])
    assert_user_error(cli("compare", two), f"error: {two}: a (method, setting, uncertainty, "
                                           "scenario) appears twice")


@pytest.mark.parametrize("text", ["nan", "inf", "-inf", ""])
def test_a_score_that_is_not_finite_is_refused(cli, tmp_path, text):
    path = folder(tmp_path / "ev", [("A", "a", "low", 0, 1.0), ("A", "a", "low", 1, 2.0)])
    rows = (path / "results.csv").read_text().splitlines()
    rows[2] = rows[2].replace(",2.0,", f",{text},", 1)
    (path / "results.csv").write_text("\n".join(rows) + "\n")
    what = "a finite number"
    assert_user_error(cli("report", path, "--no-figures"),
                      f"{path / 'results.csv'}: line 3: score is {text!r}, not {what}")


# -- paired differences ---------------------------------------------------------------------------
GREEDY = [10.0, 20.0, 30.0, 40.0]
SCORES = {"greedy": GREEDY, "ATA-HRL": [s + 12.5 for s in GREEDY], "w/o.AUX": GREEDY,
          "random": [15.0, 10.0, 40.0, 20.0]}


def suite_folder(path: Path, scores=SCORES, shift: float = 0.0, **kw) -> Path:
    """SCORES at (a, low) and, 7 points lower, at (b, high); greedy's rows in reverse order."""
    rows = []
    for m, values in scores.items():
        for s, lv, d in (("a", "low", 0.0), ("b", "high", -7.0)):
            block = [(m, s, lv, 100 + i, v + d + shift, v + d + shift + 1.0)
                     for i, v in enumerate(values)]
            rows += block[::-1] if m == "greedy" else block
    return folder(path, rows, **kw)


def test_compare_one_folder_each_method_against_greedy(cli, tmp_path):
    ev = suite_folder(tmp_path / "ev")
    tables = cmp.compare(read_results(ev), None, ["score"])
    assert [(t.setting, t.level, t.what) for t in tables] == [
        ("a", "low", "method - greedy, paired"), ("b", "high", "method - greedy, paired")]
    # random - greedy = (15 - 10, 10 - 20, 40 - 30, 20 - 40), in greedy's row order (reversed)
    lo = bootstrap_ci([-20.0, 10.0, -10.0, 5.0])
    assert tables[0].header == ["method", "paired", "differing in score",
                                "score difference [95% CI]"]
    assert tables[0].rows == [["ATA-HRL", "4", "4", "+12.5 [+12.5, +12.5]"],
                              ["w/o.AUX", "4", "0", "+0.0 [+0.0, +0.0]"],
                              ["random", "4", "4",
                               f"{lo[0]:+.1f} [{lo[1]:+.1f}, {lo[2]:+.1f}]"]]
    assert tables[1].rows == tables[0].rows                    # the same differences at (b)
    out = cli("compare", ev, "--base", "ATA-HRL", "--methods", "greedy", "-c", "expected_score",
              "--full")
    assert out.exit_code == 0, out.output
    assert "setting a, low uncertainty: method - ATA-HRL, paired" in flat(out.output)
    assert "│ greedy │ 4 │ 4 │ -12.5 [-12.5, -12.5] │" in flat(out.output)
    assert_user_error(cli("compare", ev, "--base", "nobody"), "--base: no method 'nobody'")
    assert_user_error(cli("compare", ev, "-c", "colour"), "--column: no numeric column "
                      "'colour' in the results of the first folder; columns: score,")
    assert_user_error(cli("compare", ev, "-c", "method"), "no numeric column 'method'")
    assert_user_error(cli("compare", ev, ev, ev), "compares one folder")
    assert_user_error(cli("compare", ev, "--power", "--means"), "--power or --means")


def test_compare_two_evaluations_method_by_method(cli, tmp_path):
    a = suite_folder(tmp_path / "a", shift=2.0)
    # B lacks ATA-HRL's scenario 103 at (a, low): 3 pairs there
    rows = [r for r in csv.reader(open(suite_folder(tmp_path / "b0") / "results.csv"))]
    b = folder(tmp_path / "b", [(r[0], r[1], r[2], int(r[3]), float(r[5]), float(r[11]))
                                for r in rows[1:] if r[:4] != ["ATA-HRL", "a", "low", "103"]])
    tables = cmp.compare(read_results(a), read_results(b), ["score", "expected_score"])
    assert tables[0].what == "A - B, paired"
    two = "+2.00 [+2.00, +2.00]"                  # below 10: two decimals
    assert tables[0].rows == [["greedy", "4", "4", two, two], ["ATA-HRL", "3", "3", two, two],
                              ["w/o.AUX", "4", "4", two, two], ["random", "4", "4", two, two]]
    assert tables[1].rows[1][:2] == ["ATA-HRL", "4"]
    # each method of A against B's greedy
    tables = cmp.compare(read_results(a), read_results(b), ["score"], base="greedy",
                         methods=["ATA-HRL", "greedy"])
    assert tables[0].what == "A's method - B's greedy, paired"
    assert tables[0].rows == [["greedy", "4", "4", "+2.0 [+2.0, +2.0]"],
                              ["ATA-HRL - greedy", "4", "4", "+14.5 [+14.5, +14.5]"]]
    other = folder(tmp_path / "other", [("X", "a", "low", 100, 1.0), ("X", "b", "low", 100, 1.0)])
    assert_user_error(cli("compare", a, other, "--full"),
                      "no method of the first folder is in the second")


def test_compare_two_plain_runs(cli, tmp_path):
    a = run_folder(tmp_path / "a", "greedy", [10.0, 20.0, 30.0])
    b = run_folder(tmp_path / "b", "random", [4.0, 20.0, 0.0])
    tables = cmp.compare(read_results(a), read_results(b), ["score", "reallocations"])
    low = bootstrap_ci([6.0, 0.0, 30.0])
    assert [(t.setting, t.level, t.what) for t in tables] == [("a", "medium", "A - B, paired")]
    assert tables[0].rows == [["greedy - random", "3", "2",
                               f"{low[0]:+.1f} [{low[1]:+.1f}, {low[2]:+.1f}]",
                               "+0.000 [+0.000, +0.000]"]]    # digits per column
    # two runs at other levels still pair: each folder is one cell
    c = run_folder(tmp_path / "c", "greedy", [11.0, 21.0, 31.0], uncertainty="high")
    assert cmp.compare(read_results(c), read_results(a), ["score"])[0].rows == [
        ["greedy", "3", "3", "+1.00 [+1.00, +1.00]"]]
    out = cli("report", a, b, "--no-figures", "--reference", "greedy")
    assert out.exit_code == 0, out.output
    assert "| random | 3 | 8.0 [" in (a / "report.md").read_text()


def test_compare_two_real_runs_of_ata_run(cli, tmp_path):
    mission = tmp_path / "tiny.toml"
    mission.write_text('[mission]\nname = "tiny"\nscenarios = 3\n')
    assert cli("run", mission, "-q", "-o", tmp_path / "a").exit_code == 0
    assert cli("run", mission, "-q", "-o", tmp_path / "b", "--set",
               "components.condition=never").exit_code == 0
    with open(tmp_path / "a" / "results.csv", newline="") as f:
        moves = [float(r["reallocations"]) for r in csv.DictReader(f)]
    tables = cmp.compare(read_results(tmp_path / "a"), read_results(tmp_path / "b"),
                         ["reallocations"])
    mean, low, high = bootstrap_ci(moves)             # `never` never reallocates
    d = 1 if max(map(abs, (mean, low, high))) >= 10 else 2
    assert tables[0].rows == [["tiny", "3", str(sum(m != 0 for m in moves)),
                               f"{mean:+.{d}f} [{low:+.{d}f}, {high:+.{d}f}]"]]


# -- power and means ------------------------------------------------------------------------------
def test_power_gives_the_scenarios_a_ci_needs_at_the_expected_difference(cli, tmp_path):
    drawn = [30.0, -10.0, 20.0, 0.0]      # B - A in drawn points, per scenario
    expected = [2.0, 4.0, 1.0, 5.0]       # and in expected points: mean 3 (low), -3 (high)
    rows = []
    for lv, sign in (("low", 1.0), ("high", -1.0)):
        for i in range(4):
            rows += [("A", "a", lv, i, 100.0, 90.0),
                     ("B", "a", lv, i, 100.0 + drawn[i], 90.0 + sign * expected[i])]
    ev = folder(tmp_path / "ev", rows)
    sd = float(np.std(drawn, ddof=1))
    assert cmp.power_needed(np.array(drawn), np.array(expected)) == \
        pytest.approx((1.959964 * sd / 3.0) ** 2, rel=1e-12)
    assert cmp.power_needed(np.array(drawn), -np.array(expected)) == math.inf
    tables = cmp.compare(read_results(ev), None, ["score"], base="A", power=True)
    assert tables[0].header == ["method", "paired", "score difference ± 1.96 SE (sd)",
                                "expected_score difference ± 1.96 SE (sd)",
                                "scenarios for a score CI above 0"]
    half = 1.959964 * sd / 2.0
    e_sd = float(np.std(expected, ddof=1))
    assert tables[0].rows == [["B", "4", f"+10.0 ± {half:.1f} (sd {sd:.0f})",
                               f"+3.0 ± {1.959964 * e_sd / 2:.1f} (sd {e_sd:.0f})",
                               f"{(1.959964 * sd / 3.0) ** 2:.0f}"]]
    assert tables[1].rows[0][-1] == "never (estimate <= 0)"
    out = cli("compare", ev, "--power", "--base", "A", "--markdown")
    assert out.exit_code == 0, out.output
    assert out.output.splitlines()[:4] == [
        "### method - A, paired", "",
        "| method | cell | paired | score difference ± 1.96 SE (sd) | expected_score "
        "difference ± 1.96 SE (sd) | scenarios for a score CI above 0 |",
        "|---|---:|---:|---:|---:|---:|"]


def test_means_per_method_and_cell(cli, tmp_path):
    ev = suite_folder(tmp_path / "ev")
    tables = cmp.mean_tables([("ev", read_results(ev))], ["score", "reallocations"])
    assert tables[0].header == ["method", "rows", "score, mean", "reallocations, mean"]
    # reallocations: scenario % 3 of 100..103 = 1, 2, 0, 1
    assert tables[0].rows == [["greedy", "4", "25.000", "1.000"],
                              ["ATA-HRL", "4", "37.500", "1.000"],
                              ["w/o.AUX", "4", "25.000", "1.000"],
                              ["random", "4", "21.250", "1.000"]]
    assert tables[1].rows[0] == ["greedy", "4", "18.000", "1.000"]
    other = suite_folder(tmp_path / "other", shift=1.0)
    tables = cmp.mean_tables([("ev", read_results(ev)), ("other", read_results(other))],
                             ["score"], methods=["greedy"])
    assert tables[0].rows == [["greedy", "ev", "4", "25.000"], ["greedy", "other", "4", "26.000"]]
    out = cli("compare", ev, "--means", "-c", "nothere")
    assert_user_error(out, "--column: no numeric column 'nothere' in the results of ")


# -- the tables of docs/RESULTS.md ----------------------------------------------------------------
def test_report_markdown_prints_the_results_tables(cli, tmp_path):
    ev = folder(tmp_path / "ev", [(m, "a", "low", i, v) for m, v in (("ATA-HRL", 30.0),
                                                                      ("greedy", 20.0))
                                  for i in range(3)], pairs=[["greedy", "ATA-HRL"],
                                                             ["greedy", "nobody"]])
    table = ("| method | (a) low |\n|---|---:|\n| ATA-HRL | 30.0 [30, 30] (0.30 U) |\n"
             "| greedy | 20.0 [20, 20] (0.20 U) |\n")
    head = ("Paired differences, A - B on the same scenarios, mean [95% bootstrap CI] (bold: "
            "the interval is above 0):\n\n| paired difference | (a) low |\n|---|---:|\n")
    lead = "Mean total team performance [95% bootstrap CI] (mean fraction of U):\n\n"
    # every row's wall_s is 0.1; the machine is the one eval.json records, with the workers
    times = ("\nTime per scenario, seconds (the mean of `wall_s`: each work unit's wall time "
             "shared among its scenarios; a method's first unit pays for its imports and "
             "weights), made on CPU X, 8 cores (python 3.11.7; torch 2.13.0), 2 worker "
             "processes:\n\n| method | (a) low |\n|---|---:|\n| ATA-HRL | 0.100 |\n"
             "| greedy | 0.100 |\n")
    meta = json.loads((ev / "eval.json").read_text())
    meta["machine"] = {"cpu": "CPU X", "cores": 8, "python": "3.11.7", "torch": "2.13.0"}
    meta["arguments"] = {"executor": {"executor": "process", "workers": 2}}
    (ev / "eval.json").write_text(json.dumps(meta))
    # the suite's pairs (one naming a method the results lack: left out)
    out = cli("report", ev, "--markdown")
    assert out.exit_code == 0, out.output
    assert out.output == (lead + table + "\n" + head
                          + "| greedy - ATA-HRL | -10.0 [-10.0, -10.0] |\n" + times)
    assert not (ev / "report.md").exists()
    # --pair instead; bold where the interval is above 0
    out = cli("report", ev, "--markdown", "--pair", "ATA-HRL,greedy")
    assert out.output == lead + table + "\n" + head + \
        "| ATA-HRL - greedy | **+10.0 [+10.0, +10.0]** |\n" + times
    # the paired table of another column names it
    out = cli("report", ev, "--markdown", "--pair", "ATA-HRL,greedy", "-c", "expected_score")
    assert "Paired differences of `expected_score`, A - B" in out.output
    assert "| ATA-HRL - greedy | **+10.0 [+10.0, +10.0]** |" in out.output
    assert_user_error(cli("report", ev, "--markdown", "-c", "nothere"),
                      "--column: no numeric column 'nothere'")
    assert_user_error(cli("report", ev, "--markdown", "--pair", "ATA-HRL"),
                      "--pair: names two methods")
    # without pairs: the reference against every other method
    (ev / "eval.json").write_text(json.dumps({"rows": 6}))
    assert rep.default_pairs(read_results(ev)) == [("ATA-HRL", "greedy")]


def test_suite_pairs_are_read_and_checked(tmp_path):
    from ata.experiment.suites import load_suite
    path = tmp_path / "s.toml"
    path.write_text('[suite]\npairs = [["ATA-HRL", "greedy"]]\n[[method]]\nname = "g"\n'
                    'mission = "builtin:greedy"\n')
    assert load_suite(path).raw["suite"]["pairs"] == [["ATA-HRL", "greedy"]]
    path.write_text('[suite]\npairs = ["ATA-HRL"]\n[[method]]\nname = "g"\n'
                    'mission = "builtin:greedy"\n')
    with pytest.raises(MissionError, match=r"\[suite\] key 'pairs': must be a list of \[A, B\]"):
        load_suite(path)


# -- 80 columns -----------------------------------------------------------------------------------
def assert_whole_at_80(output: str, values: list[str]) -> None:
    """No line over 80 characters, nothing cut short, and every value on one line, whole."""
    lines = output.splitlines()
    assert max(len(line) for line in lines) <= 80, output
    assert "…" not in output
    for value in values:
        assert any(value in line for line in lines), f"{value!r} not shown whole in\n{output}"


WIDE = {"ATA-HRL": 700.0, "ATA-HRL (learned off)": 600.0, "ITA-MILP": 650.0, "greedy": 640.0,
        "w/o.AUX": 690.0}


def test_report_and_compare_show_every_value_at_80_columns(tmp_path):
    rows = [(m, s, lv, i, v + 37.3 * i - (300.0 if m == "greedy" and i % 2 else 0.0))
            for m, v in WIDE.items() for s in "ab" for lv in ("low", "high") for i in range(5)]
    ev = folder(tmp_path / "ev", rows)
    code, output = cli80("report", ev, "--no-figures")
    assert code == 0, output
    report = rep.summarize(read_results(ev))
    values = [v for s, lv in report.groups() for row in rep.table_rows(report, s, lv, True)[1]
              for v in row]
    assert_whole_at_80(output, values)
    three = ["score", "expected_score", "fraction_of_u"]
    for columns, power in ((["score"], False), (["score"], True), (three, False)):
        args = [a for c in columns for a in ("-c", c)] + (["--power"] if power else [])
        code, output = cli80("compare", ev, *args, "--full")
        assert code == 0, output
        tables = cmp.compare(read_results(ev), None, columns, power=power)
        assert_whole_at_80(output, [v for t in tables for row in t.rows for v in row])
    for columns in (["score"], three):              # the default: a table per cell
        code, output = cli80("compare", ev, *[a for c in columns for a in ("-c", c)])
        assert code == 0, output
        tables = cmp.leaderboards(read_results(ev), None, columns)
        assert len(tables) == 4 * len(columns)
        assert_whole_at_80(output, [v for t in tables for row in t.rows for v in row])
    code, output = cli80("compare", ev, "--means", "-c", "score", "-c", "expected_score",
                         "-c", "classified_share", "-c", "reallocations")
    assert code == 0, output
    assert_whole_at_80(output, [v for t in cmp.mean_tables(
        [("ev", read_results(ev))], ["score", "expected_score", "classified_share",
                                     "reallocations"]) for row in t.rows for v in row])


def test_eval_shows_every_value_at_80_columns(tmp_path, monkeypatch):
    monkeypatch.setenv("ATA_CACHE", str(tmp_path / "cache"))
    suite = tmp_path / "s.toml"
    suite.write_text('[suite]\nsettings = ["a"]\nuncertainty = ["high"]\nscenarios = 2\n'
                     '[[method]]\nname = "greedy (on-event reallocation)"\n'
                     'mission = "builtin:greedy"\n'
                     '[[method]]\nname = "greedy, never reallocating"\nmission = "builtin:greedy"\n'
                     'set = ["components.condition=\'never\'"]\n')
    code, output = cli80("eval", suite, "-e", "serial", "-q", "-o", tmp_path / "out")
    assert code == 0, output
    report = rep.summarize(read_results(tmp_path / "out"))
    assert_whole_at_80(output, [v for row in rep.table_rows(report, "a", "high", True)[1]
                                for v in row])


def test_compare_of_a_folder_of_one_method_says_what_to_give(cli, tmp_path):
    out = tmp_path / "one"
    assert cli("run", "builtin:greedy", "-n", "2", "--set", "mission.horizon_s=600", "-q",
               "-o", str(out)).exit_code == 0
    result = cli("compare", str(out))
    assert result.exit_code == 2
    assert "this folder holds one method: give a second folder" in " ".join(result.output.split())


# -- the default: one compact table per cell against a base ---------------------------------------
def test_the_default_is_a_table_per_cell_of_every_method_against_greedy(cli, tmp_path):
    ev = suite_folder(tmp_path / "ev")
    tables = cmp.leaderboards(read_results(ev), None, ["score"])
    assert [(t.setting, t.level) for t in tables] == [("a", "low"), ("b", "high")]
    assert tables[0].title == ("setting a, low uncertainty: score, 4 paired scenarios, against "
                               "greedy")
    assert tables[0].header == ["method", "score [95% CI]", "method - base [95% CI]",
                                "P(beats base)"]
    # greedy's rows reversed: its order pairs them, (103, 102, 101, 100)
    mean = [bootstrap_ci(v) for v in ([40.0, 30.0, 20.0, 10.0], [52.5, 42.5, 32.5, 22.5],
                                      [20.0, 40.0, 10.0, 15.0])]
    diff = bootstrap_ci([-20.0, 10.0, -10.0, 5.0])          # random - greedy
    assert mean[2][1:] == (12.5, 33.75) and diff[1:] == (-15.0, 7.5)   # half-widths >= 10: 0 dp
    assert tables[0].rows == [
        ["greedy", "25 [15, 35]", "base", "-"],
        ["ATA-HRL", "38 [28, 48]", "+12.5 [+12.5, +12.5]", "1.00"],   # a point: by its size
        ["w/o.AUX", "25 [15, 35]", "+0.0 [+0.0, +0.0]", "0.50"],      # every scenario a tie
        ["random", "21 [12, 34]", "-4 [-15, +8]", "0.50"]]            # 2 of 4 above greedy
    assert [r[2:] for r in tables[1].rows] == [r[2:] for r in tables[0].rows]
    # --base, --methods (the base shown all the same), and the CLI's table
    tables = cmp.leaderboards(read_results(ev), None, ["score"], base="random",
                              methods=["ATA-HRL"])
    assert [r[0] for r in tables[0].rows] == ["random", "ATA-HRL"]
    out = cli("compare", ev)
    assert out.exit_code == 0, out.output
    assert "setting a, low uncertainty: score, 4 paired scenarios, against greedy" in \
        flat(out.output)
    assert "│ ATA-HRL │ 38 [28, 48] │ +12.5 [+12.5, +12.5] │ 1.00 │" in flat(out.output)
    assert "differing in score" not in out.output            # the full tables: --full
    assert_user_error(cli("compare", ev, "--base", "nobody"), "--base: no method 'nobody'")


def test_the_default_of_two_folders_shows_both_against_one_base(cli, tmp_path):
    new = suite_folder(tmp_path / "new", shift=2.0)
    old = suite_folder(tmp_path / "old")
    tables = cmp.leaderboards(read_results(new), read_results(old), ["score"])
    t = tables[0]
    assert t.title.endswith("against greedy (B)")          # B's greedy: the names are in both
    assert [r[0] for r in t.rows] == ["greedy (A)", "ATA-HRL (A)", "w/o.AUX (A)", "random (A)",
                                      "greedy (B)", "ATA-HRL (B)", "w/o.AUX (B)", "random (B)"]
    assert t.sections == [3]                                 # a rule after A's methods
    assert t.rows[0][2:] == ["+2.00 [+2.00, +2.00]", "1.00"]
    assert t.rows[4][2:] == ["base", "-"]
    out = cli("compare", new, old)
    assert out.exit_code == 0, out.output
    assert f"A: {new}; B: {old}" in flat(out.output)
    # two runs of one cell each, at other levels: greedy is the base wherever it is
    a = run_folder(tmp_path / "a", "greedy", [10.0, 20.0, 30.0])
    b = run_folder(tmp_path / "b", "random", [4.0, 20.0, 0.0], uncertainty="high")
    t = cmp.leaderboards(read_results(b), read_results(a), ["score"])[0]
    assert (t.setting, t.level) == ("a", "high - medium")
    assert t.rows == [["random", "8 [0, 20]", "-12 [-30, +0]", "0.17"],
                      ["greedy", "20 [10, 30]", "base", "-"]]
    # the scenarios are A's (4 of B's 6); a method of B with fewer says so in a column n
    rows = [("greedy", "a", "low", i, 10.0 + i) for i in range(6)] + \
        [("mine", "a", "low", i, 12.0 + i) for i in range(6)] + \
        [("other", "a", "low", i, 9.0) for i in range(2)]
    short = folder(tmp_path / "short", [r for r in rows if r[0] == "mine" and r[3] < 4])
    t = cmp.leaderboards(read_results(short), read_results(folder(tmp_path / "six", rows)),
                         ["score"])[0]
    assert t.title == "setting a, low uncertainty: score, against greedy"
    assert t.header[:2] == ["method", "n"]
    assert [r[:2] for r in t.rows] == [["mine (A)", "4"], ["greedy", "4"], ["mine (B)", "4"],
                                       ["other", "2"]]
    assert t.rows[0][3:] == ["+2.00 [+2.00, +2.00]", "1.00"]


# -- a run against the shipped published rows: a screen per cell ---------------------------------
def test_a_run_against_the_published_rows_prints_a_screen_per_cell_at_80_columns(tmp_path,
                                                                               monkeypatch):
    """`ata compare RUN published` of a one-method run: one table per cell, each at most 40
    lines, no line over 80 columns (it was 505 lines, 77 tables, 11 split in two)."""
    from ata.published import sets as published
    theirs, manifest, _ = published.read_published("published")
    rows = []
    for cell in sorted({c for e in manifest["methods"].values() for c in e["cells"]}):
        setting, level = cell.split("/")
        sel = theirs.select("greedy", setting, level)
        ids = theirs.columns["scenario"][sel][:20]
        scores = theirs.columns["score"][sel][:20]
        rows += [("mine", setting, level, int(i), float(s) + 3.0 * (k % 5))
                 for k, (i, s) in enumerate(zip(ids, scores))]
    mine = folder(tmp_path / "mine", rows)
    # what is printed is the subject here; the pairing's checks have tests of their own
    monkeypatch.setattr(published, "check_pairing", lambda *args, **kwargs: None)
    code, output = cli80("compare", mine, "published")
    assert code == 0, output
    lines = output.splitlines()
    assert max(len(line) for line in lines) <= 80, output
    titles = [k for k, line in enumerate(lines) if "uncertainty: score" in line]
    assert len(titles) == 6, output
    # each cell's table ends where the next table's title starts (the published set's training
    # seeds follow, in the tables across seeds: not in the cells' tables)
    any_title = [k for k, line in enumerate(lines) if "uncertainty:" in line] + [len(lines)]
    for start in titles:
        end = next(k for k in any_title if k > start)
        assert end - start <= 40, "\n".join(lines[start:end])
        assert not any(" seed " in line for line in lines[start:end])
    # the published seeds are named, their tables one option away
    assert "holds training seeds (NAME seed S) of ATA-HRL, w/o.AUX, w/o.C, TR-POMDP, AtRL-TR" \
        in flat(output) and "--full adds" in output
    assert sum("(1 of 2)" in line for line in lines[:any_title[6]]) == 0   # no cell split in two
    assert "published rows of paper@" in flat(output) and "(published:paper;" in flat(output)
    assert str(published.PUBLISHED) not in output                     # no path of this machine
    plain = [m for m in theirs.methods if " seed " not in m]
    table = cmp.leaderboards(read_results(mine), theirs, ["score"], tags=("A", "published"),
                             b_methods=plain)[0]
    assert [r[0] for r in table.rows][:2] == ["mine", "ATA-HRL"] and len(table.rows) == 12
    assert next(r for r in table.rows if r[0] == "greedy")[2:] == ["base", "-"]
    # the whole matrix stays behind --full
    code, full = cli80("compare", mine, "published", "--full")
    assert code == 0 and len(full.splitlines()) > 3 * len(lines)
