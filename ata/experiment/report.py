"""`ata report`: the tables and figures of an evaluation folder (`ata eval`'s results.csv).

Per (team setting, uncertainty level) and method: the mean total team performance with its 95%
percentile-bootstrap confidence interval over scenarios, the mean fraction of the upper bound U,
the share of POIs classified, the paired difference reference - method on the same scenarios
(the same setting, level, seed and scenario id) with its 95% bootstrap confidence interval, and
P(reference beats method): the share of those paired scenarios where the reference scores more,
ties counting half. Its figures add the paired difference method - reference of every method
against one reference (`fig_paired`).

Given a training run folder instead (`ata train`'s log.csv), `ata report` plots its learning
curves (`write_curves`).
"""

from __future__ import annotations

import csv
import json
import math
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ata.core.errors import MissionError
from ata.core.mission import UNCERTAINTY_LEVELS

DEFAULT_REFERENCE = "ATA-HRL"
PAIRED_REFERENCE = "greedy"
"""The default reference of the paired-difference figure: what each method gains over greedy."""
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
TEXT_COLUMNS = ("method", "setting", "uncertainty", "seed")
INT_COLUMNS = ("scenario",)
"""results.csv's columns of text and of integers; every other column holds numbers (blank: NaN).
The seed is kept as text: an integer, or the ``secret:`` hash of a secret one; rows pair on
it."""


def _parse(column: str, text: str) -> Any:
    """One cell of results.csv as its column's type; ValueError when it is not one."""
    if column == "seed":
        return text if text.startswith("secret:") else str(int(text))
    if column in TEXT_COLUMNS:
        return text
    if column in INT_COLUMNS:
        return int(text)
    return float(text) if text != "" else math.nan


def level_key(level: str) -> tuple[int, str]:
    order = list(UNCERTAINTY_LEVELS)
    return (order.index(level) if level in order else len(order), level)


def _read_one(path: str | Path) -> tuple[list[dict[str, Any]], list[str]]:
    """The rows of one results.csv, each cell parsed as its column's type; one MissionError
    naming the file and line for a file cut short, garbled, or of another row count than its
    eval.json."""
    given = path = Path(path)
    if path.is_dir():
        path = path / "results.csv"
    if not path.is_file():
        raise MissionError("", None, "no such results file or training log: `ata report` reads "
                           "an evaluation folder (results.csv, from `ata eval`) or a training "
                           "run folder (log.csv, from `ata train`)", file=str(given))
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
    parsed = []
    for line, row in enumerate(rows, start=2):
        if None in row or any(v is None for v in row.values()):
            raise MissionError("", None, f"line {line} has {'more' if None in row else 'fewer'} "
                               f"fields than the header: the file is cut short or garbled",
                               file=str(path))
        typed = {}
        for column, text in row.items():
            try:
                typed[column] = _parse(column, text)
            except ValueError:
                raise MissionError("", None, f"line {line}: {column} is {text!r}, not a "
                                   "number", file=str(path)) from None
        parsed.append(typed)
    meta = path.with_name("eval.json")
    if meta.is_file():
        try:
            planned = json.loads(meta.read_text(encoding="utf-8")).get("rows")
        except (json.JSONDecodeError, AttributeError):
            planned = None
        if isinstance(planned, int) and planned != len(rows):
            raise MissionError("", None, f"holds {len(rows)} rows where eval.json says "
                               f"{planned}: the file is incomplete or was changed",
                               file=str(path))
    return parsed, list(header)


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
    cols: dict[str, np.ndarray] = {}
    for name in header:
        # a column that one of the files read together lacks is blank (NaN) in its rows
        raw = [r.get(name, math.nan) for r in rows]
        cols[name] = np.array(raw, dtype=object if name in TEXT_COLUMNS
                              else np.int64 if name in INT_COLUMNS else float)
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


