"""`ata report`: the tables and figures of an evaluation folder (`ata eval`'s results.csv).

Per (team setting, uncertainty level) and method: the mean total team performance with its 95%
percentile-bootstrap confidence interval over scenarios, the mean fraction of the upper bound U,
the share of POIs classified, the paired difference reference - method on the same scenarios
(the same setting, level, seed and scenario id) with its 95% bootstrap confidence interval, and
P(reference beats method): the share of those paired scenarios where the reference scores more,
ties counting half.
"""

from __future__ import annotations

import csv
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ata.core.errors import MissionError
from ata.core.mission import UNCERTAINTY_LEVELS

DEFAULT_REFERENCE = "ATA-HRL"
RESAMPLES = 2000
BOOTSTRAP_SEED = 20240601
"""The bootstrap's fixed seed: a report is the same every time it is made."""
ABLATION_PREFIX = "w/o"


def bootstrap_ci(values: Any, resamples: int = RESAMPLES, level: float = 0.95,
                 seed: int = BOOTSTRAP_SEED) -> tuple[float, float, float]:
    """(mean, low, high): the mean and its percentile-bootstrap confidence interval.

    Draws `resamples` resamples of the values with replacement (one matrix, no Python loop) and
    takes the (1 - level) / 2 and (1 + level) / 2 quantiles of their means. NaN for no values.
    """
    v = np.asarray(values, dtype=float).ravel()
    if v.size == 0:
        return float("nan"), float("nan"), float("nan")
    mean = float(v.mean())
    if v.size == 1:
        return mean, mean, mean
    gen = np.random.default_rng(seed)
    idx = gen.integers(0, v.size, size=(resamples, v.size))
    means = v[idx].mean(axis=1)
    low, high = np.quantile(means, [(1.0 - level) / 2.0, (1.0 + level) / 2.0])
    return mean, float(low), float(high)


def beat_probability(reference: Any, other: Any) -> float:
    """Share of pairs where reference > other; ties count half. NaN for no pairs."""
    r, o = np.asarray(reference, dtype=float), np.asarray(other, dtype=float)
    if r.size == 0:
        return float("nan")
    return float(np.mean((r > o) + 0.5 * (r == o)))


# -- results ------------------------------------------------------------------------------------
@dataclass
class Results:
    """results.csv as columns, with the methods, settings and levels in report order."""

    columns: dict[str, np.ndarray]
    methods: list[str]
    settings: list[str]
    levels: list[str]

    def select(self, method: str, setting: str, level: str) -> np.ndarray:
        c = self.columns
        return (c["method"] == method) & (c["setting"] == setting) & (c["uncertainty"] == level)


REQUIRED = ("method", "setting", "uncertainty", "scenario", "seed", "score", "upper_bound",
            "fraction_of_u", "classified_share")


def level_key(level: str) -> tuple[int, str]:
    order = list(UNCERTAINTY_LEVELS)
    return (order.index(level) if level in order else len(order), level)


def _read_one(path: str | Path) -> tuple[list[dict[str, str]], list[str]]:
    path = Path(path)
    if path.is_dir():
        path = path / "results.csv"
    if not path.is_file():
        raise MissionError("", None, "no such results file (run `ata eval` first)",
                           file=str(path))
    with open(path, newline="", encoding="utf-8") as f:
        reader = csv.DictReader(f)
        rows = list(reader)
        header = reader.fieldnames or []
    missing = [c for c in REQUIRED if c not in header]
    if missing:
        raise MissionError("", None, f"not an evaluation's results: no column {missing[0]!r}",
                           file=str(path))
    if not rows:
        raise MissionError("", None, "has no rows", file=str(path))
    return rows, list(header)


