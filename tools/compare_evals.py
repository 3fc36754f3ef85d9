"""Paired differences between two evaluations of the same methods on the same scenarios: for
every (method, setting, level) in both, the mean of (score in A - score in B) over the scenario
ids both hold, with 1.96 standard errors, and how many of those scenarios differ at all. For
comparing two sets of weights run under the same method names (docs/training.md, "Setting
(b)"). COLUMN (default score) names another
results.csv column to compare, e.g. expected_score: the score in expectation over the
classification outcomes, far less noisy for comparisons (docs/evaluation.md). BASE_METHOD pairs
every method of A with that one method of B instead, for variants named otherwise than the row
they are compared with ("w/o.AUX + arrivals" against the suite's "w/o.AUX").

Usage: python tools/compare_evals.py EVAL_DIR_A EVAL_DIR_B [COLUMN [BASE_METHOD]]
"""

from __future__ import annotations

import sys

import numpy as np

from ata.experiment.report import md_table, read_results


def main(a_dir: str, b_dir: str, column: str = "score", base_method: str | None = None) -> None:
    a, b = read_results(a_dir), read_results(b_dir)
    rows = []
    for method in a.methods:
        for setting in a.settings:
            for level in a.levels:
                scores = [dict(zip(res.columns["scenario"][sel].tolist(),
                                   np.asarray(res.columns[column][sel], dtype=float)))
                          for res, m in ((a, method), (b, base_method or method))
                          for sel in [res.select(m, setting, level)]]
                common = sorted(set(scores[0]) & set(scores[1]))
                if not common:
                    continue
                d = np.array([scores[0][i] - scores[1][i] for i in common])
                half = 1.96 * d.std(ddof=1) / np.sqrt(d.size) if d.size > 1 else float("nan")
                rows.append([method, setting, level, str(d.size), str(int((d != 0).sum())),
                             f"{d.mean():+.1f} ± {half:.1f}"])
    print("\n".join(md_table(["method", "setting", "level", "scenarios", "differing",
                              "A - B (± 1.96 SE)"], rows)))


if __name__ == "__main__":
    if len(sys.argv) not in (3, 4, 5):
        sys.exit(__doc__)
    main(*sys.argv[1:5])
