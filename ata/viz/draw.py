"""The three pictures of an episode, each to PNG and SVG: the map (`show_map`), a timeline per
member (`show_timeline`) and the humans' states over time (`show_humans`).

Colours are Okabe and Ito's colour-blind-safe set for categories (outcomes, activities,
quantities) and Paul Tol's muted set for the robots' routes; every category is also told apart
by shape or line style where it matters. Times are drawn in minutes, positions in metres.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from ata.runtime import extras
from ata.results.report import save_figure
from ata.model import tables
from ata.viz.record import OUTCOMES, RIGHT, UNCLASSIFIED, UNVISITED, WRONG, Episode

BLUE, VERMILLION, GREEN, SKY = "#0072B2", "#D55E00", "#009E73", "#56B4E9"
ORANGE, YELLOW, PURPLE, GREY = "#E69F00", "#F0E442", "#CC79A7", "#999999"
OUTCOME_COLOURS = {RIGHT: BLUE, WRONG: VERMILLION, UNCLASSIFIED: YELLOW, UNVISITED: "white"}
ROUTE_COLOURS = ("#CC6677", "#332288", "#DDCC77", "#117733", "#88CCEE", "#882255", "#44AA99",
                 "#999933", "#AA4499", "#555555")
KIND_MARKERS = {tables.AIR: "^", tables.GROUND: "s"}
DIFFICULTY_SIZES = (32.0, 90.0, 200.0)       # scatter marker areas, points^2
STEMS = ("show_map", "show_timeline", "show_humans")
"""The file names written, without extension."""


def figure_class() -> Any:
    """matplotlib's Figure (no pyplot, no global backend), or one clear message without it."""
    def load() -> Any:
        from matplotlib.figure import Figure   # on use: matplotlib's start-up time
        return Figure
    return extras.required("plot", load, "the pictures need matplotlib")


def robot_colour(robot: int) -> str:
    return ROUTE_COLOURS[robot % len(ROUTE_COLOURS)]


def route_style(ep: Episode, robot: int) -> Any:
    """A UAV's route is solid, a UGV's dashed."""
    return "-" if ep.robot_type[robot] == tables.UAV else (0, (4, 2))


def robot_label(ep: Episode, robot: int) -> str:
    return f"R{robot} ({'UAV' if ep.robot_type[robot] == tables.UAV else 'UGV'})"


def human_label(ep: Episode, human: int) -> str:
    return f"H{human} ({tables.SKILLS[ep.skill[human]]} skill)"


def _title(ep: Episode, what: str) -> str:
    share = ep.score / ep.upper_bound if ep.upper_bound > 0 else float("nan")
    return (f"{what}: mission {ep.mission!r}, setting ({ep.setting}), uncertainty "
            f"{ep.uncertainty}, scenario {ep.scenario} (seed {ep.seed}); score {ep.score:.0f} "
            f"points, {share:.0%} of U = {ep.upper_bound:.0f}")


def _reallocation_lines(ax: Any, ep: Episode, zorder: float = 0.5,
                        counts_at: float | None = None) -> None:
    """Reallocation epochs as vertical lines (x in minutes): solid when POIs changed, dotted
    when none did; with `counts_at`, the number of POIs changed is written at that height."""
    for epoch, n in ep.reallocations:
        x = epoch * ep.epoch_s / 60.0
        if n:
            ax.axvline(x, color="#444444", lw=0.9, ls="-", zorder=zorder)
            if counts_at is not None:
                ax.text(x, counts_at, str(n), ha="center", va="bottom", fontsize=8,
                        bbox=dict(boxstyle="round,pad=0.15", fc="white", ec="#444444", lw=0.6))
        else:
            ax.axvline(x, color=GREY, lw=0.8, ls=":", zorder=zorder)


