"""Paired differences of the methods of one eval folder against a base method of another,
over the scenarios both ran (same setting, level and scenario id): mean ± 1.96 SE per cell.

Usage: python tools/round9/pair_with.py NEW_DIR BASE_DIR BASE_METHOD [COLUMN...]
(COLUMN: default expected_score, score and reallocations)
"""

from __future__ import annotations

import csv
import sys
from collections import defaultdict
from pathlib import Path

import numpy as np


def rows(folder: str) -> list[dict]:
    with open(Path(folder) / "results.csv", newline="") as f:
        return list(csv.DictReader(f))


def main(argv: list[str]) -> None:
    if len(argv) < 3:
        sys.exit(__doc__)
    new_dir, base_dir, base_method = argv[:3]
    columns = argv[3:] or ["expected_score", "score", "reallocations"]
    base = {(r["setting"], r["uncertainty"], r["scenario"]): r for r in rows(base_dir)
            if r["method"] == base_method}
    cells = defaultdict(list)
    for r in rows(new_dir):
        key = (r["setting"], r["uncertainty"], r["scenario"])
        if key in base:
            cells[(r["method"], r["setting"], r["uncertainty"])].append((r, base[key]))
    if not cells:
        sys.exit(f"no scenario of {new_dir} is among {base_method}'s in {base_dir}")
    for (method, setting, level), pairs in cells.items():
        parts = []
        for col in columns:
            d = np.array([float(a[col]) - float(b[col]) for a, b in pairs])
            half = 1.96 * d.std(ddof=1) / np.sqrt(len(d)) if len(d) > 1 else float("nan")
            parts.append(f"{col} {d.mean():+.2f} ± {half:.2f}")
        print(f"{method} {setting} {level} (n {len(pairs)}): " + ", ".join(parts))


if __name__ == "__main__":
    main(sys.argv[1:])