def read_results(path: str | Path | list) -> Results:
    """Read an evaluation's results.csv (methods keep their order of first appearance). Given
    several paths (evaluations run apart, with the same seed), their rows are read together; a
    (method, setting, level, scenario) found twice is an error."""
    paths = path if isinstance(path, (list, tuple)) else [path]
    rows, header = [], []
    for p in paths:
        more, cols = _read_one(p)
        rows += more
        header += [c for c in cols if c not in header]
    keys = [(r["method"], r["setting"], r["uncertainty"], r["scenario"]) for r in rows]
    if len(set(keys)) != len(keys):
        raise MissionError("", None, "a (method, setting, uncertainty, scenario) appears twice "
                           "in the results read together", file=str(paths[0]))
    rows = [{k: r.get(k, "") or "" for k in header} for r in rows]
    cols: dict[str, np.ndarray] = {}
    for name in header:
        raw = [r[name] for r in rows]
        if name in ("method", "setting", "uncertainty"):
            cols[name] = np.array(raw, dtype=object)
        elif name in ("scenario", "seed"):
            cols[name] = np.array([int(x) for x in raw], dtype=np.int64)
        else:
            try:
                cols[name] = np.array([float(x) if x != "" else math.nan for x in raw])
            except ValueError:
                cols[name] = np.array(raw, dtype=object)
    methods = list(dict.fromkeys(cols["method"]))
    settings = sorted(set(cols["setting"]))
    levels = sorted(set(cols["uncertainty"]), key=level_key)
    return Results(columns=cols, methods=methods, settings=settings, levels=levels)


# -- summary ------------------------------------------------------------------------------------
@dataclass
class Cell:
    """One method at one (setting, level)."""

    method: str
    setting: str
    level: str
    n: int
    mean: float
    low: float
    high: float
    fraction_of_u: float
    classified_share: float
    reallocations: float
    beats: float          # P(reference beats this method); NaN for the reference itself
    diff: tuple[float, float, float] = (float("nan"),) * 3   # reference - method: mean, CI


@dataclass
class Report:
    reference: str
    results: Results
    cells: list[Cell] = field(default_factory=list)

    def table(self, setting: str, level: str) -> list[Cell]:
        return [c for c in self.cells if c.setting == setting and c.level == level]

    def groups(self) -> list[tuple[str, str]]:
        return [(s, lv) for s in self.results.settings for lv in self.results.levels
                if self.table(s, lv)]


