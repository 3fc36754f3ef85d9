"""Every method of one evaluation against one method of another, paired on the same (setting,
level, scenario): the mean difference +- 1.96 standard errors, per cell. For variants named
otherwise than the suite row they are compared with ("w/o.AUX, fresh task rows" against the
suite's "w/o.AUX").

Usage: python tools/round6/pair_with.py EVAL_DIR BASE_DIR BASE_METHOD [COLUMN]   (COLUMN: score
by default, or e.g. expected_score)
"""

from __future__ import annotations

import sys

import numpy as np

from ata.experiment.report import read_results


def rows(path: str, column: str) -> dict[tuple[str, str, str, int], float]:
    c = read_results(path).columns
    return {(m, s, lv, int(sc)): float(v) for m, s, lv, sc, v in
            zip(c["method"], c["setting"], c["uncertainty"], c["scenario"], c[column])}


def main(eval_dir: str, base_dir: str, base_method: str, column: str = "score") -> None:
    new, base = rows(eval_dir, column), rows(base_dir, column)
    cells: dict[tuple[str, str, str], list[float]] = {}
    for (m, s, lv, sc), v in new.items():
        ref = base.get((base_method, s, lv, sc))
        if ref is not None:
            cells.setdefault((m, s, lv), []).append(v - ref)
    if not cells:
        sys.exit(f"no scenario of {eval_dir} is in {base_dir} under {base_method!r}")
    print(f"| method - {base_method} | setting | level | scenarios | {column} (+- 1.96 SE) |")
    print("|---|---:|---:|---:|---:|")
    for (m, s, lv), d in cells.items():
        d = np.asarray(d)
        se = d.std(ddof=1) / np.sqrt(len(d)) if len(d) > 1 else 0.0
        print(f"| {m} | {s} | {lv} | {len(d)} | {d.mean():+.1f} +- {1.96 * se:.1f} |")


if __name__ == "__main__":
    if len(sys.argv) < 4:
        sys.exit(__doc__)
    main(*sys.argv[1:5])
