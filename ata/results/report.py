"""`ata report`: the tables and figures of an evaluation (`ata eval`'s results.csv, read with
`ata.results.rows`).

Per (team setting, uncertainty level) and method: the mean total team performance with its 95%
percentile-bootstrap confidence interval over scenarios, the mean fraction of the upper bound U,
the share of POIs classified, the paired difference reference - method on the same scenarios
(the same setting, level, seed and scenario id) with its 95% bootstrap confidence interval, and
P(reference beats method): the share of those paired scenarios where the reference scores more,
ties counting half. Its figures add the paired difference method - reference of every method
against one reference (`fig_paired`); `ata.results.markdown` gives the tables of
docs/RESULTS.md. A training run folder's curves are `ata.results.curves`'.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ata.core.errors import MissionError
from ata.runtime import extras
from ata.runtime.folders import prepare_out_dir, writing
from ata.results.rows import (BOOTSTRAP_SEED, RESAMPLES, Results, beat_probability,
                                    bootstrap_ci, nanmean, paired_values, read_results)
from ata.results.seed_figure import (CAPTION as SEEDS_CAPTION, STEM as SEEDS_STEM,
                                     seeds_figure)
from ata.results.seeds import SeedTable, has_seeds, plain_methods, seed_tables

DEFAULT_REFERENCE = "ATA-HRL"
PAIRED_REFERENCE = "greedy"
"""The default reference of the paired-difference figure: what each method gains over greedy."""
ABLATION_PREFIX = "w/o"
SEEDS_TEXT = ("A method named `NAME seed S` is training seed S of NAME. Per method: its seeds, the "
              "scenarios every seed ran, the mean over seeds of their means with a 95% interval "
              "from a two-level bootstrap (seeds, then the scenarios, one draw for all seeds), "
              "or, with one seed, the scenario-level bootstrap; the interquartile mean (IQM) "
              "and the spread of the seeds' means. Per pair: A - B with its two-level interval "
              "and P(seed of A beats seed of B), the share of seed pairs whose mean over the "
              "paired scenarios is higher, ties counting half.")


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
    seeds: list[SeedTable] = field(default_factory=list)
    """Where a method has rows from several training seeds: the tables across seeds."""

    def table(self, setting: str, level: str) -> list[Cell]:
        return [c for c in self.cells if c.setting == setting and c.level == level]

    def groups(self) -> list[tuple[str, str]]:
        return [(s, lv) for s in self.results.settings for lv in self.results.levels
                if self.table(s, lv)]


def summarize(res: Results, reference: str | None = None, resamples: int = RESAMPLES,
              seed: int = BOOTSTRAP_SEED) -> Report:
    """Every (method, setting, level) cell of the results, and P(reference beats method)."""
    # across seeds, the default reference is ATA-HRL's seeds where it has no plain row
    seeds_reference = reference or DEFAULT_REFERENCE
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
                    low=low, high=high, fraction_of_u=nanmean(c["fraction_of_u"][sel]),
                    classified_share=nanmean(c["classified_share"][sel]),
                    reallocations=nanmean(realloc[sel]) if realloc is not None else nan,
                    beats=beats, diff=diff))
    if has_seeds(res):
        report.seeds = seed_tables(res, seeds_reference, resamples)
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
def fmt(x: float, spec: str, dash: str = "-") -> str:
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
        rows.append([report.results.label(cell.method), str(cell.n),
                     f"{cell.mean:.1f} [{cell.low:.1f}, {cell.high:.1f}]",
                     fmt(cell.fraction_of_u, ".3f"),
                     fmt(100 * cell.classified_share, ".1f") + "%"
                     if not math.isnan(cell.classified_share) else "-",
                     fmt(cell.reallocations, ".2f"),
                     "-" if math.isnan(d) else f"{d:+.1f} [{lo:+.1f}, {hi:+.1f}]",
                     fmt(cell.beats, ".3f")])
    if all(math.isnan(c.diff[0]) for c in report.table(setting, level)):
        # no method is paired with the reference (it is alone): no empty paired columns
        header, rows = header[:-2], [r[:-2] for r in rows]
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
    if report.results.replaced:
        lines += ["Cells taken from a later folder read together with the first: "
                  + replaced_text(report.results) + ".", ""]
    for setting, level in report.groups():
        header, rows = table_rows(report, setting, level)
        lines += [f"## {title(setting, level).capitalize()}", "", *md_table(header, rows), ""]
    if report.seeds:
        lines += ["## Across training seeds", "", SEEDS_TEXT, ""]
        for t in report.seeds:
            lines += [f"### {t.title[0].upper()}{t.title[1:]}", "", *md_table(t.header, t.rows),
                      ""]
    pngs = [p for p in written if p.suffix == ".png"]
    if pngs:
        lines += ["## Figures", "", "Each as PNG and SVG beside this file.", ""]
        for png in pngs:
            lines += [f"{figure_caption(png.stem, report, paired)}", "",
                      f"![{png.stem}]({png.name})", ""]
    return "\n".join(lines)


def replaced_text(res: Results) -> str:
    """The cells a later folder replaced, as text: 'greedy (a, low), ...'."""
    return ", ".join(f"{m} ({s}, {lv})" for m, s, lv in res.replaced)


def default_pairs(res: Results) -> list[tuple[str, str]]:
    """The pairs of the paired table: those the evaluations' suites name (``[suite] pairs``),
    else the tables' default reference against every other method."""
    if res.pairs:
        return list(res.pairs)
    ref = DEFAULT_REFERENCE if DEFAULT_REFERENCE in res.methods else res.methods[0]
    return [(ref, m) for m in res.methods if m != ref]


