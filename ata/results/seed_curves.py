"""`ata report DIR` of a folder of seeds (`ata train --seeds N`): the learning curves across
seeds (each seed's curve, their mean, the middle half of the seeds shaded, the phases marked),
a table of each seed's best held-out validation, and, once `ata eval DIR -o DIR/eval` has run,
each seed's best weights paired with greedy on the same scenarios and the interquartile mean
(IQM) across seeds with a bootstrap interval over seeds and scenarios (as rliable does)."""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ata.results.curves import CURVE_PANELS, TrainingLog, mark_phases, read_log
from ata.results.report import md_table, pyplot, save_figure
from ata.results.rows import bootstrap_ci, paired_values, read_results
from ata.results.seeds import SeedTable, across_seeds, iqm, seed_matrix, seed_tables
from ata.runtime.folders import prepare_out_dir, writing
from ata.training import read_checkpoint
from ata.training.folders import read_seeds

@dataclass
class SeedLogs:
    """The logs of a folder of seeds (`ata.training.folders`), in seed order."""

    path: Path                     # the folder
    seeds: list[int]
    logs: list[TrainingLog]
    dirs: list[Path]


def read_seed_logs(folder: str | Path) -> SeedLogs:
    data = read_seeds(folder)
    logs = [read_log(d) for d in data["dirs"]]
    return SeedLogs(Path(folder), data["seeds"], logs, data["dirs"])


def across(seeds: SeedLogs, column: str) -> tuple[np.ndarray, np.ndarray]:
    """(x, values (rows, seeds)) of a column over the rows every seed logged it (the same
    phase and step), x as the first seed's log counts it."""
    keyed = []
    for log in seeds.logs:
        values = log.columns.get(column)
        rows = {}
        if values is not None:
            for k, (_, first, end) in enumerate(log.phases):
                for r in range(first, end):
                    if math.isfinite(values[r]):
                        rows[(k, float(log.columns["step"][r]))] = (float(log.x[r]), values[r])
        keyed.append(rows)
    common = sorted(set.intersection(*(set(r) for r in keyed)) if keyed else set())
    x = np.array([keyed[0][key][0] for key in common])
    v = np.array([[rows[key][1] for rows in keyed] for key in common]).reshape(len(common), -1)
    return x, v


def seeds_figure(plt, seeds: SeedLogs):
    """fig_curves_seeds: a panel per kind of column; for each column every seed's curve, thin,
    their mean, and a band over the middle half of the seeds (the 25th to the 75th percentile,
    the seeds an IQM averages); dashed lines where a phase begins, named above the top row."""
    panels: dict[str, list[str]] = {}
    for log in seeds.logs:
        for key, columns in log.panels().items():
            panels.setdefault(key, [])
            panels[key] += [c for c in columns if c not in panels[key]]
    shown = [p for p in CURVE_PANELS if p[0] in panels]
    ncols = 2 if len(shown) > 1 else 1
    nrows = math.ceil(len(shown) / ncols)
    fig, axes = plt.subplots(nrows, ncols, squeeze=False, layout="constrained",
                             figsize=(5.6 * ncols, 3.0 * nrows))
    axes = list(axes.ravel())
    for ax in axes[len(shown):]:
        ax.remove()
    first = seeds.logs[0]
    for i, ((key, name, unit), ax) in enumerate(zip(shown, axes)):
        for column in panels[key]:
            x, v = across(seeds, column)
            if not x.size:
                continue
            marker = "o" if key == "held_out" else None
            line, = ax.plot(x, v.mean(1), linewidth=1.4, marker=marker, markersize=3,
                            label=f"{column} (mean of {v.shape[1]})")
            colour = line.get_color()
            ax.plot(x, v, linewidth=0.5, color=colour, alpha=0.35)
            if v.shape[1] > 1:
                low, high = np.percentile(v, [25, 75], axis=1)
                ax.fill_between(x, low, high, color=colour, alpha=0.15, linewidth=0)
        if len(first.phases) > 1:
            mark_phases(ax, first, named=i < ncols)
        ax.set_title(name, fontsize=10)
        ax.set_ylabel(unit)
        ax.set_xlabel("step, the phases one after another")
        ax.grid(color="0.92", linewidth=0.6)
        ax.legend(fontsize=7, loc="best")
    fig.suptitle(f"Training curves over {len(seeds.seeds)} seeds: {seeds.path.name} (each "
                 "seed thin, their mean, the middle half of the seeds shaded)", fontsize=11)
    return fig


def best_rows(seeds: SeedLogs) -> tuple[list[str], list[list[str]]]:
    """A row per seed: its best held-out validation (the one best.pt holds), the steps it
    trained and its training time; then their mean with its 95% interval and their IQM."""
    header = ["seed", "best held-out score (best.pt)", "steps", "training time, s", "folder"]
    rows, best = [], []
    for seed, folder in zip(seeds.seeds, seeds.dirs):
        info = _trained(folder)
        value = info.get("best_eval", math.nan)
        best.append(value)
        steps = sum(v for k, v in info.get("counters", {}).items() if k != "episodes")
        rows.append([str(seed), f"{value:.2f}", str(steps) if info else "-",
                     f"{info.get('wall_s', math.nan):.0f}", folder.name])
    v = np.array([b for b in best if math.isfinite(b)])
    if v.size:
        half = _t_half(v)
        rows.append(["mean (95% CI)", f"{v.mean():.2f} ± {half:.2f}", "", "", ""])
        rows.append(["IQM", f"{iqm(v):.2f}", "", "", ""])
    return header, rows


