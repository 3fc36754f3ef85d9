"""The tables of docs/RESULTS.md from `ata eval` output folders.

Usage: python tools/results_tables.py RUN_DIR [RUN_DIR ...]

Prints, in markdown: every method's mean total team performance with its 95% percentile-bootstrap
interval and its mean fraction of U, per setting and uncertainty level; then the paired
differences the issue's goals name (A - B on the same scenarios, mean [95% bootstrap CI]). The
bootstrap is `ata report`'s (2000 resamples, fixed seed), so the figures match its report.md.
"""

from __future__ import annotations

import math
import sys

from ata.experiment.report import md_table, read_results, summarize

PAIRS = [("ATA-HRL", "greedy"), ("ATA-HRL", "ATA-HRL (learned off)"), ("ATA-HRL", "w/o.AUX"),
         ("ATA-HRL", "w/o.C"), ("AtRL-TR", "TR-POMDP"), ("ATA-HRL", "ITA-MILP"),
         ("ATA-HRL", "AtRL-TR"), ("ATA-HRL", "TR-POMDP"), ("AtRL-TR", "ITA-MILP")]


def main(dirs: list[str]) -> None:
    res = read_results(dirs if len(dirs) > 1 else dirs[0])
    groups = [(s, lv) for s in res.settings for lv in res.levels]
    # one report per reference: its cells hold every method's mean and CI, and the paired
    # difference reference - method
    refs = {a for a, _ in PAIRS if a in res.methods} | {res.methods[0]}
    cells = {ref: {(c.method, c.setting, c.level): c for c in summarize(res, ref).cells}
             for ref in refs}
    first = cells[res.methods[0]]
    columns = [f"({s}) {lv}" for s, lv in groups]
    rows = []
    for m in res.methods:
        row = [m]
        for s, lv in groups:
            c = first.get((m, s, lv))
            row.append("-" if c is None else
                       f"{c.mean:.1f} [{c.low:.0f}, {c.high:.0f}] ({c.fraction_of_u:.2f} U)")
        rows.append(row)
    print("\n".join(md_table(["method", *columns], rows)))
    print()
    rows = []
    for a, b in PAIRS:
        if a not in res.methods or b not in res.methods:
            continue
        row = [f"{a} - {b}"]
        for s, lv in groups:
            c = cells[a].get((b, s, lv))
            if c is None or math.isnan(c.diff[0]):      # not run, or no paired scenarios
                row.append("-")
                continue
            mean, low, high = c.diff
            mark = "**" if low > 0 else ""
            row.append(f"{mark}{mean:+.1f} [{low:+.1f}, {high:+.1f}]{mark}")
        rows.append(row)
    print("\n".join(md_table(["paired difference", *columns], rows)))


if __name__ == "__main__":
    if len(sys.argv) < 2:
        sys.exit(__doc__)
    main(sys.argv[1:])