def paired_values(res: Results, ref: np.ndarray, other: np.ndarray,
                  column: str = "score") -> tuple[np.ndarray, np.ndarray]:
    """A column (the score by default) of the rows `ref` and `other` select (masks, e.g. of
    `Results.select`), on the scenarios both ran (same seed and id), in pairs."""
    c = res.columns
    key_r = {(str(s), int(i)): k for k, s, i in zip(np.nonzero(ref)[0], c["seed"][ref],
                                                   c["scenario"][ref])}
    pairs = [(key_r[(str(s), int(i))], k) for k, s, i in
             zip(np.nonzero(other)[0], c["seed"][other], c["scenario"][other])
             if (str(s), int(i)) in key_r]
    if not pairs:
        return np.zeros(0), np.zeros(0)
    a, b = np.array(pairs).T
    return c[column][a], c[column][b]


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
                    a, b = paired_values(res, ref, sel)
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


@dataclass
class Paired:
    """method - reference on the scenarios both ran at one (setting, level)."""

    method: str
    reference: str
    setting: str
    level: str
    n: int                # paired scenarios
    mean: float
    low: float
    high: float


def paired_reference(res: Results, reference: str | None = None) -> str:
    """The reference of the paired differences: `reference`, else greedy if present, else the
    first method."""
    if reference is None:
        return PAIRED_REFERENCE if PAIRED_REFERENCE in res.methods else res.methods[0]
    if reference not in res.methods:
        raise MissionError("--paired-reference", None, f"no method {reference!r} in the "
                           "results; methods: " + ", ".join(res.methods))
    return reference


def paired_differences(res: Results, reference: str, resamples: int = RESAMPLES,
                       seed: int = BOOTSTRAP_SEED) -> list[Paired]:
    """Every other method's paired difference method - reference per (setting, level): the mean
    over the scenarios both ran (same seed and scenario id) and its 95% percentile-bootstrap
    interval, as the tables compute theirs. Cells without paired scenarios are left out."""
    out = []
    for setting in res.settings:
        for level in res.levels:
            ref = res.select(reference, setting, level)
            if not ref.any():
                continue
            for method in res.methods:
                sel = res.select(method, setting, level)
                if method == reference or not sel.any():
                    continue
                a, b = paired_values(res, ref, sel)
                if a.size:
                    out.append(Paired(method, reference, setting, level, int(a.size),
                                      *bootstrap_ci(b - a, resamples, seed=seed)))
    return out


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


def markdown(report: Report, written: list[Path] = (), paired: list[Paired] = ()) -> str:
    """report.md: the tables, then the figures `written` (if any), each with its caption."""
    lines = ["# Evaluation report", "",
             f"Mean total team performance with its 95% percentile-bootstrap confidence interval "
             f"over scenarios, the mean fraction of the upper bound U, the mean share of POIs "
             f"classified and of reallocations per scenario, the paired difference "
             f"{report.reference} - method on the same scenarios with its 95% bootstrap "
             f"confidence interval, and P({report.reference} beats): the share of paired "
             f"scenarios where {report.reference} scores more (ties count half).", ""]
    for setting, level in report.groups():
        header, rows = table_rows(report, setting, level)
        lines += [f"## {title(setting, level).capitalize()}", "", *md_table(header, rows), ""]
    pngs = [p for p in written if p.suffix == ".png"]
    if pngs:
        lines += ["## Figures", "", "Each as PNG and SVG beside this file.", ""]
        for png in pngs:
            lines += [f"{figure_caption(png.stem, report, paired)}", "",
                      f"![{png.stem}]({png.name})", ""]
    return "\n".join(lines)


def figure_caption(stem: str, report: Report, paired: list[Paired] = ()) -> str:
    """What a figure of `figures` shows, in a sentence."""
    if stem.startswith("fig_setting_"):
        return (f"`{stem}`: setting {stem.removeprefix('fig_setting_')}, the mean total team "
                f"performance of every method with its 95% bootstrap CI, by uncertainty level.")
    if stem == "fig_ablations":
        return (f"`{stem}`: {report.reference} and the methods whose names start with "
                f"{ABLATION_PREFIX}, the mean score with its 95% CI across the levels, a panel "
                f"per setting.")
    if stem == "fig_paired":
        ref = paired[0].reference if paired else "the reference"
        return (f"`{stem}`: the paired difference method - {ref} on the same scenarios (points), "
                f"its mean and 95% bootstrap CI, a panel per setting, grouped by uncertainty "
                f"level; the value beside each bar is in bold where its CI excludes 0.")
    return f"`{stem}`."


