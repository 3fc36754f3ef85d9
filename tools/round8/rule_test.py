"""Whole episodes with pi_C's decisions changed by rules fitted on flip labels (cond_labels.py).

A weighted logistic rule per kind of epoch (event, quiet), on pi_C's ten condition features,
is fitted on the label files; at each epoch it flips ATA-HRL's decision where it gives the flip
a probability above 1/2 of gaining. Runs N selection scenarios from id FIRST (root seed
99000017; take ids the label files do not hold) and prints expected points against the method
as it is (paired, mean ± 1.96 SE) and the reallocations per scenario. A diagnostic: no shipped
component uses these rules.

Usage: python tools/round8/rule_test.py SETTING LEVEL FILE[,FILE...] FIRST N [LABEL [MODES]]
LABEL: d_exp (expected points, default) or d_rc (the paper's R_C). MODES (comma-separated,
default all): base, rule (both kinds of epoch), rule_event (event epochs only), rule_quiet,
always, never.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from cond_labels import _logistic, load, play, session  # noqa: E402

MODES = ("base", "rule", "rule_event", "rule_quiet", "always", "never")


def fit_rules(d: dict, label: str) -> dict:
    """(mean, scale, weights) of the logistic rule of each kind of epoch."""
    F, y = d["feats"][:, :10], d[label]
    rules = {}
    for kind, m in (("event", d["base_choice"]), ("quiet", ~d["base_choice"])):
        mu, sd = F[m].mean(0), F[m].std(0) + 1e-9
        rules[kind] = (mu, sd, _logistic((F[m] - mu) / sd, (y[m] > 0).astype(float),
                                         np.abs(y[m])))
    return rules


def decide(mode: str, rules: dict, cond, taken: np.ndarray) -> np.ndarray:
    """The decision of `mode` given ATA-HRL's own (`taken`) and its policy's features."""
    if mode in ("always", "never"):
        return np.full_like(taken, mode == "always")
    out = taken.copy()
    event = cond.cond_prior > 0
    for kind, m in (("event", event), ("quiet", ~event)):
        if mode not in ("rule", f"rule_{kind}"):
            continue
        mu, sd, b = rules[kind]
        X = (cond.cond_feats - mu) / sd
        p = 1.0 / (1.0 + np.exp(-(np.c_[X, np.ones(len(X))] @ b)))
        out = np.where(m & (p > 0.5), ~taken, out)
    return out


def run(s, ids: np.ndarray, mode: str, rules: dict) -> tuple[np.ndarray, np.ndarray]:
    """(expected points, reallocations) per scenario."""
    n_realloc = np.zeros(len(ids))

    def count(cond, ctx, k, active):
        n_realloc[:] += active

    change = (lambda cond, k, active: active) if mode == "base" else \
        (lambda cond, k, active: decide(mode, rules, cond, active))
    record = play(s, ids, change, count)
    return record.metrics["expected_score"], n_realloc


def main(argv: list[str]) -> None:
    if len(argv) < 5:
        sys.exit(__doc__)
    setting, level, files, first, n = argv[0], argv[1], argv[2].split(","), int(argv[3]), \
        int(argv[4])
    label = argv[5] if len(argv) > 5 else "d_exp"
    modes = argv[6].split(",") if len(argv) > 6 else MODES
    rules = fit_rules(load(files), label)
    s = session(setting, level, 99000017)
    ids = np.arange(first, first + n)
    base = None
    for mode in ("base",) + tuple(m for m in modes if m != "base"):
        parts = [run(s, ids[i:i + 50], mode, rules) for i in range(0, n, 50)]
        score = np.concatenate([p[0] for p in parts])
        realloc = np.concatenate([p[1] for p in parts])
        base = score if base is None else base
        diff = score - base
        print(f"{mode:11s} expected {score.mean():7.1f}, - base {diff.mean():+6.2f} ± "
              f"{1.96 * diff.std(ddof=1) / np.sqrt(n):.2f}, reallocations {realloc.mean():.1f}",
              flush=True)


if __name__ == "__main__":
    main(sys.argv[1:])