def draw_map(ep: Episode, fig: Any) -> None:
    """Base, POIs (shape: kind, size: difficulty, fill: outcome), each robot's route, its
    failure, and the POIs whose attributes differ from the estimate."""
    from matplotlib.lines import Line2D   # on use: matplotlib's start-up time

    ax = fig.add_axes((0.07, 0.07, 0.62, 0.85))
    area = ep.area_m
    for robot in range(ep.robot_type.size):
        legs = [leg for leg in ep.legs if leg.robot == robot]
        colour, style = robot_colour(robot), route_style(ep, robot)
        if legs:
            xs = [legs[0].origin[0]] + [leg.dest[0] for leg in legs]
            ys = [legs[0].origin[1]] + [leg.dest[1] for leg in legs]
            ax.plot(xs, ys, color=colour, lw=1.7, ls=style, zorder=2, solid_capstyle="round")
            for leg in legs:                 # an arrow head halfway along each leg
                (x0, y0), (x1, y1) = leg.origin, leg.dest
                if np.hypot(x1 - x0, y1 - y0) > 0.04 * area:
                    mx, my = (x0 + x1) / 2, (y0 + y1) / 2
                    ax.annotate("", xy=(mx + (x1 - x0) * 0.02, my + (y1 - y0) * 0.02),
                                xytext=(mx, my), zorder=2,
                                arrowprops=dict(arrowstyle="-|>", color=colour, lw=1.2,
                                                mutation_scale=11))
    outcome = ep.outcome
    for kind, marker in KIND_MARKERS.items():
        for diff, size in enumerate(DIFFICULTY_SIZES):
            sel = (ep.true_kind == kind) & (ep.true_diff == diff)
            if sel.any():
                ax.scatter(ep.poi_pos[sel, 0], ep.poi_pos[sel, 1], s=size, marker=marker,
                           c=[OUTCOME_COLOURS[o] for o in outcome[sel]], edgecolors="black",
                           linewidths=0.9, zorder=4)
    changed = ep.changed
    if changed.any():
        ax.scatter(ep.poi_pos[changed, 0], ep.poi_pos[changed, 1], s=430, marker="o",
                   facecolors="none", edgecolors="black", linewidths=0.9, linestyles="--",
                   zorder=3)
    ax.scatter([ep.base[0]], [ep.base[1]], s=320, marker="*", c="black", edgecolors="white",
               linewidths=0.8, zorder=6)
    for robot in np.flatnonzero(ep.fail_time <= ep.horizon_s):
        # a robot moves only on its legs: it fails where its last leg ended, or was cut short
        own = [leg for leg in ep.legs if leg.robot == robot]
        x, y = own[-1].dest if own else ep.base
        ax.scatter([x], [y], s=190, marker="X", c=robot_colour(robot), edgecolors="black",
                   linewidths=1.0, zorder=7)
        dx = 14 if x < 0.8 * area else -14
        ax.annotate(f"R{robot} fails, {ep.fail_time[robot] / 60:.1f} min", (x, y),
                    xytext=(dx, 10), textcoords="offset points", fontsize=8.5, zorder=8,
                    ha="left" if dx > 0 else "right",
                    bbox=dict(boxstyle="round,pad=0.2", fc="white", ec="none", alpha=0.6))
    pad = 0.03 * area
    ax.set_xlim(-pad, area + pad)
    ax.set_ylim(-pad, area + pad)
    ax.set_aspect("equal")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.grid(color="#DDDDDD", lw=0.5, zorder=0)
    ax.set_title(_title(ep, "Map"), fontsize=10, loc="left", wrap=True)

    captures = np.bincount(np.asarray([leg.robot for leg in ep.legs if leg.captured], dtype=int),
                           minlength=ep.robot_type.size)
    robots = [Line2D([], [], color=robot_colour(r), lw=1.7, ls=route_style(ep, r),
                     label=f"{robot_label(ep, r)}: {captures[r]} captures")
              for r in range(ep.robot_type.size)]
    first = fig.legend(handles=robots, title="routes (UAV solid, UGV dashed)", loc="upper left",
                       bbox_to_anchor=(0.72, 0.92), fontsize=8.5, title_fontsize=9,
                       frameon=False)
    counts = np.bincount(outcome, minlength=len(OUTCOMES))

    def marker(label: str, shape: str = "o", face: str = "white", size: float = 9.0,
               edge: str = "black", ls: str = "none", lw: float = 0.9) -> Line2D:
        return Line2D([], [], marker=shape, markersize=size, markerfacecolor=face,
                      markeredgecolor=edge, markeredgewidth=lw, ls=ls, color=edge, label=label)

    pois = [marker(f"{OUTCOMES[o]} ({counts[o]})", face=OUTCOME_COLOURS[o])
            for o in (RIGHT, WRONG, UNCLASSIFIED, UNVISITED)]
    pois += [marker("air (true kind)", "^"), marker("ground (true kind)", "s")]
    pois += [marker(f"{name} difficulty, {tables.POINTS[d]:.0f} points", "o",
                    size=np.sqrt(DIFFICULTY_SIZES[d]) * 0.85)
             for d, name in enumerate(tables.DIFFICULTIES)]
    pois += [ax.scatter([], [], s=300, marker="o", facecolors="none", edgecolors="black",
                        linewidths=0.9, linestyles="--",
                        label=f"attribute changed ({int(changed.sum())})"),
             marker("robot failure", "X", GREY, 10), marker("base", "*", "black", 14)]
    fig.legend(handles=pois, title="POIs (fill: outcome)", loc="upper left",
               bbox_to_anchor=(0.72, 0.52), fontsize=8.5, title_fontsize=9, frameon=False)
    fig.add_artist(first)