def figure_caption(stem: str, report: Report, paired: list[Paired] = ()) -> str:
    """What a figure of `figures` shows, in a sentence."""
    if stem.startswith("fig_setting_"):
        return (f"`{stem}`: setting {stem.removeprefix('fig_setting_')}, the mean total team "
                f"performance of every method with its 95% bootstrap CI, by uncertainty level.")
    if stem == "fig_ablations":
        return (f"`{stem}`: {report.reference} and the methods whose names start with "
                f"{ABLATION_PREFIX}, the mean score with its 95% CI across the levels, a panel "
                f"per setting.")
    if stem == SEEDS_STEM:
        return SEEDS_CAPTION
    if stem == "fig_paired":
        ref = paired[0].reference if paired else "the reference"
        return (f"`{stem}`: the paired difference method - {ref} on the same scenarios (points), "
                f"its mean and 95% bootstrap CI, a panel per setting, grouped by uncertainty "
                f"level; the value beside each bar is in bold where its CI excludes 0.")
    return f"`{stem}`."


def pyplot():
    """matplotlib's pyplot on the Agg backend; a MissionError naming the fix without it."""
    def load() -> Any:
        import matplotlib   # on use: matplotlib's start-up time
        return matplotlib
    matplotlib = extras.required("plot", load, "the figures need matplotlib (or use "
                                 "--no-figures)")
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt   # on use: matplotlib's start-up time
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
    import matplotlib   # on use: matplotlib's start-up time

    paths = []
    with matplotlib.rc_context({"svg.hashsalt": salt}):
        for ext in ("png", "svg"):
            path = Path(out_dir) / f"{stem}.{ext}"
            fig.savefig(path, dpi=150, bbox_inches="tight" if tight else None,
                        metadata={"Date": None} if ext == "svg" else None)
            paths.append(path)
    return paths


def figures(report: Report, out_dir: str | Path, paired: list[Paired] = (),
            resamples: int = RESAMPLES) -> list[Path]:
    """fig_setting_<s>.{png,svg} per setting (bars of the mean score with CI error bars, per
    method, grouped by level) and fig_ablations.{png,svg} (the reference and the w/o methods
    across the levels), after the paper's Fig. 4; with `paired`, fig_paired.{png,svg}
    (`paired_figure`). Figures without data are skipped. A training seed's rows (``NAME seed
    S``) are left to the tables across seeds and to fig_seeds.{png,svg}
    (`ata.results.seed_figure`), drawn where some method has seeds: these figures draw the
    other methods."""
    plt = pyplot()
    out = Path(out_dir)
    res = report.results
    plain = plain_methods(res.methods)
    paired = [p for p in paired if p.method in plain]
    written: list[Path] = []
    for setting in res.settings:
        levels = [lv for lv in res.levels if report.table(setting, lv)]
        methods = [m for m in plain
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
            ax.bar(x + (k - (len(methods) - 1) / 2) * width, mean, width, label=res.label(method),
                   yerr=np.vstack([mean - low, high - mean]), capsize=2)
        ax.set_xticks(x, [f"{lv}" for lv in levels])
        ax.set_xlabel("uncertainty")
        ax.set_ylabel("total team performance")
        ax.set_title(f"Setting {setting}")
        ax.legend(fontsize=7, ncols=min(len(methods), 4), loc="upper center",
                  bbox_to_anchor=(0.5, -0.18), frameon=False)
        written += save_figure(fig, out, f"fig_setting_{setting}")
        plt.close(fig)

    ablations = [m for m in plain if m.startswith(ABLATION_PREFIX)]
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
    fig = seeds_figure(plt, res, resamples)
    if fig is not None:
        written += save_figure(fig, out, SEEDS_STEM)
        plt.close(fig)
    return written


def paired_figure(plt, res: Results, paired: list[Paired]):
    """Horizontal bars of method - reference (mean, 95% CI) with a zero line, a panel per
    setting; the rows are grouped by uncertainty level (a heading row per level), the methods
    in results order and colours (those of fig_setting_<s>), the value of each bar printed at
    the panel's right edge (bold where the CI excludes 0)."""
    ref = paired[0].reference
    plain = plain_methods(res.methods)     # fig_setting's colours
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
            ax.barh(k, cell.mean, 0.7, color=colours[plain.index(method) % len(colours)],
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
        pyplot()                      # a missing matplotlib fails before anything is written
    prepare_out_dir(out, kind="report", reads=tuple(dirs))
    written, paired = [], []
    with writing(out):
        if with_figures:
            paired = paired_differences(res, paired_ref, resamples)
            written = figures(report, out, paired, resamples)
        path = out / "report.md"
        path.write_text(markdown(report, written, paired), encoding="utf-8")
    return report, [path] + written

