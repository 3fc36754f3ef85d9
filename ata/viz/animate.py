"""The map of an episode through time (`show_map.gif`): one frame per epoch, drawn at the epoch's
end, with the robots on their routes, the POIs changing state as they are captured, classified
and revealed, and the robots' failures as they happen.

Frames are drawn with matplotlib's Agg canvas and written with Pillow (a dependency of
matplotlib), so no external program is needed. Positions between a leg's ends are interpolated
over the leg's time, capture included: a robot is where the map of `draw` puts it, to a few
metres.
"""

from __future__ import annotations

import contextlib
from pathlib import Path
from typing import Any, Callable, ContextManager

import numpy as np

from ata.viz.draw import (BLUE, GREEN, GREY, KIND_MARKERS, OUTCOME_COLOURS, VERMILLION, YELLOW,
                          figure_class, robot_colour, robot_label, route_style)
from ata.viz.record import RIGHT, UNCLASSIFIED, UNVISITED, WRONG, Episode

STEM = "show_map"
SIZE_IN, DPI = (8.0, 6.4), 80
"""The frames' size: 640 x 512 pixels."""
FRAME_MS = 400
"""How long each frame shows, ms (a 30-epoch episode lasts 12 s)."""


MAX_FRAMES = 150
"""Frames at most: each takes about a third of a second to draw, so a long episode (720
epochs took 223 s) shows every k-th epoch instead, the last one always."""