def _pyplot():
    try:
        import matplotlib
    except ImportError:
        raise MissionError("", None, "the figures need matplotlib: pip install 'ata[plot]' "
                           "(or use --no-figures)") from None
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt


def md_table(header: list[str], rows: list[list[str]]) -> list[str]:
    """A Markdown table's lines: the first column left-aligned, the others right-aligned."""
    return (["| " + " | ".join(header) + " |",
             "|" + "|".join(["---"] + ["---:"] * (len(header) - 1)) + "|"]
            + ["| " + " | ".join(r) + " |" for r in rows])


def save_figure(fig: Any, out_dir: str | Path, stem: str, *, tight: bool = True,
                salt: str = "ata-report") -> list[Path]:
    """`stem`.png and `stem`.svg of `fig` in `out_dir`, reproducibly (fixed SVG ids from
    `salt`, no date): the same figure gives the same files. The paths."""
    import matplotlib

    paths = []
    with matplotlib.rc_context({"svg.hashsalt": salt}):
        for ext in ("png", "svg"):
            path = Path(out_dir) / f"{stem}.{ext}"
            fig.savefig(path, dpi=150, bbox_inches="tight" if tight else None,
                        metadata={"Date": None} if ext == "svg" else None)
            paths.append(path)
    return paths


def figures(report: Report, out_dir: str | Path, paired: list[Paired] = ()) -> list[Path]:
    """fig_setting_<s>.{png,svg} per setting (bars of the mean score with CI error bars, per
    method, grouped by level) and fig_ablations.{png,svg} (the reference and the w/o methods
    across the levels), after the paper's Fig. 4; with `paired`, fig_paired.{png,svg}
    (`paired_figure`). Figures without data are skipped."""
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
        written += save_figure(fig, out, f"fig_setting_{setting}")
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
        written += save_figure(fig, out, "fig_ablations")
        plt.close(fig)

    if paired:
        fig = paired_figure(plt, res, paired)
        written += save_figure(fig, out, "fig_paired")
        plt.close(fig)
    return written


def paired_figure(plt, res: Results, paired: list[Paired]):
    """Horizontal bars of method - reference (mean, 95% CI) with a zero line, a panel per
    setting; the rows are grouped by uncertainty level (a heading row per level), the methods
    in results order and colours (those of fig_setting_<s>), the value of each bar printed at
    the panel's right edge (bold where the CI excludes 0)."""
    ref = paired[0].reference
    cells = {(p.setting, p.level, p.method): p for p in paired}
    settings = [s for s in res.settings if any(p.setting == s for p in paired)]
    labels, rows = [], []                      # rows: (level, method or None for a heading)
    for level in res.levels:
        methods = [m for m in res.methods
                   if any(p.level == level and p.method == m for p in paired)]
        if methods:
            labels.append(f"{level} uncertainty")
            rows.append((level, None))
            labels += methods
            rows += [(level, m) for m in methods]
    y = np.arange(len(rows))
    fig, axes = plt.subplots(1, len(settings), sharey=True, squeeze=False, layout="constrained",
                             figsize=(1.6 + 4.6 * len(settings), 1.0 + 0.2 * len(rows)))
    colours = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    for ax, setting in zip(axes[0], settings):
        values = []
        for k, (level, method) in enumerate(rows):
            cell = cells.get((setting, level, method))
            if cell is None:
                values.append("")
                continue
            ax.barh(k, cell.mean, 0.7, color=colours[res.methods.index(method) % len(colours)],
                    xerr=[[cell.mean - cell.low], [cell.high - cell.mean]], capsize=2,
                    error_kw={"elinewidth": 0.8, "capthick": 0.8})
            values.append(f"{cell.mean:+.1f} [{cell.low:+.1f}, {cell.high:+.1f}]")
        ax.axvline(0.0, color="black", linewidth=0.8)
        for k, (level, method) in enumerate(rows):
            if method is None and k:
                ax.axhline(k - 0.5, color="0.8", linewidth=0.6)
        ax.set_yticks(y, labels, fontsize=7)
        ax.tick_params(axis="y", length=0)
        ax.set_ylim(len(rows) - 0.5, -0.5)        # the first row at the top
        right = ax.secondary_yaxis("right")
        right.set_yticks(y, values, fontsize=7)
        right.tick_params(axis="y", length=0)
        for k, text in enumerate(right.get_yticklabels()):
            cell = cells.get((setting, *rows[k]))
            if cell is not None and (cell.low > 0 or cell.high < 0):
                text.set_fontweight("bold")
        ax.set_xlabel(f"points, method \u2212 {ref} (mean, 95% CI)")
        ax.set_title(f"Setting {setting}")
        ax.grid(axis="x", color="0.9", linewidth=0.6)
        ax.set_axisbelow(True)
    for text, (level, method) in zip(axes[0][0].get_yticklabels(), rows):
        if method is None:
            text.set_fontweight("bold")
    fig.suptitle(f"Paired difference against {ref} on the same scenarios", fontsize=10)
    return fig


