"""Means of results.csv columns per (method, setting, level) of an evaluation: the counts the
docs quote beside the scores (re-briefs, re-plans, reallocations, the share classified, the
chunk time per scenario).

Usage: python tools/column_means.py EVAL_DIR COLUMN [COLUMN ...]
   e.g. python tools/column_means.py runs/suite classified_share reallocations rebriefs replans
"""

from __future__ import annotations

import sys

import numpy as np

from ata.experiment.report import md_table, read_results


def main(eval_dir: str, *columns: str) -> None:
    if not columns:
        raise SystemExit(__doc__)
    res = read_results(eval_dir)
    missing = [c for c in columns if c not in res.columns]
    if missing:
        raise SystemExit(f"{eval_dir}: no column {', '.join(missing)} in results.csv")
    rows = []
    for method in res.methods:
        for setting in res.settings:
            for level in res.levels:
                sel = res.select(method, setting, level)
                if sel.any():
                    rows.append([method, setting, level] + [
                        f"{np.asarray(res.columns[c][sel], dtype=float).mean():.3f}"
                        for c in columns])
    print("\n".join(md_table(["method", "setting", "level", *columns], rows)))


if __name__ == "__main__":
    main(*sys.argv[1:])