def frame_epochs(ep: Episode) -> np.ndarray:
    """The epochs drawn: every one, or every k-th (and the last) when there are more than
    `MAX_FRAMES`."""
    n = len(ep.epoch_times)
    step = -(-n // MAX_FRAMES)
    return np.unique(np.append(np.arange(0, n, step), n - 1)) if n else np.arange(0)


def frame_times(ep: Episode) -> np.ndarray:
    """The time of each frame, s: the end of each epoch."""
    return ep.epoch_times + ep.epoch_s


def poi_states(ep: Episode, t: float) -> np.ndarray:
    """(P,) each POI's state at time t: UNVISITED, UNCLASSIFIED (captured, waiting for its
    classification), RIGHT or WRONG (classified)."""
    classified = ep.classified_at <= t
    return np.where(classified, np.where(ep.gain > 0, RIGHT, WRONG),
                    np.where(ep.capture_time <= t, UNCLASSIFIED, UNVISITED))


def robot_at(ep: Episode, robot: int, t: float) -> tuple[tuple[float, float], list, bool]:
    """Where `robot` is at time t, the points of its route so far, and whether a human
    navigates it then."""
    pos, trail = ep.base, [ep.base]
    for leg in (leg for leg in ep.legs if leg.robot == robot):
        if t >= leg.end:
            pos = leg.dest
            trail.append(pos)
            continue
        if t > leg.start:
            share = (t - leg.start) / (leg.end - leg.start)
            pos = (leg.origin[0] + share * (leg.dest[0] - leg.origin[0]),
                   leg.origin[1] + share * (leg.dest[1] - leg.origin[1]))
            trail.append(pos)
            return pos, trail, leg.navigator >= 0
        break
    return pos, trail, False


def draw_frame(ep: Episode, ax: Any, k: int, t: float) -> None:
    """Epoch k's frame (at time t) on a cleared axis."""
    area = ep.area_m
    state = poi_states(ep, t)
    revealed = ep.reveal_time <= t
    kind = np.where(revealed, ep.true_kind, ep.est_kind)
    for code in (UNVISITED, UNCLASSIFIED, RIGHT, WRONG):
        for k_code, shape in KIND_MARKERS.items():
            mask = (state == code) & (kind == k_code)
            ax.scatter(ep.poi_pos[mask, 0], ep.poi_pos[mask, 1], s=70, marker=shape,
                       facecolors=OUTCOME_COLOURS[code], edgecolors="black", linewidths=0.8,
                       zorder=3)
    changed = revealed & ep.changed
    ax.scatter(ep.poi_pos[changed, 0], ep.poi_pos[changed, 1], s=260, marker="o",
               facecolors="none", edgecolors="black", linewidths=0.8, linestyles="--", zorder=2)
    ax.plot(*ep.base, marker="*", markersize=16, color="black", zorder=4)
    for robot in range(ep.robot_type.size):
        pos, trail, navigated = robot_at(ep, robot, t)
        xs, ys = zip(*trail)
        colour = robot_colour(robot)
        ax.plot(xs, ys, color=colour, lw=1.2, alpha=0.6, ls=route_style(ep, robot), zorder=1)
        if ep.fail_time[robot] <= t:
            ax.plot(*pos, marker="X", markersize=12, color=GREY, markeredgecolor="black",
                    zorder=5)
            continue
        ax.plot(*pos, marker="o", markersize=13, color=colour, zorder=5,
                markeredgecolor=GREEN if navigated else "black",
                markeredgewidth=2.5 if navigated else 1.0)
        ax.text(*pos, str(robot), color="white", fontsize=7, fontweight="bold", ha="center",
                va="center", zorder=6)
    ax.set_xlim(0, area)
    ax.set_ylim(0, area)
    ax.set_aspect("equal")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    done = np.isfinite(ep.classified_at) & (ep.classified_at <= t)
    score = float(np.sum(ep.r_perf[:k + 1]))
    ax.set_title(f"{ep.mission!r}, scenario {ep.scenario}: minute {t / 60:.0f} of "
                 f"{ep.horizon_s / 60:.0f}, epoch {k + 1}; {int(done.sum())} of "
                 f"{state.size} POIs classified, {score:.0f} points", fontsize=9, loc="left")


def legend(ep: Episode, fig: Any) -> None:
    """What the marks mean, once, right of the map."""
    from matplotlib.lines import Line2D   # on use: matplotlib's start-up time

    def mark(label: str, shape: str = "o", face: str = "white", edge: str = "black",
             width: float = 0.8, size: float = 8.0) -> Line2D:
        return Line2D([], [], ls="none", marker=shape, markersize=size, markerfacecolor=face,
                      markeredgecolor=edge, markeredgewidth=width, label=label)

    handles = [mark("not visited"), mark("captured, not classified", face=YELLOW),
               mark("classified right", face=BLUE), mark("classified wrong", face=VERMILLION),
               mark("air POI", "^"), mark("ground POI", "s"),
               Line2D([], [], ls="none", marker="o", markersize=13, markerfacecolor="none",
                      markeredgecolor="black", label="attribute changed (revealed)"),
               mark("robot N, navigated by a human", "o", "white", GREEN, 2.5, 11),
               mark("robot failed", "X", GREY, size=10), mark("base", "*", "black", size=12)]
    handles += [Line2D([], [], color=robot_colour(r), lw=1.5, ls=route_style(ep, r),
                       label=f"{robot_label(ep, r)}, route so far")
                for r in range(ep.robot_type.size)]
    fig.legend(handles=handles, loc="center left", bbox_to_anchor=(0.70, 0.5), fontsize=7.5,
               frameon=False)


def write_animation(ep: Episode, out_dir: str | Path,
                    progress: Callable[[str, int, int], ContextManager[Callable[[float], None]]]
                    | None = None) -> Path:
    """Write `out_dir`/show_map.gif, one frame per epoch (at most `MAX_FRAMES`: `frame_epochs`),
    looping; its path. `progress` (`ata.experiment.execute.ProgressFactory`) is told of each
    frame drawn."""
    Figure = figure_class()              # no matplotlib: one clear message first
    from matplotlib.backends.backend_agg import FigureCanvasAgg  # matplotlib's start-up time
    from PIL import Image   # on use: matplotlib's start-up time

    fig = Figure(figsize=SIZE_IN, dpi=DPI)
    canvas = FigureCanvasAgg(fig)
    ax = fig.add_axes((0.08, 0.08, 0.6, 0.84))
    legend(ep, fig)
    frames = []
    times, epochs = frame_times(ep), frame_epochs(ep)
    bar = progress("frames of show_map.gif", len(epochs), 0) if progress is not None else \
        contextlib.nullcontext(lambda n: None)
    with bar as advance:
        for k in epochs:
            ax.clear()
            draw_frame(ep, ax, int(k), float(times[k]))
            canvas.draw()
            width, height = canvas.get_width_height()
            frame = Image.frombuffer("RGBA", (width, height), canvas.buffer_rgba(), "raw",
                                     "RGBA", 0, 1)
            frames.append(frame.convert("RGB").quantize(colors=255, dither=Image.Dither.NONE))
            advance(1)
    path = Path(out_dir) / f"{STEM}.gif"
    frames[0].save(path, save_all=True, append_images=frames[1:], duration=FRAME_MS, loop=0,
                   optimize=False)
    return path