def write_report(run_dir: str | Path, reference: str | None = None, with_figures: bool = True,
                 resamples: int = RESAMPLES, paired_ref: str | None = None,
                 out_dir: str | Path | None = None) -> tuple[Report, list[Path]]:
    """Read DIR/results.csv (of one folder, or of several read together); write report.md and
    (unless told not to) the figures into `out_dir`, by default the first folder.
    `paired_ref` is the reference of fig_paired (`paired_reference`)."""
    dirs = [Path(d) for d in run_dir] if isinstance(run_dir, (list, tuple)) else [Path(run_dir)]
    out = Path(out_dir) if out_dir is not None else dirs[0]
    res = read_results(dirs)
    report = summarize(res, reference, resamples)
    paired_ref = paired_reference(res, paired_ref)
    if with_figures:
        _pyplot()                      # a missing matplotlib fails before anything is written
    out.mkdir(parents=True, exist_ok=True)
    written, paired = [], []
    if with_figures:
        paired = paired_differences(res, paired_ref, resamples)
        written = figures(report, out, paired)
    path = out / "report.md"
    path.write_text(markdown(report, written, paired), encoding="utf-8")
    return report, [path] + written


# -- training curves ----------------------------------------------------------------------------
LOG_FILE = "log.csv"
CURVE_PANELS = (
    ("score", "training score", "points"),
    ("held_out", "held-out validation score", "points"),
    ("loss", "losses", "loss"),
    ("speed", "samples/s", "episodes per second"),
)
"""The panels of fig_curves: (key, title, y label), in the figure's order."""
SMOOTH_SHARE = 25
"""A per-step series is drawn with its moving mean over 1/SMOOTH_SHARE of each phase's values
(when that is 3 values or more)."""


def curve_panel(column: str) -> str | None:
    """The panel of fig_curves that plots a log.csv column, by its name alone, whatever the
    trainer: eval_*/val_* held-out scores, *score training scores, loss/*_loss/*_mse losses,
    *_per_s throughput; None for the others (phase, step, counters, rewards, wall_s)."""
    if re.match(r"(eval|val|valid|validation)_", column):
        return "held_out"
    if re.search(r"(^|_)score$", column):
        return "score"
    if re.search(r"(^|_)(loss|mse)($|_)", column):
        return "loss"
    if column.endswith("_per_s"):
        return "speed"
    return None


@dataclass
class TrainingLog:
    """A training run's log.csv: its numeric columns, the phases (runs of rows of one `phase`
    value, in order) and the step of every row counted across the phases."""

    path: Path
    columns: dict[str, np.ndarray]
    phases: list[tuple[str, int, int]]           # (name, first row, end row)
    x: np.ndarray                                # step, each phase after the one before
    starts: list[float]                          # x where each phase begins
    superseded: int = 0                          # rows logged again later (left out)

    def panels(self) -> dict[str, list[str]]:
        """Panel key -> the columns it plots (those with a value), for the panels that have
        any."""
        out: dict[str, list[str]] = {}
        for name, values in self.columns.items():
            panel = curve_panel(name)
            if panel is not None and np.isfinite(values).any():
                out.setdefault(panel, []).append(name)
        return out


