"""`ata show`: replay one scenario of a run folder or a mission file with the recorder attached,
and draw it.

A run folder is read through its ``mission.resolved.toml``; the replay runs the one scenario as a
batch of one, which gives the results it had in the run (a scenario's numbers depend on the root
seed and its id alone), and is checked against the run's ``results.csv`` row.
"""

from __future__ import annotations

import csv
import tomllib
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ata.core import mission as mission_mod
from ata.core.errors import MissionError
from ata.session import BUILTIN_MISSION, Session, load_session
from ata.runtime.folders import named_folder, prepare_out_dir, writing
from ata.experiment.units import scenario_ids, one_thread
from ata.viz import draw
from ata.viz.animate import write_animation
from ata.viz.record import Episode, replay

RUN_MISSION = "mission.resolved.toml"
"""The mission file of a run folder (written by `ata run`)."""


@dataclass
class Shown:
    """What `show` did: the episode, the files written, and the run's score for the scenario
    (None when there is no run folder, no row for it, or the mission was overridden)."""

    episode: Episode
    written: list[Path]
    out_dir: Path
    run_score: float | None
    results: Path | None


def mission_of(target: str | None) -> tuple[str, Path | None]:
    """The mission file to replay and the run folder it belongs to (None for a mission file;
    the built-in mission when `target` is None)."""
    if target is None:
        return str(BUILTIN_MISSION), None
    path = Path(target)
    if path.is_dir():
        if not (path / RUN_MISSION).is_file():
            raise MissionError("", None, f"no {RUN_MISSION} here: not a run folder (give a "
                               "folder written by ata run, or a mission file)", file=str(path))
        return str(path / RUN_MISSION), path
    return str(path), None


def run_score(run_dir: Path, scenario: int) -> float | None:
    """The score of `scenario` in the run folder's results.csv, or None without one."""
    path = run_dir / "results.csv"
    if not path.is_file():
        return None
    with open(path, newline="", encoding="utf-8") as f:
        for row in csv.DictReader(f):
            if row.get("scenario") == str(scenario):
                return float(row["score"])
    return None


def check_whole(source: str, session: Session) -> None:
    """Refuse a run folder's resolved mission that lacks a key of its own resolution: the file
    was cut short (or written by another version), and defaults would fill the gap, replaying
    another mission than the run's."""
    written = mission_mod.read_toml(source)
    resolved = tomllib.loads(session.mission.to_toml())
    missing = [f"[{table}]" if table not in written else f"[{table}] {key}"
               for table, keys in resolved.items() for key in keys
               if not isinstance(written.get(table), dict) or key not in written[table]]
    missing = list(dict.fromkeys(missing))
    if missing:
        more = f" and {len(missing) - 3} more" if len(missing) > 3 else ""
        raise MissionError("", None, f"not a whole resolved mission: {', '.join(missing[:3])}"
                           f"{more} missing (the file was cut short, or written by another "
                           "version of ata); a replay would fill them with defaults and show "
                           "another mission than the run's", file=source)


def show(target: str | None, scenario: int | None, overrides: list[str] | None = None,
         out: str | Path | None = None, animate: bool = False, progress: Any = None) -> Shown:
    """Replay `scenario` (default: the mission's first) of a run folder or mission file and
    write its three pictures, PNG and SVG (with `animate`, the map through time as a GIF too),
    to `out` (default: RUN_DIR/show-N, or runs/show-NAME-N). Bad input raises MissionError
    before anything runs or is written. `progress` (a progress-bar factory, as `ata run`'s)
    is told of the animation's frames."""
    source, run_dir = mission_of(target)
    session = load_session(source, list(overrides or []))
    if run_dir is not None:
        check_whole(source, session)
    m = session.mission
    ids = scenario_ids(m)
    first, last = int(ids[0]), int(ids[-1])
    scenario = first if scenario is None else scenario
    if not first <= scenario <= last:
        raise MissionError("--scenario", None, f"{scenario} is not one of the mission's "
                           f"scenarios: ids {first} to {last}", file=source)
    draw.figure_class()                   # no matplotlib: say so before the replay
    if out is None:
        out = (run_dir / f"show-{scenario}" if run_dir is not None else
               named_folder(f"show-{m.settings.name}-{scenario}"))
    out = prepare_out_dir(out, kind="show")   # unwritable, another's: say so before the replay
    # one torch thread, as a unit of the run has: the same reduction order, and no threads
    # waiting on each other for a batch of one (13 s instead of 0.7 s on a busy 2-core machine)
    with one_thread():
        episode = replay(m, session.registry, scenario)
    with writing(out):
        written = draw.write_figures(episode, out)
        if animate:
            written.append(write_animation(episode, out, progress))
    checked = run_dir is not None and not overrides
    score = run_score(run_dir, scenario) if checked else None
    return Shown(episode=episode, written=written, out_dir=Path(out), run_score=score,
                 results=run_dir / "results.csv" if score is not None else None)
