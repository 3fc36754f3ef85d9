"""The tables of docs/RESULTS.md from `ata eval` output folders.

Usage: python tools/results_tables.py RUN_DIR [RUN_DIR ...]

Prints, in markdown: every method's mean total team performance with its 95% percentile-bootstrap
interval and its mean fraction of U, per setting and uncertainty level; then the paired
differences the issue's goals name (A - B on the same scenarios, mean [95% bootstrap CI]). The
bootstrap is `ata report`'s (2000 resamples, fixed seed), so the figures match its report.md.
"""

from __future__ import annotations

import sys

import numpy as np

from ata.core.report import _paired, bootstrap_ci, read_results

PAIRS = [("ATA-HRL", "greedy"), ("ATA-HRL", "ATA-HRL (learned off)"), ("ATA-HRL", "w/o.AUX"),
         ("ATA-HRL", "w/o.C"), ("AtRL-TR", "TR-POMDP"), ("ATA-HRL", "ITA-MILP"),
         ("ATA-HRL", "AtRL-TR"), ("ATA-HRL", "TR-POMDP"), ("AtRL-TR", "ITA-MILP")]


def main(dirs: list[str]) -> None:
    res = read_results(dirs if len(dirs) > 1 else dirs[0])
    groups = [(s, lv) for s in res.settings for lv in res.levels]
    score = res.columns["score"]
    head = "| method | " + " | ".join(f"({s}) {lv}" for s, lv in groups) + " |"
    print(head)
    print("|---|" + "---:|" * len(groups))
    for m in res.methods:
        cells = []
        for s, lv in groups:
            sel = res.select(m, s, lv)
            if not sel.any():
                cells.append("-")
                continue
            mean, low, high = bootstrap_ci(score[sel])
            frac = float(np.nanmean(res.columns["fraction_of_u"][sel]))
            cells.append(f"{mean:.1f} [{low:.0f}, {high:.0f}] ({frac:.2f} U)")
        print(f"| {m} | " + " | ".join(cells) + " |")
    print()
    print("| paired difference | " + " | ".join(f"({s}) {lv}" for s, lv in groups) + " |")
    print("|---|" + "---:|" * len(groups))
    for a, b in PAIRS:
        if a not in res.methods or b not in res.methods:
            continue
        cells = []
        for s, lv in groups:
            x, y = _paired(res, res.select(a, s, lv), res.select(b, s, lv))
            if x.size == 0:
                cells.append("-")
                continue
            mean, low, high = bootstrap_ci(x - y)
            mark = "**" if low > 0 else ""
            cells.append(f"{mark}{mean:+.1f} [{low:+.1f}, {high:+.1f}]{mark}")
        print(f"| {a} - {b} | " + " | ".join(cells) + " |")


if __name__ == "__main__":
    if len(sys.argv) < 2:
        sys.exit(__doc__)
    main(sys.argv[1:])
