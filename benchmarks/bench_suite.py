"""Wall time of the paper's evaluation suite, broken down by method and team setting.

    ata eval examples/paper_suite.toml --cache CACHE -o DIR       # first run: the MILPs solve
    ata eval examples/paper_suite.toml --cache CACHE -o DIR2      # again: MILPs from the cache
    python benchmarks/bench_suite.py DIR [DIR2 ...]

For each folder: the elapsed wall time of the whole `ata eval` (eval.json), and per (method,
setting) the summed wall time of its chunks (each chunk's time in the worker that ran it, so the
per-method times add up to about workers x elapsed).

`run_suite` runs the suite itself with an empty MILP cache (what bench_fast.py times).
"""

from __future__ import annotations

import argparse
import csv
import json
import shutil
import subprocess
import sys
import tempfile
import time
from collections import defaultdict
from pathlib import Path

SUITE = Path(__file__).resolve().parent.parent / "examples" / "paper_suite.toml"
SUITE_SCENARIOS = 500
"""Scenarios per cell of the paper's suite."""


def breakdown(run_dir: Path) -> tuple[float, dict[tuple[str, str], float], list[str]]:
    meta = json.loads((run_dir / "eval.json").read_text())
    per: dict[tuple[str, str], float] = defaultdict(float)
    methods: list[str] = []
    with open(run_dir / "results.csv", newline="") as f:
        for row in csv.DictReader(f):
            per[(row["method"], row["setting"])] += float(row["wall_s"])
            if row["method"] not in methods:
                methods.append(row["method"])
    return float(meta["wall_s"]), per, methods


def run_suite(scenarios: int, workers: int = 2) -> tuple[float, dict[tuple[str, str], float]]:
    """(wall seconds of the whole `ata eval` process, per-(method, setting) summed chunk
    seconds) of the paper's suite at `scenarios` per cell, `workers` workers, with an empty
    MILP cache (a fresh folder, deleted after)."""
    ata = shutil.which("ata") or str(Path(sys.executable).with_name("ata"))
    tmp = Path(tempfile.mkdtemp(prefix="bench_suite_"))
    try:
        t0 = time.perf_counter()
        out = subprocess.run([ata, "eval", str(SUITE), "-w", str(workers), "--scenarios",
                              str(scenarios), "--cache", str(tmp / "cache"), "-o",
                              str(tmp / "out"), "--quiet"], capture_output=True, text=True)
        if out.returncode != 0:
            raise RuntimeError(f"ata eval failed: {out.stderr[-2000:]}")
        wall = time.perf_counter() - t0
        _, per, _ = breakdown(tmp / "out")
        return wall, dict(per)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("dirs", nargs="+", type=Path, help="`ata eval` output folders")
    args = parser.parse_args()
    for d in args.dirs:
        wall, per, methods = breakdown(d)
        settings = sorted({s for _, s in per})
        print(f"\n{d}: elapsed {wall / 60:.1f} min")
        print("| method | " + " | ".join(f"setting {s} (s)" for s in settings) + " | total (s) |")
        print("|---|" + "---:|" * (len(settings) + 1))
        for m in methods:
            cells = [per.get((m, s), 0.0) for s in settings]
            print(f"| {m} | " + " | ".join(f"{c:.0f}" for c in cells) + f" | {sum(cells):.0f} |")
        total = sum(per.values())
        print("| all (summed over workers) | " + " | ".join(
            f"{sum(v for (m, s), v in per.items() if s == st):.0f}" for st in settings)
            + f" | {total:.0f} |")


if __name__ == "__main__":
    main()
