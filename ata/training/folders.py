"""Training folders as users meet them: one run's folder (what `ata run DIR` and a suite's
method evaluate: its best weights), and a folder of several seeds (`ata train --seeds N`), each
seed a run folder of its own, ``seed-S``, trained side by side (`ata.experiment.training`).

A folder of seeds holds ``seeds.json`` (the seeds, the trainer, the training mission and its
overrides) and ``seed-S/`` for each seed S; ``ata train --resume DIR`` carries every seed on from
its own checkpoint (a finished seed does nothing more).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import tomli_w

from ata.core.errors import MissionError
from ata.core.mission import read_toml

SEEDS_FILE = "seeds.json"
RESOLVED = "mission.resolved.toml"
REPORT = "trained.json"
"""A finished run's summary, written as its last step: a run without it has not finished."""


def is_seeds_folder(path: str | Path) -> bool:
    return (Path(path) / SEEDS_FILE).is_file()


def is_run_folder(path: str | Path) -> bool:
    """A single `ata train` run folder (its resolved mission and log.csv)."""
    p = Path(path)
    return (p / RESOLVED).is_file() and (p / "log.csv").is_file() \
        and not (p / "results.csv").exists()


SEEDS_LIMIT = 1000
"""The most seeds one folder trains: each seed is a whole training run and a folder of its own."""


def parse_seeds(text: str) -> list[int]:
    """``--seeds``: a count N (seeds 0 .. N-1) or a list ``1,2,5``, at most `SEEDS_LIMIT` seeds
    (the trainer's settings bound each seed)."""
    text = str(text)
    if len(text) > 24 * SEEDS_LIMIT:
        raise MissionError("--seeds", None, f"at most {SEEDS_LIMIT:,} seeds")
    parts = [t.strip() for t in text.split(",") if t.strip()]
    try:
        values = [int(t) for t in parts]
    except ValueError:
        values = []
    if not values:
        raise MissionError("--seeds", None, f"{text!r}: give a count (3) or a list of seeds "
                           "(1,2,5)")
    if len(values) == 1 and "," not in text:
        if not 1 <= values[0] <= SEEDS_LIMIT:
            raise MissionError("--seeds", None, f"the count must be 1 to {SEEDS_LIMIT:,} (each "
                               "seed is a whole training run)")
        return list(range(values[0]))
    if len(values) > SEEDS_LIMIT:
        raise MissionError("--seeds", None, f"{len(values):,} seeds: at most {SEEDS_LIMIT:,}")
    if len(set(values)) != len(values) or any(v < 0 for v in values):
        raise MissionError("--seeds", None, f"{text!r}: the seeds must differ and be >= 0")
    return values


def read_seeds(folder: str | Path) -> dict[str, Any]:
    """seeds.json of a folder of seeds, with ``dirs``: each seed's run folder."""
    folder = Path(folder)
    try:
        data = json.loads((folder / SEEDS_FILE).read_text(encoding="utf-8"))
        seeds = [int(s) for s in data["seeds"]]
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise MissionError("", None, f"not a readable folder of seeds ({exc})",
                           file=str(folder / SEEDS_FILE)) from None
    data["seeds"] = seeds
    data["dirs"] = [folder / seed_dir_name(s) for s in seeds]
    return data


def seed_dir_name(seed: int) -> str:
    return f"seed-{seed}"


def write_seeds(folder: Path, seeds: list[int], info: dict[str, Any]) -> None:
    folder.mkdir(parents=True, exist_ok=True)
    (folder / SEEDS_FILE).write_text(json.dumps({"seeds": seeds, **info}, indent=2) + "\n",
                                     encoding="utf-8")


def trained_mission(folder: str | Path) -> str:
    """The mission that evaluates a run folder's trained weights: its resolved mission (whose
    trained components' checkpoint keys name its best.pt), once best.pt exists."""
    folder = Path(folder)
    if is_seeds_folder(folder):
        dirs = read_seeds(folder)["dirs"]
        raise MissionError("", None, f"a folder of {len(dirs)} seeds: name one of them "
                           f"({dirs[0]}), or evaluate them all with `ata eval {folder}`",
                           file=str(folder))
    if not is_run_folder(folder):
        raise MissionError("", None, "a folder, not a mission file, and not an `ata train` "
                           "run folder (its mission.resolved.toml and log.csv)",
                           file=str(folder))
    if not (folder / "best.pt").is_file():
        raise MissionError("", None, "holds no best.pt yet: train on (ata train --resume "
                           f"{folder}) until a validation writes one", file=str(folder))
    for table, settings in read_toml(folder / RESOLVED).items():
        value = settings.get("checkpoint") if isinstance(settings, dict) else None
        if isinstance(value, str) and value.endswith("best.pt") \
                and Path(value).resolve() != (folder / "best.pt").resolve():
            raise MissionError(f"[{table}]", "checkpoint", f"names {value}, not this folder's "
                               "best.pt (a folder moved or copied after training): point it "
                               "at this folder's best.pt", file=str(folder / RESOLVED))
    return str(folder / RESOLVED)


def trained_methods(folder: str | Path, label: str) -> list[tuple[str, str]]:
    """(method name, mission file) of each run of a training folder: one for a run folder,
    ``LABEL seed S`` for each seed of a folder of seeds."""
    folder = Path(folder)
    if is_seeds_folder(folder):
        data = read_seeds(folder)
        return [(f"{label} seed {s}", trained_mission(d))
                for s, d in zip(data["seeds"], data["dirs"])]
    return [(label, trained_mission(folder))]


def write_report(folder: Path, report: dict[str, Any]) -> None:
    """trained.json: a finished run's summary (best held-out score, training time, steps)."""
    keep = {k: report[k] for k in ("best_eval", "wall_s", "counters") if k in report}
    (Path(folder) / REPORT).write_text(json.dumps(keep, indent=2, default=float)
                                               + "\n", encoding="utf-8")


def trained_suite(folder: str | Path) -> str:
    """The suite file `ata eval FOLDER` reads: a folder of seeds' suite.toml (every seed's best
    weights against greedy, at the training mission's setting and level), or a run folder's
    resolved mission."""
    folder = Path(folder)
    if is_seeds_folder(folder):
        return str(folder / SUITE_FILE)
    return trained_mission(folder)


SUITE_FILE = "suite.toml"


def write_suite(folder: Path, seeds: list[int], label: str, setting: str, level: str) -> None:
    """A folder of seeds' suite.toml: each seed a method, paired with greedy."""
    methods = [f"{label} seed {s}" for s in seeds]
    suite = {"suite": {"name": f"{label}-seeds", "settings": [setting], "uncertainty": [level],
                       "pairs": [[m, "greedy"] for m in methods]},
             "method": [{"name": label, "mission": "."},
                        {"name": "greedy", "mission": "builtin:greedy"}]}
    (folder / SUITE_FILE).write_text("# `ata eval` of this folder: every seed's best.pt "
                                     "against greedy\n" + tomli_w.dumps(suite),
                                     encoding="utf-8")