def _trained(folder: Path) -> dict:
    """trained.json of a finished seed, else what its best.pt says (a seed under way)."""
    path = folder / "trained.json"
    if path.is_file():
        return json.loads(path.read_text(encoding="utf-8"))
    if (folder / "best.pt").is_file():
        data = read_checkpoint(folder / "best.pt")
        return {"best_eval": float(data.get("best_eval", math.nan)),
                "wall_s": float(data.get("wall_s", math.nan)),
                "counters": dict(data.get("counters", {}))}
    return {}


def _t_half(v: np.ndarray) -> float:
    if v.size < 2:
        return math.nan
    from scipy import stats   # imported on use: scipy.stats costs start-up time
    return float(stats.t.ppf(0.975, v.size - 1) * v.std(ddof=1) / math.sqrt(v.size))


def paired_rows(seeds: SeedLogs, eval_dir: Path, reference: str = "greedy"):
    """Each seed's best weights minus `reference` on the same scenarios (mean, 95% bootstrap
    CI over scenarios); then, per cell, the mean and the IQM of the seeds' differences with
    their 95% intervals from the two-level bootstrap of `ata.results.seeds` (seeds, then
    scenarios)."""
    res = read_results(eval_dir)
    header = ["seed", "method", "cell", "scenarios", f"mean - {reference} (95% CI)"]
    rows = []
    for setting, level in [(s, lv) for s in res.settings for lv in res.levels]:
        ref = res.select(reference, setting, level)
        names = []
        for seed in seeds.seeds:
            name = next((m for m in res.methods if m.endswith(f" seed {seed}")), None)
            if name is None or not ref.any():
                continue
            a, b = paired_values(res, ref, res.select(name, setting, level))
            if not a.size:
                continue
            mean, low, high = bootstrap_ci(b - a)
            names.append(name)
            rows.append([str(seed), name, f"{setting}/{level}", str(a.size),
                         f"{mean:+.2f} [{low:+.2f}, {high:+.2f}]"])
        if len(names) > 1:
            # the differences on the scenarios every seed ran, a (seeds x scenarios) matrix
            mine, ref_rows = seed_matrix(res, names, setting, level,
                                         also=[(res, [reference])])
            stats = across_seeds(mine - ref_rows)
            size = f"{len(names)} x {stats.scenarios}"
            rows.append(["mean over seeds", "", f"{setting}/{level}", size,
                         f"{stats.mean:+.2f} [{stats.low:+.2f}, {stats.high:+.2f}]"])
            rows.append(["IQM over seeds", "", f"{setting}/{level}", size,
                         f"{stats.iqm:+.2f} [{stats.iqm_low:+.2f}, {stats.iqm_high:+.2f}]"])
    return header, rows


def eval_tables(seeds: SeedLogs) -> list[SeedTable]:
    """The across-seed tables (`ata.results.seeds.seed_tables`) of the folder's evaluation,
    eval/, once `ata eval DIR -o DIR/eval` has run: the seeds as one method, against greedy."""
    eval_dir = seeds.path / "eval"
    if not (eval_dir / "results.csv").is_file():
        return []
    return seed_tables(read_results(eval_dir))


def write_seed_report(folder: str | Path, out_dir: str | Path | None = None,
                      with_figures: bool = True) -> tuple[SeedLogs, list[Path]]:
    """fig_curves_seeds.{png,svg} and curves.md of a folder of seeds."""
    seeds = read_seed_logs(folder)
    out = Path(out_dir) if out_dir is not None else seeds.path
    prepare_out_dir(out, kind="report", reads=(seeds.path,))
    written: list[Path] = []
    with writing(out):
        if with_figures:
            plt = pyplot()
            fig = seeds_figure(plt, seeds)
            written = save_figure(fig, out, "fig_curves_seeds")
            plt.close(fig)
        lines = [f"# Training over {len(seeds.seeds)} seeds: {seeds.path.name}", "",
                 "Each seed's best held-out validation (the score of its best.pt):", "",
                 *md_table(*best_rows(seeds)), ""]
        eval_dir = seeds.path / "eval"
        if (eval_dir / "results.csv").is_file():
            lines += ["Each seed's best.pt against greedy on the same scenarios (`ata eval` "
                      "in eval/); the intervals over seeds resample seeds, then scenarios:", "",
                      *md_table(*paired_rows(seeds, eval_dir)), ""]
            for t in eval_tables(seeds):
                lines += [f"{t.title[0].upper()}{t.title[1:]}:", "",
                          *md_table(t.header, t.rows), ""]
        lines += [f"![{p.stem}]({p.name})" for p in written if p.suffix == ".png"]
        path = out / "curves.md"
        path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return seeds, [path] + written
