"""`ata report RUN_DIR` of a training run folder: the learning curves of `ata train`'s log.csv.

Any trainer's columns are read by name (`curve_panel`): held-out scores, training scores,
losses and throughput, each phase's steps one after another. `write_curves` writes
fig_curves.{png,svg} and curves.md; `curves_rows` is the summary table, a row per phase.
"""

from __future__ import annotations

import csv
import math
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ata.core.errors import MissionError
from ata.runtime.folders import prepare_out_dir, writing
from ata.results.report import fmt, md_table, pyplot, save_figure

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


def mark_phases(ax, log: TrainingLog, named: bool) -> None:
    """Dashed lines where each phase of `log` after the first begins; with `named`, each
    phase's name above the panel, over its steps."""
    for start in log.starts[1:]:
        ax.axvline(start, color="0.5", linestyle="--", linewidth=0.8)
    if named:
        ends = log.starts[1:] + [float(log.x.max())]
        top = ax.secondary_xaxis("top")
        top.set_xticks([(a + b) / 2 for a, b in zip(log.starts, ends)],
                       [p for p, _, _ in log.phases], fontsize=7, color="0.35")
        top.tick_params(axis="x", length=0)


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
            mark_phases(ax, log, named=i < ncols)         # named above the top row
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
            row.append(fmt(float(np.median(v[np.isfinite(v)])) if np.isfinite(v).any()
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
            row.append(fmt(float(np.nanmax(v)) if np.isfinite(v).any() else float("nan"),
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
    prepare_out_dir(out, kind="report", reads=(log.path.parent,))
    with writing(out):
        if with_figures:
            plt = pyplot()
            fig = curves_figure(plt, log, f"Training curves: {log.path.parent.name}")
            written = save_figure(fig, out, "fig_curves")
            plt.close(fig)
        path = out / "curves.md"
        path.write_text(curves_markdown(log, written), encoding="utf-8")
    return log, [path] + written
