"""benchmarks/bench_recipes.py: a finished folder's measured training time, and the held-out
paired difference of new weights against published rows (the recipes' timing itself is a
benchmark, run by hand: docs/training.md)."""

import csv
import json
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))

import bench_recipes  # noqa: E402
from ata.published import sets  # noqa: E402
from ata.results.rows import read_results  # noqa: E402


def test_a_folder_of_seeds_gives_the_mean_of_its_measured_times(tmp_path):
    (tmp_path / "seeds.json").write_text(json.dumps({"seeds": [0, 1]}))
    for seed, wall in ((0, 600.0), (1, 900.0)):
        (tmp_path / f"seed-{seed}").mkdir()
        (tmp_path / f"seed-{seed}" / "trained.json").write_text(json.dumps(
            {"wall_s": wall, "counters": {"ita": 800, "ctr": 30, "episodes": 99}}))
    minutes, how = bench_recipes.trained_time(tmp_path)
    assert minutes == pytest.approx(12.5) and "mean of 2 seeds (longest 15.0 min)" in how
    assert "(800 ita, 30 ctr steps)" in how
    (tmp_path / "seed-1" / "trained.json").unlink()
    with pytest.raises(SystemExit, match="has not finished"):
        bench_recipes.trained_time(tmp_path)


def rows(path: Path, methods: dict) -> Path:
    path.mkdir()
    with open(path / "results.csv", "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["method", "setting", "uncertainty", "scenario", "seed", "score",
                    "upper_bound", "fraction_of_u", "classified_share", "expected_score"])
        for m, values in methods.items():
            for i, v in enumerate(values):
                w.writerow([m, "a", "medium", 2**40 + i, 0, v + 50, 100, 0.5, 0.5, v])
    return path


def test_new_weights_are_paired_with_the_published_method_on_expected_points(
        tmp_path, monkeypatch, capsys):
    base = np.random.default_rng(1).normal(40, 5, 12)
    mine = rows(tmp_path / "mine", {"new seed 0": base + 1, "new seed 1": base + 3})
    theirs = read_results(rows(tmp_path / "pub", {"ATA-HRL": base, "greedy": base - 5}))
    monkeypatch.setattr(sets, "read_published", lambda name: (theirs, {}, "SET"))
    monkeypatch.setattr(sets, "check_pairing", lambda *a: None)
    bench_recipes.paired(mine, "ATA-HRL")
    out = capsys.readouterr().out
    assert "(expected_score, SET)" in out
    assert "new - ATA-HRL | 2 / 1 | 12 | +2.0 [" in out and "| 1.00" in out
    assert "greedy" not in out


def test_repeats_judge_the_median_of_the_recipe_s_extrapolations(monkeypatch, capsys):
    totals = iter([14.0, 16.0, 15.2])          # minutes of three repeats, in turn
    firsts = []

    def estimate(*calls, first_step=0):
        firsts.append(first_step)
        return [("ITA steps", 1.0, 1, 1, next(totals) * 60)]
    monkeypatch.setattr(bench_recipes.bench_training, "recipe_estimate", estimate)
    monkeypatch.setattr(sys, "argv", ["bench_recipes.py", "--only", "ata_hrl", "--repeats", "3",
                                      "--no-warm-up"])
    bench_recipes.main()
    out = capsys.readouterr().out
    assert "[ata_hrl 3/3] ITA steps" in out
    [row] = [line for line in out.splitlines() if line.strip().startswith("ATA-HRL (a)")]
    assert row.split()[2] == "15.2" and "median of 3 extrapolations" in row   # not 14.0 or 16.0
    assert firsts == [0, 6, 12]                 # each repeat times the next 6 ITA steps
