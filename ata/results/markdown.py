"""The tables of docs/RESULTS.md from an evaluation, in Markdown (`ata report DIR --markdown`):
every method's score, the paired differences the suite names, and the time per scenario with
the machine that ran it."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from ata.results.report import default_pairs, md_table
from ata.results.rows import (BOOTSTRAP_SEED, RESAMPLES, Results, bootstrap_ci, nanmean,
                                    paired_values)
from ata.results.seeds import has_seeds, plain_methods, seed_markdown
from ata.runtime.machine import machine_text


def results_markdown(res: Results, pairs: list[tuple[str, str]] | None = None,
                     resamples: int = RESAMPLES, seed: int = BOOTSTRAP_SEED,
                     made_on: list[str] = (), column: str = "score") -> str:
    """The three tables of docs/RESULTS.md, in Markdown, a column per (setting, level): every
    method's mean score [95% bootstrap CI] (mean fraction of U), the paired differences A - B
    on the same scenarios, mean [95% bootstrap CI], in bold where the interval is above 0 (the
    numbers of `summarize` with A as the reference), and every method's mean time per scenario
    (`made_on`: the machines and workers that ran it, one line each). The paired differences
    are of `column` (default the drawn score; ``expected_score``: the expected points). Pairs
    naming a method the results lack are left out; `pairs` defaults to `default_pairs`. A
    training seed's rows (a method ``NAME seed S``) are in the tables across seeds that follow
    (`seeds.seed_markdown`), not in these."""
    groups = [(s, lv) for s in res.settings for lv in res.levels]
    columns = [f"({s}) {lv}" for s, lv in groups]
    c = res.columns
    # a training seed's rows (`NAME seed S`) are read across seeds, in the tables after these
    methods = plain_methods(res.methods)
    rows = []
    for m in methods:
        row = [res.label(m)]
        for s, lv in groups:
            sel = res.select(m, s, lv)
            if not sel.any():
                row.append("-")
                continue
            mean, low, high = bootstrap_ci(c["score"][sel], resamples, seed=seed)
            row.append(f"{mean:.1f} [{low:.0f}, {high:.0f}] "
                       f"({nanmean(c['fraction_of_u'][sel]):.2f} U)")
        rows.append(row)
    lines = ["Mean total team performance [95% bootstrap CI] (mean fraction of U):", "",
             *md_table(["method", *columns], rows), ""]
    rows = []
    for a, b in default_pairs(res) if pairs is None else pairs:
        if a not in methods or b not in methods:
            continue
        row = [f"{res.label(a)} - {res.label(b)}"]
        for s, lv in groups:
            va, vb = paired_values(res, res.select(a, s, lv), res.select(b, s, lv), column)
            if not va.size:                          # not run, or no paired scenarios
                row.append("-")
                continue
            mean, low, high = bootstrap_ci(va - vb, resamples, seed=seed)
            mark = "**" if low > 0 else ""
            row.append(f"{mark}{mean:+.1f} [{low:+.1f}, {high:+.1f}]{mark}")
        rows.append(row)
    what = "" if column == "score" else f" of `{column}`"
    lines += [f"Paired differences{what}, A - B on the same scenarios, mean [95% bootstrap CI] "
              "(bold: the interval is above 0):", "",
              *md_table(["paired difference", *columns], rows)]
    if has_seeds(res):
        lines += ["", *seed_markdown(res, default_pairs(res) if pairs is None else pairs,
                                     resamples, column)][:-1]
    if "wall_s" in c:
        rows = [[res.label(m)] + [fmt_time(c["wall_s"][res.select(m, s, lv)]) for s, lv in groups]
                for m in methods]
        lines += ["", "Time per scenario, seconds (the mean of `wall_s`: each work unit's wall "
                  "time shared among its scenarios; a method's first unit pays for its imports "
                  "and weights)" + (", made on " + "; ".join(made_on) if made_on else "") + ":",
                  "", *md_table(["method", *columns], rows)]
    return "\n".join(lines) + "\n"


def made_on(folders: list[Path]) -> list[str]:
    """Each evaluation folder's machine and worker count, as its eval.json records them
    (`ata.runtime.machine.machine`), one distinct line each; folders of no record are left out."""
    out: list[str] = []
    for folder in folders:
        path = Path(folder) / "eval.json"
        try:
            meta = json.loads(path.read_text(encoding="utf-8"))
        except (OSError, ValueError):
            continue
        if isinstance(meta.get("machine"), dict):
            workers = (meta.get("arguments") or {}).get("executor", {}).get("workers")
            line = machine_text(meta["machine"]) + (f", {workers} worker processes"
                                                    if workers else "")
            out += [line] if line not in out else []
    return out


def fmt_time(values: np.ndarray) -> str:
    """A mean time in seconds to about three significant digits; '-' for none."""
    values = values[np.isfinite(values)] if values.size else values
    if not values.size:
        return "-"
    mean = float(values.mean())
    return f"{mean:.3f}" if mean < 1 else f"{mean:.2f}" if mean < 10 else f"{mean:.1f}"
