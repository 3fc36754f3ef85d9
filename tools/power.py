"""How many scenarios a paired comparison needs before its drawn-score CI can clear 0.

For one method against a base, in every (setting, level) of an evaluation: the paired difference
in drawn points (`score`) and in expected points (`expected_score`, the same mean without the
noise of the outcome draws), each with its standard deviation over scenarios, and the number of
scenarios at which a 95% CI of the *drawn* difference would exclude 0 if the true difference
were the expected-points estimate: n = (1.96 sd_drawn / mean_expected)^2.

Usage: python tools/power.py EVAL_DIR METHOD BASE
"""

from __future__ import annotations

import sys

import numpy as np

from ata.experiment.report import paired_values, read_results


def rows(eval_dir: str, method: str, base: str) -> list[dict[str, float | str]]:
    r = read_results(eval_dir)
    out = []
    for setting in r.settings:
        for level in r.levels:
            ref, sel = r.select(base, setting, level), r.select(method, setting, level)
            b, v = paired_values(r, ref, sel, "score")
            be, ve = paired_values(r, ref, sel, "expected_score")
            d, de = v - b, ve - be
            sd = d.std(ddof=1)
            need = (1.96 * sd / de.mean()) ** 2 if de.mean() > 0 else float("inf")
            out.append({"setting": setting, "level": level, "n": len(d),
                        "drawn": d.mean(), "drawn_ci": 1.96 * sd / np.sqrt(len(d)), "drawn_sd": sd,
                        "expected": de.mean(), "expected_ci": 1.96 * de.std(ddof=1) / np.sqrt(len(d)),
                        "expected_sd": de.std(ddof=1), "needed": need})
    return out


def main(eval_dir: str, method: str, base: str) -> None:
    print(f"{method} - {base}: paired, mean +- 1.96 SE (sd over scenarios)")
    print("| cell | n | drawn | expected | scenarios for a drawn CI above 0 |")
    print("|---|---:|---:|---:|---:|")
    for c in rows(eval_dir, method, base):
        need = "never (expected <= 0)" if c["needed"] == float("inf") else f"{c['needed']:.0f}"
        print(f"| ({c['setting']}) {c['level']} | {c['n']} | {c['drawn']:+.1f} +- {c['drawn_ci']:.1f} "
              f"(sd {c['drawn_sd']:.0f}) | {c['expected']:+.1f} +- {c['expected_ci']:.1f} "
              f"(sd {c['expected_sd']:.0f}) | {need} |")


if __name__ == "__main__":
    if len(sys.argv) != 4:
        sys.exit(__doc__)
    main(*sys.argv[1:4])
