"""tools/replace_cells.py: an evaluation with some cells taken from a rerun, read by `ata report`
as any evaluation; tools/power.py: the scenarios a paired drawn-score CI needs."""

from __future__ import annotations

import csv
import json
import subprocess
import sys
from pathlib import Path

from ata.experiment.report import read_results

TOOL = Path(__file__).resolve().parents[1] / "tools" / "replace_cells.py"
HEADER = ["method", "setting", "uncertainty", "scenario", "seed", "score", "upper_bound",
          "fraction_of_u", "classified_share", "reallocations", "wall_s"]


def folder(path: Path, rows: list[tuple]) -> Path:
    path.mkdir()
    with open(path / "results.csv", "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(HEADER)
        for m, s, lv, sc, score in rows:
            w.writerow([m, s, lv, sc, 0, score, 100.0, score / 100.0, 0.5, 1, 0.1])
    (path / "eval.json").write_text(json.dumps({"rows": len(rows)}))
    return path


def run(*args) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, str(TOOL), *map(str, args)], capture_output=True,
                          text=True)


def test_replace_cells_takes_the_rerun_cells_and_keeps_the_rest(tmp_path):
    base = folder(tmp_path / "base", [("A", "a", "low", i, 10.0) for i in range(3)]
                  + [("A", "b", "low", i, 20.0) for i in range(3)]
                  + [("B", "b", "low", i, 30.0) for i in range(3)])
    new = folder(tmp_path / "new", [("A", "b", "low", i, 25.0 + i) for i in range(3)])
    proc = run(base, new, tmp_path / "out")
    assert proc.returncode == 0, proc.stderr
    res = read_results(tmp_path / "out")
    c = res.columns
    got = {(m, s, int(sc)): float(v) for m, s, sc, v in
           zip(c["method"], c["setting"], c["scenario"], c["score"])}
    assert len(got) == 9
    assert [got[("A", "b", i)] for i in range(3)] == [25.0, 26.0, 27.0]    # from the rerun
    assert [got[("A", "a", i)] for i in range(3)] == [10.0] * 3             # kept
    assert [got[("B", "b", i)] for i in range(3)] == [30.0] * 3
    meta = json.loads((tmp_path / "out" / "eval.json").read_text())
    assert meta["rows"] == 9 and meta["replaced_cells"] == [["A", "b", "low"]]


def test_replace_cells_refuses_a_cell_of_another_size_or_not_in_the_base(tmp_path):
    base = folder(tmp_path / "base", [("A", "a", "low", i, 10.0) for i in range(3)])
    short = folder(tmp_path / "short", [("A", "a", "low", 0, 1.0)])
    proc = run(base, short, tmp_path / "out")
    assert proc.returncode != 0 and "has 1 rows" in proc.stderr
    other = folder(tmp_path / "other", [("C", "a", "low", i, 1.0) for i in range(3)])
    proc = run(base, other, tmp_path / "out2")
    assert proc.returncode != 0 and "not in" in proc.stderr
    assert not (tmp_path / "out").exists() and not (tmp_path / "out2").exists()


def load_tool(name: str):
    import importlib.util
    spec = importlib.util.spec_from_file_location(name, TOOL.parent / f"{name}.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_power_gives_the_scenarios_a_drawn_ci_needs_at_the_expected_difference(tmp_path):
    """tools/power.py: paired drawn and expected differences, and n = (1.96 sd / mean)^2."""
    path = tmp_path / "ev"
    path.mkdir()
    drawn_b = [30.0, -10.0, 20.0, 0.0]      # B - A in drawn points, per scenario
    exp_b = [2.0, 4.0, 1.0, 5.0]            # and in expected points
    with open(path / "results.csv", "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(HEADER + ["expected_score"])
        for lv, sign in (("low", 1.0), ("high", -1.0)):
            for i in range(4):
                w.writerow(["A", "a", lv, i, 0, 100.0, 1000.0, 0.1, 0.5, 1, 0.1, 90.0])
                w.writerow(["B", "a", lv, i, 0, 100.0 + drawn_b[i], 1000.0, 0.1, 0.5, 1, 0.1,
                            90.0 + sign * exp_b[i]])
    (path / "eval.json").write_text(json.dumps({"rows": 16}))
    got = {c["level"]: c for c in load_tool("power").rows(str(path), "B", "A")}
    import numpy as np
    sd = np.std(drawn_b, ddof=1)
    low = got["low"]
    assert low["n"] == 4 and low["drawn"] == np.mean(drawn_b) and low["expected"] == 3.0
    assert abs(low["needed"] - (1.96 * sd / 3.0) ** 2) < 1e-9
    assert abs(low["drawn_ci"] - 1.96 * sd / 2.0) < 1e-9
    assert got["high"]["expected"] == -3.0 and got["high"]["needed"] == float("inf")