def draw_timeline(ep: Episode, fig: Any) -> None:
    """One row per human (navigation legs, classifications, re-briefs, SA switch cost, idle
    time) and per robot (travel, waiting for a navigator, captures, re-plans, failure)."""
    from matplotlib.lines import Line2D   # on use: matplotlib's start-up time
    from matplotlib.patches import Patch   # on use: matplotlib's start-up time

    H, R = ep.skill.size, ep.robot_type.size
    inches = fig.get_figheight()
    ax = fig.add_axes((0.12, 1.75 / inches, 0.79, 1 - 2.25 / inches))
    end = ep.horizon_s / 60.0
    rows = [("H", i) for i in range(H)] + [("R", i) for i in range(R)]
    y_of = {row: len(rows) - i + (0.6 if row[0] == "H" else 0.0) for i, row in enumerate(rows)}
    height = 0.62

    def bars(y: float, spans: list[tuple[float, float]], **style: Any) -> None:
        spans = [(a / 60.0, (b - a) / 60.0) for a, b in spans if b > a]
        if spans:
            ax.broken_barh(spans, (y - height / 2, height), **style)

    outcome = ep.outcome
    for human in range(H):
        y = y_of[("H", human)]
        bars(y, [(0.0, ep.horizon_s)], facecolors="#EEEEEE", zorder=1)
        items = [w for w in ep.work if w.human == human]
        bars(y, [(w.start, w.begin) for w in items], facecolors="white", edgecolors="black",
             hatch="////", linewidths=0.0, zorder=2)
        bars(y, [(w.begin, w.end) for w in items if w.kind == "nav"], facecolors=GREEN,
             zorder=2)
        for code, colour in ((RIGHT, BLUE), (WRONG, VERMILLION), (UNCLASSIFIED, YELLOW)):
            bars(y, [(w.begin, w.end) for w in items
                     if w.kind == "classify" and outcome[w.poi] == code],
                 facecolors=colour, zorder=2)
        bars(y, [(w.begin, w.end) for w in items if w.kind == "rebrief"], facecolors=PURPLE,
             zorder=2)
        busy = _covered([(w.start, min(w.end, ep.horizon_s)) for w in items])
        ax.text(end * 1.01, y, f"idle {1 - busy / ep.horizon_s:.0%}", va="center", fontsize=8.5)
    for robot in range(R):
        y = y_of[("R", robot)]
        bars(y, [(0.0, min(ep.fail_time[robot], ep.horizon_s))], facecolors="#EEEEEE", zorder=1)
        legs = [leg for leg in ep.legs if leg.robot == robot]
        bars(y, [(leg.start, leg.end) for leg in legs if leg.navigator < 0], facecolors=SKY,
             zorder=2)
        bars(y, [(leg.start, leg.end) for leg in legs if leg.navigator >= 0], facecolors=GREEN,
             zorder=2)
        bars(y, [(w.start, w.end) for w in ep.waits if w.robot == robot], facecolors=ORANGE,
             zorder=2)
        caps = [leg.end / 60.0 for leg in legs if leg.captured]
        ax.plot(caps, [y] * len(caps), ls="none", marker="|", markersize=11, color="black",
                markeredgewidth=1.1, zorder=3)
        holds = [t / 60.0 for t, rr in ep.replans if rr == robot]
        ax.plot(holds, [y + height / 2 + 0.08] * len(holds), ls="none", marker="v",
                markersize=5, color="black", zorder=3)
        ft = ep.fail_time[robot]
        if ft <= ep.horizon_s:
            bars(y, [(ft, ep.horizon_s)], facecolors="white", edgecolors=GREY, hatch="xx",
                 linewidths=0.0, zorder=1)
            ax.plot([ft / 60.0], [y], marker="X", markersize=10, color="black", zorder=4)
        ax.text(end * 1.01, y, f"{len(caps)} captures", va="center", fontsize=8.5)
    _reallocation_lines(ax, ep, zorder=5, counts_at=len(rows) + 0.97)
    ax.set_yticks([y_of[row] for row in rows])
    ax.set_yticklabels([human_label(ep, i) if k == "H" else robot_label(ep, i)
                        for k, i in rows], fontsize=9)
    ax.set_ylim(0.4, len(rows) + 1.4)
    ax.set_xlim(0, end)
    ax.set_xticks(np.arange(0, end + 1e-9, 5 if end > 10 else 1))
    ax.set_xlabel("time (min)")
    ax.axhline((y_of[("H", H - 1)] + y_of[("R", 0)]) / 2, color="black", lw=0.6)
    for side in ("top", "right"):
        ax.spines[side].set_visible(False)
    ax.set_title(_title(ep, "Timeline"), fontsize=10, loc="left")
    handles = [Patch(fc="#EEEEEE", label="idle"),
               Patch(fc=GREEN, label="navigating / navigated leg"),
               Patch(fc=BLUE, label="classification, right"),
               Patch(fc=VERMILLION, label="classification, wrong"),
               Patch(fc=YELLOW, label="classification ends after the horizon"),
               Patch(fc=PURPLE, label="re-brief (reallocation)"),
               Patch(fc="white", ec="black", hatch="////", label="SA switch cost"),
               Patch(fc=SKY, label="robot travel, autonomous"),
               Patch(fc=ORANGE, label="robot waits for its navigator"),
               Line2D([], [], ls="none", marker="|", markersize=11, color="black",
                      markeredgewidth=1.1, label="capture (end of leg)"),
               Line2D([], [], ls="none", marker="v", markersize=5, color="black",
                      label="re-plan hold"),
               Line2D([], [], ls="none", marker="X", markersize=9, color="black",
                      label="robot failure"),
               Patch(fc="white", ec=GREY, hatch="xx", label="robot down"),
               Line2D([], [], color="#444444", lw=0.9,
                      label="reallocation (number: POIs changed)"),
               Line2D([], [], color=GREY, lw=0.8, ls=":",
                      label="reallocation (nothing changed)")]
    fig.legend(handles=handles, loc="lower center", ncols=4, fontsize=8.5, frameon=False,
               bbox_to_anchor=(0.5, 0.02))


