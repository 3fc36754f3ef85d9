"""Paired differences within one evaluation: every method against a base method (default the
suite's first) on the same scenarios, per (setting, level): mean score and the mean difference
+- 1.96 standard errors.

Usage: python tools/longer_ita/paired.py EVAL_DIR [BASE_METHOD] [COLUMN]   (COLUMN: score by
default, or e.g. expected_score; EVAL_DIR may be several folders joined by commas, read as
one evaluation as `ata report` reads several)
"""

from __future__ import annotations

import sys

import numpy as np

from ata.experiment.report import paired_values, read_results


def main(eval_dir: str, base: str | None = None, column: str = "score") -> None:
    dirs = eval_dir.split(",")
    r = read_results(dirs if len(dirs) > 1 else dirs[0])
    base = base or r.methods[0]
    for setting in r.settings:
        for level in r.levels:
            ref = r.select(base, setting, level)
            cells = []
            for m in r.methods:
                b, v = paired_values(r, ref, r.select(m, setting, level), column)
                d = v - b
                se = d.std(ddof=1) / np.sqrt(len(d)) if len(d) > 1 else 0.0
                cells.append(f"{m} {v.mean():.1f} ({d.mean():+.1f} +- {1.96 * se:.1f})")
            print(setting, level, " | ".join(cells))


if __name__ == "__main__":
    main(*sys.argv[1:4])