def _paired(res: Results, ref: np.ndarray, other: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The scores of reference and other on the scenarios both ran (same seed and id)."""
    c = res.columns
    key_r = {(int(s), int(i)): k for k, s, i in zip(np.nonzero(ref)[0], c["seed"][ref],
                                                   c["scenario"][ref])}
    pairs = [(key_r[(int(s), int(i))], k) for k, s, i in
             zip(np.nonzero(other)[0], c["seed"][other], c["scenario"][other])
             if (int(s), int(i)) in key_r]
    if not pairs:
        return np.zeros(0), np.zeros(0)
    a, b = np.array(pairs).T
    return c["score"][a], c["score"][b]


def summarize(res: Results, reference: str | None = None, resamples: int = RESAMPLES,
              seed: int = BOOTSTRAP_SEED) -> Report:
    """Every (method, setting, level) cell of the results, and P(reference beats method)."""
    if reference is None:
        reference = DEFAULT_REFERENCE if DEFAULT_REFERENCE in res.methods else res.methods[0]
    elif reference not in res.methods:
        raise MissionError("--reference", None, f"no method {reference!r} in the results; "
                           "methods: " + ", ".join(res.methods))
    report = Report(reference=reference, results=res)
    c = res.columns
    nan = float("nan")
    for setting in res.settings:
        for level in res.levels:
            ref = res.select(reference, setting, level)
            for method in res.methods:
                sel = res.select(method, setting, level)
                if not sel.any():
                    continue
                mean, low, high = bootstrap_ci(c["score"][sel], resamples, seed=seed)
                beats, diff = nan, (nan, nan, nan)
                if method != reference and ref.any():
                    a, b = _paired(res, ref, sel)
                    beats = beat_probability(a, b)
                    diff = bootstrap_ci(a - b, resamples, seed=seed)
                realloc = c.get("reallocations")
                report.cells.append(Cell(
                    method=method, setting=setting, level=level, n=int(sel.sum()), mean=mean,
                    low=low, high=high, fraction_of_u=float(np.nanmean(c["fraction_of_u"][sel])),
                    classified_share=float(np.nanmean(c["classified_share"][sel])),
                    reallocations=float(np.nanmean(realloc[sel])) if realloc is not None
                    else nan, beats=beats, diff=diff))
    return report


# -- rendering ----------------------------------------------------------------------------------
def _fmt(x: float, spec: str, dash: str = "-") -> str:
    return dash if x is None or (isinstance(x, float) and math.isnan(x)) else format(x, spec)


def table_rows(report: Report, setting: str, level: str,
               short: bool = False) -> tuple[list[str], list[list[str]]]:
    """Header and rows of one (setting, level) table, as text (`short`: terse headers)."""
    ref = report.reference
    if short:
        header = ["method", "n", "score [95% CI]", "of U", "classified", "realloc.",
                  f"{ref} - method [95% CI]", f"P({ref} beats)"]
    else:
        header = ["method", "scenarios", "total team performance [95% CI]", "fraction of U",
                  "POIs classified", "reallocations", f"{ref} - method, paired [95% CI]",
                  f"P({ref} beats)"]
    rows = []
    for cell in report.table(setting, level):
        d, lo, hi = cell.diff
        rows.append([cell.method, str(cell.n),
                     f"{cell.mean:.1f} [{cell.low:.1f}, {cell.high:.1f}]",
                     _fmt(cell.fraction_of_u, ".3f"),
                     _fmt(100 * cell.classified_share, ".1f") + "%"
                     if not math.isnan(cell.classified_share) else "-",
                     _fmt(cell.reallocations, ".2f"),
                     "-" if math.isnan(d) else f"{d:+.1f} [{lo:+.1f}, {hi:+.1f}]",
                     _fmt(cell.beats, ".3f")])
    return header, rows


def title(setting: str, level: str) -> str:
    return f"setting {setting}, {level} uncertainty"


def markdown(report: Report) -> str:
    lines = ["# Evaluation report", "",
             f"Mean total team performance with its 95% percentile-bootstrap confidence interval "
             f"over scenarios, the mean fraction of the upper bound U, the mean share of POIs "
             f"classified and of reallocations per scenario, the paired difference "
             f"{report.reference} - method on the same scenarios with its 95% bootstrap "
             f"confidence interval, and P({report.reference} beats): the share of paired "
             f"scenarios where {report.reference} scores more (ties count half).", ""]
    for setting, level in report.groups():
        header, rows = table_rows(report, setting, level)
        lines += [f"## {title(setting, level).capitalize()}", "",
                  "| " + " | ".join(header) + " |",
                  "|" + "|".join(["---"] + ["---:"] * (len(header) - 1)) + "|"]
        lines += ["| " + " | ".join(r) + " |" for r in rows]
        lines.append("")
    return "\n".join(lines)


def _pyplot():
    try:
        import matplotlib
    except ImportError:
        raise MissionError("", None, "the figures need matplotlib: pip install 'ata[plot]' "
                           "(or use --no-figures)") from None
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt


def _save(fig, out_dir: Path, stem: str) -> list[Path]:
    paths = []
    for ext in ("png", "svg"):
        path = out_dir / f"{stem}.{ext}"
        fig.savefig(path, dpi=150, bbox_inches="tight")
        paths.append(path)
    return paths


def figures(report: Report, out_dir: str | Path) -> list[Path]:
    """fig_setting_<s>.{png,svg} per setting (bars of the mean score with CI error bars, per
    method, grouped by level) and fig_ablations.{png,svg} (the reference and the w/o methods
    across the levels), after the paper's Fig. 4. Figures without data are skipped."""
    plt = _pyplot()
    out = Path(out_dir)
    res = report.results
    written: list[Path] = []
    for setting in res.settings:
        levels = [lv for lv in res.levels if report.table(setting, lv)]
        methods = [m for m in res.methods
                   if any(c.method == m and c.setting == setting for c in report.cells)]
        if not levels or not methods:
            continue
        fig, ax = plt.subplots(figsize=(max(5.0, 1.1 * len(levels) * max(len(methods), 2) / 2),
                                        3.6))
        width = 0.8 / len(methods)
        x = np.arange(len(levels))
        for k, method in enumerate(methods):
            cells = {c.level: c for c in report.cells if c.method == method
                     and c.setting == setting}
            mean = np.array([cells[lv].mean if lv in cells else np.nan for lv in levels])
            low = np.array([cells[lv].low if lv in cells else np.nan for lv in levels])
            high = np.array([cells[lv].high if lv in cells else np.nan for lv in levels])
            ax.bar(x + (k - (len(methods) - 1) / 2) * width, mean, width, label=method,
                   yerr=np.vstack([mean - low, high - mean]), capsize=2)
        ax.set_xticks(x, [f"{lv}" for lv in levels])
        ax.set_xlabel("uncertainty")
        ax.set_ylabel("total team performance")
        ax.set_title(f"Setting {setting}")
        ax.legend(fontsize=7, ncols=min(len(methods), 4), loc="upper center",
                  bbox_to_anchor=(0.5, -0.18), frameon=False)
        written += _save(fig, out, f"fig_setting_{setting}")
        plt.close(fig)

    ablations = [m for m in res.methods if m.startswith(ABLATION_PREFIX)]
    settings = [s for s in res.settings
                if any(c.setting == s and c.method in ablations for c in report.cells)]
    if ablations and settings:
        fig, axes = plt.subplots(1, len(settings), figsize=(4.8 * len(settings), 3.4),
                                 squeeze=False)
        for ax, setting in zip(axes[0], settings):
            levels = [lv for lv in res.levels if report.table(setting, lv)]
            x = np.arange(len(levels))
            shown = [report.reference] + ablations
            for k, method in enumerate(shown):
                cells = {c.level: c for c in report.cells if c.method == method
                         and c.setting == setting}
                if not cells:
                    continue
                mean = np.array([cells[lv].mean if lv in cells else np.nan for lv in levels])
                low = np.array([cells[lv].low if lv in cells else np.nan for lv in levels])
                high = np.array([cells[lv].high if lv in cells else np.nan for lv in levels])
                dodge = (k - (len(shown) - 1) / 2) * 0.04
                ax.errorbar(x + dodge, mean, yerr=np.vstack([mean - low, high - mean]), marker="o",
                            capsize=3, label=method)
            ax.set_xticks(x, levels)
            ax.set_xlabel("uncertainty")
            ax.set_ylabel("total team performance")
            ax.set_title(f"Ablations, setting {setting}")
            ax.legend(fontsize=7)
        written += _save(fig, out, "fig_ablations")
        plt.close(fig)
    return written


def write_report(run_dir: str | Path, reference: str | None = None, with_figures: bool = True,
                 resamples: int = RESAMPLES) -> tuple[Report, list[Path]]:
    """Read DIR/results.csv (of one folder, or of several read together); write report.md and
    (unless told not to) the figures into the first folder."""
    dirs = [Path(d) for d in run_dir] if isinstance(run_dir, (list, tuple)) else [Path(run_dir)]
    run_dir = dirs[0]
    report = summarize(read_results(dirs), reference, resamples)
    if with_figures:
        _pyplot()                      # a missing matplotlib fails before anything is written
    path = run_dir / "report.md"
    path.write_text(markdown(report), encoding="utf-8")
    written = [path]
    if with_figures:
        written += figures(report, run_dir)
    return report, written