def _covered(spans: list[tuple[float, float]]) -> float:
    """Total length of a union of intervals."""
    total, reach = 0.0, -np.inf
    for a, b in sorted(spans):
        if b > reach:
            total += b - max(a, reach)
            reach = b
    return total


def draw_humans(ep: Episode, fig: Any) -> None:
    """Per human: true fatigue F_f and the F_f policies saw (after the injectors), utilisation
    over the trailing window, SA, re-briefs and the reallocation epochs."""
    from matplotlib.lines import Line2D   # on use: matplotlib's start-up time

    H = ep.skill.size
    cols = 2 if H > 1 else 1
    nrows = int(np.ceil(H / cols))
    axes = fig.subplots(nrows, cols, sharex=True, sharey=True, squeeze=False)
    minutes = ep.times / 60.0
    seen = ep.fatigue_seen
    low = min(-0.05, float(np.nanmin(seen)) - 0.05)
    high = max(1.08, float(np.nanmax(seen)) + 0.05)
    for human in range(H):
        ax = axes[human // cols, human % cols]
        ax.axhspan(0.0, 1.0, color="#F4F4F4", zorder=0)
        _reallocation_lines(ax, ep)
        ax.plot(minutes, ep.fatigue[human], color=BLUE, lw=1.8, zorder=3)
        ax.plot(ep.epoch_times / 60.0, seen[human], ls="none", marker="o", markersize=3.8,
                markerfacecolor="white", markeredgecolor=BLUE, markeredgewidth=1.0, zorder=4)
        ax.plot(minutes, ep.utilisation[human], color=VERMILLION, lw=1.3, zorder=2)
        ax.plot(minutes, ep.sa[human], color=GREEN, lw=1.3, zorder=2)
        rebriefs = [w.start / 60.0 for w in ep.work if w.human == human and w.kind == "rebrief"]
        ax.plot(rebriefs, [low + 0.04] * len(rebriefs), ls="none", marker="^", markersize=6,
                color=PURPLE, zorder=4)
        ax.set_title(f"{human_label(ep, human)}, {ep.working_h[human, 0]:.2f} h worked at "
                     f"t = 0", fontsize=9.5, loc="left")
        ax.set_ylim(low, high)
        ax.set_xlim(0, ep.horizon_s / 60.0)
        ax.grid(axis="y", color="#DDDDDD", lw=0.5)
        if human // cols == nrows - 1:
            ax.set_xlabel("time (min)")
        if human % cols == 0:
            ax.set_ylabel("F_f, utilisation, SA")
    for extra in range(H, nrows * cols):            # an empty panel: the one above gets the axis
        axes[extra // cols, extra % cols].set_visible(False)
        above = axes[extra // cols - 1, extra % cols]
        above.xaxis.set_tick_params(labelbottom=True)
        above.set_xlabel("time (min)")
    fig.suptitle(_title(ep, "Humans"), fontsize=10, x=0.07, y=1 - 0.12 / fig.get_figheight(),
                 ha="left", va="top")
    window = f"{ep.window_s:.0f} s" if ep.window_s < 120 else f"{ep.window_s / 60:.0f} min"
    handles = [Line2D([], [], color=BLUE, lw=1.8, label="fatigue F_f, true"),
               Line2D([], [], ls="none", marker="o", markersize=4.5, markerfacecolor="white",
                      markeredgecolor=BLUE, label="fatigue F_f, observed by policies (each epoch)"),
               Line2D([], [], color=VERMILLION, lw=1.3,
                      label=f"utilisation (busy share of the last {window})"),
               Line2D([], [], color=GREEN, lw=1.3, label="situational awareness SA"),
               Line2D([], [], ls="none", marker="^", markersize=6, color=PURPLE,
                      label="re-brief"),
               Line2D([], [], color="#444444", lw=0.9, label="reallocation (POIs changed)"),
               Line2D([], [], color=GREY, lw=0.8, ls=":",
                      label="reallocation (nothing changed)")]
    inches = fig.get_figheight()
    fig.subplots_adjust(left=0.07, right=0.98, top=1 - 0.75 / inches, bottom=1.35 / inches,
                        hspace=0.32, wspace=0.06)
    fig.legend(handles=handles, loc="lower center", ncols=3, fontsize=8.5, frameon=False,
               bbox_to_anchor=(0.5, 0.01))


def write_figures(ep: Episode, out_dir: str | Path) -> list[Path]:
    """Draw the three pictures of `ep` into `out_dir`, each as PNG and SVG; the paths."""
    Figure = figure_class()              # no matplotlib: one clear message first
    import matplotlib   # on use: matplotlib's start-up time

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    H, R = ep.skill.size, ep.robot_type.size
    figures = [(STEMS[0], (11.0, 8.2), draw_map),
               (STEMS[1], (13.0, 0.42 * (H + R) + 3.0), draw_timeline),
               (STEMS[2], (12.5, 2.2 * np.ceil(H / 2) + 2.1), draw_humans)]
    written = []
    with matplotlib.rc_context({"font.size": 9}):
        for stem, size, draw in figures:
            fig = Figure(figsize=size)
            draw(ep, fig)
            written += save_figure(fig, out, stem, tight=False, salt="ata-show")
    return written