def is_training_folder(path: str | Path) -> bool:
    """A folder with a log.csv (from `ata train`) and no results.csv (from `ata eval`)."""
    path = Path(path)
    return (path / LOG_FILE).is_file() and not (path / "results.csv").exists()


def read_log(path: str | Path) -> TrainingLog:
    """Read a training run's log.csv (or the folder holding it). Any trainer's columns are
    read; `step` is required, `phase` optional. An unreadable, empty or garbled file, or one
    with nothing to plot, is a MissionError naming the file and the line."""
    path = Path(path)
    file = path / LOG_FILE if path.is_dir() else path

    def bad(message: str) -> MissionError:
        return MissionError("", None, message, file=str(file))

    try:
        with open(file, newline="", encoding="utf-8") as f:
            reader = csv.reader(f)
            lines = [(reader.line_num, row) for row in reader if row]
    except FileNotFoundError:
        raise bad("no such training log (run `ata train` first)") from None
    except (OSError, UnicodeDecodeError, csv.Error) as exc:
        raise bad(f"not a readable CSV file: {exc}") from None
    if not lines:
        raise bad("is empty: no header, no rows")
    header = [h.strip() for h in lines[0][1]]
    if "step" not in header:
        raise bad("not a training log: no column 'step' (columns: "
                  + ", ".join(header[:12]) + ")")
    rows = lines[1:]
    if not rows:
        raise bad("has no rows")
    for num, row in rows:
        if len(row) != len(header):
            raise bad(f"line {num} has {len(row)} fields, the header {len(header)}")
    columns: dict[str, np.ndarray] = {}
    for j, name in enumerate(header):
        if name == "phase":
            continue
        try:
            columns[name] = np.array([float(r[j]) if r[j].strip() else math.nan
                                      for _, r in rows])
        except ValueError:
            if name != "step" and curve_panel(name) is None:
                continue                                 # a text column, such as setting
            num, row = next((n, r) for n, r in rows if not _is_number(r[j]))
            raise bad(f"line {num}: {name} {row[j]!r} is not a number") from None
    step = columns["step"]
    if not np.isfinite(step).all():
        num = rows[int(np.argmin(np.isfinite(step)))][0]
        raise bad(f"line {num}: no step")
    names = [r[header.index("phase")].strip() for _, r in rows] if "phase" in header \
        else [""] * len(rows)
    # a row whose step a later row of its phase logs again (a run resumed from an older
    # checkpoint, before resuming cut the log back) is superseded by it
    keep = np.ones(len(rows), dtype=bool)
    for _, first, end in _runs(names):
        later = np.minimum.accumulate(step[first:end][::-1])[::-1]
        keep[first:end - 1] = step[first:end - 1] < later[1:]
    columns = {name: values[keep] for name, values in columns.items()}
    names = [n for n, k in zip(names, keep) if k]
    step = columns["step"]
    phases = _runs(names)
    x, starts, offset = np.empty(len(names)), [], 0.0
    for _, first, end in phases:
        starts.append(offset)
        x[first:end] = offset + step[first:end]
        offset += float(step[first:end].max())
    log = TrainingLog(path=file, columns=columns, phases=phases, x=x, starts=starts,
                      superseded=int((~keep).sum()))
    if not log.panels():
        raise bad("nothing to plot: no score, eval_*, loss or *_per_s column with a value")
    return log


def _runs(names: list[str]) -> list[tuple[str, int, int]]:
    """(name, first, end) of each run of equal names."""
    runs: list[tuple[str, int, int]] = []
    for k, name in enumerate(names):
        if runs and runs[-1][0] == name:
            runs[-1] = (name, runs[-1][1], k + 1)
        else:
            runs.append((name, k, k + 1))
    return runs


def _is_number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return not text.strip()
    return True


