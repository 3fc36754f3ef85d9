"""Wall time of the paper's evaluation suite, broken down by method and team setting.

    ata eval examples/paper_suite.toml --cache CACHE -o DIR       # first run: the MILPs solve
    ata eval examples/paper_suite.toml --cache CACHE -o DIR2      # again: MILPs from the cache
    python benchmarks/bench_suite.py DIR [DIR2 ...]

For each folder: the elapsed wall time of the whole `ata eval` (eval.json), and per (method,
setting) the summed wall time of its chunks (each chunk's time in the worker that ran it, so the
per-method times add up to about workers x elapsed).
"""

from __future__ import annotations

import argparse
import csv
import json
from collections import defaultdict
from pathlib import Path


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
        print(f"| all (summed over workers) | " + " | ".join(
            f"{sum(v for (m, s), v in per.items() if s == st):.0f}" for st in settings)
            + f" | {total:.0f} |")


if __name__ == "__main__":
    main()