def moving_mean(values: np.ndarray, window: int) -> np.ndarray:
    """The centred moving mean over `window` values (over fewer at the ends)."""
    v = np.asarray(values, dtype=float)
    c = np.concatenate([[0.0], np.cumsum(v)])
    k = np.arange(v.size)
    low = np.clip(k - window // 2, 0, v.size)
    high = np.clip(k - window // 2 + window, 0, v.size)
    return (c[high] - c[low]) / (high - low)


def smoothing_window(values: np.ndarray) -> int:
    """The moving mean's window for one phase's values of a column (1: no smoothing)."""
    window = round(len(values) / SMOOTH_SHARE)
    return window if window >= 3 else 1


def _segments(log: TrainingLog, column: str):
    """(phase index, x, values) of each phase's finite values of a column."""
    values = log.columns[column]
    for k, (_, first, end) in enumerate(log.phases):
        ok = np.isfinite(values[first:end])
        if ok.any():
            yield k, log.x[first:end][ok], values[first:end][ok]


def curves_figure(plt, log: TrainingLog, title: str):
    """fig_curves: a panel per kind of column (training score, held-out score, losses,
    samples/s) against the step counted across phases; per-step series faint with their moving
    mean, held-out scores as points with the best one starred, dashed lines where a phase
    begins."""
    panels = log.panels()
    shown = [p for p in CURVE_PANELS if p[0] in panels]
    ncols = 2 if len(shown) > 1 else 1
    nrows = math.ceil(len(shown) / ncols)
    fig, axes = plt.subplots(nrows, ncols, sharex=True, squeeze=False, layout="constrained",
                             figsize=(5.6 * ncols, 3.0 * nrows))
    axes = list(axes.ravel())
    for ax in axes[len(shown):]:
        ax.remove()
    colours = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    several = len(log.phases) > 1
    for i, ((key, name, unit), ax) in enumerate(zip(shown, axes)):
        for j, column in enumerate(panels[key]):
            colour = colours[j % len(colours)]
            if key == "held_out":
                best = _best(log, column)
                for k, x, v in _segments(log, column):
                    ax.plot(x, v, marker="o", markersize=3, linewidth=1.0, color=colour,
                            label=f"{column} (best {best[0]:.1f}, {best[1]})" if k == best[2]
                            else None)
                ax.plot([best[3]], [best[0]], marker="*", markersize=11, color=colour,
                        markeredgecolor="black", markeredgewidth=0.5, linestyle="none")
                continue
            for n, (k, x, v) in enumerate(_segments(log, column)):
                window = smoothing_window(v)
                if window == 1:
                    ax.plot(x, v, linewidth=1.0, color=colour, label=None if n else column)
                else:
                    ax.plot(x, v, linewidth=0.5, color=colour, alpha=0.25)
                    ax.plot(x, moving_mean(v, window), linewidth=1.3, color=colour,
                            label=None if n else f"{column} (moving mean)")
        if several:
            for start in log.starts[1:]:
                ax.axvline(start, color="0.5", linestyle="--", linewidth=0.8)
            if i < ncols:                                # the phases named above the top row
                ends = log.starts[1:] + [float(log.x.max())]
                top = ax.secondary_xaxis("top")
                top.set_xticks([(a + b) / 2 for a, b in zip(log.starts, ends)],
                               [p for p, _, _ in log.phases], fontsize=7, color="0.35")
                top.tick_params(axis="x", length=0)
        ax.set_title(name, fontsize=10)
        ax.set_ylabel(unit)
        ax.grid(color="0.92", linewidth=0.6)
        ax.legend(fontsize=7, loc="best")
        if i + ncols >= len(shown):                     # the lowest panel of its column
            ax.xaxis.set_tick_params(labelbottom=True)
            ax.set_xlabel("step, the phases one after another" if several else "step")
    fig.suptitle(title, fontsize=11)
    return fig


def _best(log: TrainingLog, column: str) -> tuple[float, str, int, float]:
    """(value, where: "phase step N", phase index, x) of a column's highest value."""
    values = log.columns[column]
    row = int(np.nanargmax(values))
    k = next(k for k, (_, first, end) in enumerate(log.phases) if first <= row < end)
    phase = log.phases[k][0]
    where = f"{phase} step {int(log.columns['step'][row])}" if phase \
        else f"step {int(log.columns['step'][row])}"
    return float(values[row]), where, k, float(log.x[row])


def curves_rows(log: TrainingLog) -> tuple[list[str], list[list[str]]]:
    """A row per phase: its steps, the median samples/s, each training score's moving mean at
    its first and last step, each held-out score's first, best and last value, and the
    cumulative wall time at its end (where the log has those columns)."""
    panels = log.panels()
    speed, score, held = (panels.get(k, []) for k in ("speed", "score", "held_out"))
    wall = "wall_s" in log.columns and np.isfinite(log.columns["wall_s"]).any()
    header = (["phase", "steps"] + [f"{c}, median" for c in speed]
              + [f"{c}, moving mean: first -> last" for c in score]
              + [f"{c}: first -> last (best at step)" for c in held]
              + (["wall_s at end"] if wall else []))
    rows = []
    for k, (phase, first, end) in enumerate(log.phases):
        step = log.columns["step"][first:end]
        row = [phase or "-", f"{int(step.min())}-{int(step.max())}"]
        for c in speed:
            v = log.columns[c][first:end]
            row.append(_fmt(float(np.median(v[np.isfinite(v)])) if np.isfinite(v).any()
                            else float("nan"), ".1f"))
        for c in score:
            seg = [v for kk, _, v in _segments(log, c) if kk == k]
            smooth = moving_mean(seg[0], smoothing_window(seg[0])) if seg else None
            row.append("-" if smooth is None else f"{smooth[0]:.1f} -> {smooth[-1]:.1f}")
        for c in held:
            v = log.columns[c][first:end]
            ok = np.isfinite(v)
            if not ok.any():
                row.append("-")
                continue
            at = int(np.nanargmax(v))
            row.append(f"{v[ok][0]:.1f} -> {v[ok][-1]:.1f} ({v[at]:.1f} at {int(step[at])})")
        if wall:
            v = log.columns["wall_s"][first:end]
            row.append(_fmt(float(np.nanmax(v)) if np.isfinite(v).any() else float("nan"),
                            ".0f"))
        rows.append(row)
    return header, rows


def curves_markdown(log: TrainingLog, written: list[Path]) -> str:
    header, rows = curves_rows(log)
    panels = log.panels()
    shown = "; ".join(f"{name} ({', '.join(panels[key])})" for key, name, _ in CURVE_PANELS
                      if key in panels)
    lines = [f"# Training curves: {log.path.parent.name}", "",
             f"From `{log.path}`: {len(log.x)} rows, "
             + ", ".join(f"{p or 'one phase'} (rows {b - a})" for p, a, b in log.phases) + "."
             + (f" {log.superseded} rows whose steps were logged again later (a resumed run) "
                "are left out." if log.superseded else ""),
             "", *md_table(header, rows), ""]
    pngs = [p for p in written if p.suffix == ".png"]
    if pngs:
        lines += [f"`fig_curves` (PNG and SVG beside this file): {shown}, against the step"
                  + (", the phases one after another (each phase counts its own steps from "
                     "its start; dashed lines mark where one begins)" if len(log.phases) > 1
                     else "")
                  + f". Per-step series are drawn faint with their moving mean over 1/"
                  f"{SMOOTH_SHARE} of each phase's steps; each held-out "
                  "score's best value is starred.", ""]
        lines += [f"![{p.stem}]({p.name})" for p in pngs] + [""]
    return "\n".join(lines)


def write_curves(run_dir: str | Path, out_dir: str | Path | None = None,
                 with_figures: bool = True) -> tuple[TrainingLog, list[Path]]:
    """Read a training run folder's log.csv; write fig_curves.{png,svg} (unless told not to)
    and curves.md into `out_dir`, by default the run folder."""
    log = read_log(run_dir)
    out = Path(out_dir) if out_dir is not None else log.path.parent
    written: list[Path] = []
    out.mkdir(parents=True, exist_ok=True)
    if with_figures:
        plt = _pyplot()
        fig = curves_figure(plt, log, f"Training curves: {log.path.parent.name}")
        written = save_figure(fig, out, "fig_curves")
        plt.close(fig)
    path = out / "curves.md"
    path.write_text(curves_markdown(log, written), encoding="utf-8")
    return log, [path] + written
