"""`ata train`: a training mission's trainer run into its run folder, or several seeds side by
side, each in a run folder of its own (``DIR/seed-S``) on the executors of `ata eval`; and
``--resume`` of either from its checkpoints.

The command is one call, `train`; what it tells the user goes through its callbacks.
"""

from __future__ import annotations

import contextlib
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, ContextManager

from ata.core.errors import MissionError
from ata.experiment.execute import Interrupted
from ata.experiment.interrupts import Interrupts
from ata.runtime.executors import make_executor
from ata.experiment.runner import default_out_dir
from ata.runtime.folders import prepare_out_dir
from ata.session import Session, build_trainer, load_session, training_mission_for
from ata.training import TrainRun
from ata.training import folders as fd
from ata.training.presets import preset_overrides, weights_overrides

RowBar = Callable[[str, Any], ContextManager[Callable[[dict | None], None]]]
"""``bar(title, trainer)``: a context whose value is told of each log.csv row, or of None to
catch up with the trainer's steps (the CLI's progress bar)."""


@dataclass
class Trained:
    """What `train` did: the run folder (or folder of seeds), and the report of a single run
    (``None`` for seeds: `on_seed` heard each one's)."""

    folder: Path
    report: dict[str, Any] | None
    seeds: list[int] | None = None


def train(mission: str | None = None, overrides: list[str] | None = None,
          plugins: list[str] | None = None, preset: str | None = None,
          seeds: str | None = None, out: str | Path | None = None,
          resume: str | Path | None = None, *, executor: str = "process",
          workers: int | None = None, address: str | None = None,
          bar: RowBar | None = None, notify: Callable[[str], None] | None = None,
          on_start: Callable[[Path, list[int] | None], None] | None = None,
          on_seed: Callable[[dict[str, Any]], None] | None = None) -> Trained:
    """Train the learned components of a mission with the trainer it names.

    :param mission: the training mission (default: the built-in one of `plugins`, else ctr,aux).
    :param preset: a recipe of the trainer (``presets``), under `overrides`.
    :param seeds: ``N`` or ``S,S``: a folder of seeds, trained side by side on `executor`.
    :param resume: a run folder or a folder of seeds, carried on from its checkpoints.
    :param on_start: told of the folder (and the seeds) as the training starts.
    :raises Interrupted: on Ctrl-C, saying what is saved and how to go on.
    """
    notify = notify or (lambda text: None)
    on_start = on_start or (lambda folder, values: None)
    if resume is not None:
        resume = Path(resume)
        if mission is not None or overrides or plugins or preset or seeds:
            notify("--resume uses the run folder's resolved mission; the MISSION, --plugins, "
                   "--preset, --seeds and --set given are ignored")
        if fd.is_seeds_folder(resume):
            data = fd.read_seeds(resume)
            values = data["seeds"]
            missing = [d.name for d in data["dirs"] if not (d / fd.RESOLVED).is_file()]
            if missing:             # refused before any seed trains on
                raise MissionError("--resume", None, f"{resume} is a folder of {len(values)} "
                                   f"seeds, but {', '.join(missing[:3])}"
                                   f"{' ...' if len(missing) > 3 else ''} holds no "
                                   f"{fd.RESOLVED}: put the seed's folder back, or train "
                                   "the seeds again in another folder")
            on_start(resume, values)
            train_seeds(resume, values, executor, workers, address, on_seed)
            return Trained(resume, None, values)
        session = load_session(str(resume / fd.RESOLVED))
        on_start(resume, None)
        return Trained(resume, train_one(session, resume, True, bar))
    values = fd.parse_seeds(seeds) if seeds is not None else None      # bounded, before work
    source = mission or str(training_mission_for(plugins or ["ctr", "aux"]))
    extra = plugins if mission else None      # a mission file brings its own plugins
    overrides = list(overrides or [])
    session = load_session(source, overrides, extra)
    name = session.mission.slots.trainer
    if preset:
        factory = session.registry.get("trainer", name, "[components] trainer").factory
        overrides = preset_overrides(name, factory, preset) + overrides
        session = load_session(source, overrides, extra)
    # each seed's overrides (a folder of seeds in a value: its run of the seed), refused
    # before any folder is made
    per_seed = {s: seed_overrides(overrides, s) for s in values or [None]}
    # a folder of seeds and a training run are folders of two kinds: neither is written over
    # by the other
    run_dir = prepare_out_dir(out, kind="train" if seeds is None else "seeds") if out else \
        default_out_dir(session.mission, prefix="train-")
    if values is None:
        session = with_weights(source, overrides, extra, session, run_dir)
        on_start(run_dir, None)
        return Trained(run_dir, train_one(session, run_dir, False, bar))
    info = {"trainer": name, "mission": source, "overrides": overrides, "preset": preset}
    if fd.is_seeds_folder(run_dir):
        values = more_seeds(run_dir, values, info)
    for s in values:
        folder = run_dir / fd.seed_dir_name(s)
        seeded = per_seed[s] + [f"{name}.seed={s}"]
        one = with_weights(source, seeded, extra, load_session(source, seeded, extra), folder)
        folder.mkdir(parents=True, exist_ok=True)
        if not (folder / "log.csv").exists():
            (folder / fd.RESOLVED).write_text(one.mission.to_toml(), encoding="utf-8")
    every = sorted(set(values) | set(fd.read_seeds(run_dir)["seeds"]
                                     if fd.is_seeds_folder(run_dir) else []))
    fd.write_seeds(run_dir, every, info)
    m = session.mission
    fd.write_suite(run_dir, every, m.settings.name, m.settings.setting, m.settings.uncertainty)
    on_start(run_dir, values)
    train_seeds(run_dir, values, executor, workers, address, on_seed)
    return Trained(run_dir, None, every)


def more_seeds(folder: Path, values: list[int], info: dict[str, Any]) -> list[int]:
    """The seeds to add to a folder of seeds trained by the same command (trainer, mission,
    overrides and preset): those of `values` it does not hold yet (``--seeds 5`` on a folder of
    seeds 0 and 1 adds 2, 3 and 4). A folder of another command is refused (its seeds are one
    recipe's), and so are seeds it holds every one of."""
    data = fd.read_seeds(folder)
    theirs = {k: data.get(k) for k in info}
    if theirs != info:
        differ = ", ".join(k for k in info if theirs[k] != info[k])
        raise MissionError("--out", None, f"{folder} holds seeds of another command (its "
                           f"{differ} differ): add seeds with the command that trained them, "
                           f"go on with ata train --resume {folder}, or choose another folder")
    new = [s for s in values if s not in data["seeds"]]
    if not new:
        raise MissionError("--out", None, f"{folder} holds every seed given already: go on "
                           f"with ata train --resume {folder}, or give seeds it does not hold")
    return new


def seed_overrides(overrides: list[str], seed: int | None) -> list[str]:
    """The ``--set`` overrides of seed `seed`: a value naming a folder of seeds (weights to
    start from, ``ata_hrl.ita_from=runs/ita``, say) names that folder's run of the same seed,
    ``DIR/seed-S/best.pt``. Without a seed (no ``--seeds``) such a value is refused."""
    out = []
    for text in overrides:
        key, sep, value = text.partition("=")
        folder = Path(value.strip().strip("'\""))
        if sep and value.strip() and fd.is_seeds_folder(folder):
            where = f"--set {key.strip()}"
            if seed is None:
                raise MissionError(where, None, f"{folder} is a folder of seeds: train with "
                                   "--seeds, each seed starting from that folder's run of the "
                                   "same seed, or name one run's best.pt")
            if seed not in fd.read_seeds(folder)["seeds"]:
                raise MissionError(where, None, f"{folder} is a folder of seeds without seed "
                                   f"{seed}: train the same seeds as it holds")
            run = folder / fd.seed_dir_name(seed)
            if not (run / fd.REPORT).is_file():
                # its best.pt is still moving: a start from it would not be the run's result
                raise MissionError(where, None, f"seed {seed} of {folder} has not finished "
                                   f"training (no {fd.REPORT} in {run}): let it finish, or "
                                   f"resume it with ata train --resume {folder}")
            best = run / "best.pt"
            text = f"{key.strip()}={str(best.resolve())!r}"
        out.append(text)
    return out


def with_weights(source: str, overrides: list[str], extra: list[str] | None,
                 session: Session, run_dir: Path) -> Session:
    """The session with the trained components' checkpoint keys naming the run's best.pt (if
    the trainer trains any), for the run folder's resolved mission."""
    weights = weights_overrides(build_trainer(session), (run_dir / "best.pt").resolve())
    return load_session(source, overrides + weights, extra) if weights else session


def train_one(session: Session, run_dir: Path, resume: bool,
              bar: RowBar | None = None) -> dict[str, Any]:
    """One run of the session's trainer in `run_dir`, to its end; its report (trained.json)."""
    trainer = build_trainer(session)
    m = session.mission
    run = None
    rows = bar(f"train {m.settings.name}", trainer) if bar is not None else \
        contextlib.nullcontext(lambda row: None)
    try:
        # a Ctrl-C lost where it landed (numba compiling a loop) stops at the next row the
        # trainer logs or tells of
        with Interrupts() as interrupts, rows as tell:
            def on_row(row: dict | None) -> None:
                interrupts.check()
                tell(row)
            run = TrainRun(run_dir, m.to_toml(), trainer.log_fields, resume=resume,
                           on_row=on_row)
            on_row(None)
            report = trainer.run(run, resume=resume)
    except KeyboardInterrupt:
        raise Interrupted(training_saved(run_dir)) from None
    finally:
        if run is not None:
            run.close()
    fd.write_report(run_dir, report)
    return report


def train_seeds(folder: Path, seeds: list[int], executor: str, workers: int | None,
                address: str | None,
                on_seed: Callable[[dict[str, Any]], None] | None = None) -> None:
    """Every seed's run of a folder of seeds, side by side on the executor; each resumes from
    its own checkpoint. `on_seed` hears each finished seed's summary."""
    units = [{"seed": s, "dir": str(folder / fd.seed_dir_name(s))} for s in seeds]
    try:
        with make_executor(executor, workers or None, address) as ex:
            for _, report in ex.run(train_seed, units):
                if on_seed is not None:
                    on_seed(report)
    except KeyboardInterrupt:
        raise Interrupted(f"interrupted: each seed keeps its last checkpoint; run ata train "
                          f"--resume {folder} to go on from them") from None


def train_seed(unit: dict[str, Any]) -> dict[str, Any]:
    """One seed's run, in a worker (process pool or Ray): its folder's resolved mission,
    trained (or resumed, if its folder has a log) to the end, quietly; its summary."""
    folder = Path(unit["dir"])
    resume = (folder / "log.csv").is_file()
    session = load_session(str(folder / fd.RESOLVED))
    trainer = build_trainer(session)
    run = TrainRun(folder, session.mission.to_toml(), trainer.log_fields, resume=resume)
    try:
        report = trainer.run(run, resume=resume)
    finally:
        run.close()
    fd.write_report(folder, report)
    return {"seed": unit["seed"], "dir": str(folder), "best_eval": report.get("best_eval"),
            "wall_s": report.get("wall_s")}


def training_saved(run_dir: str | Path) -> str:
    """What an interrupted `ata train` left in its run folder and how to go on, read from the
    folder's files (the trainers save checkpoint.pt as they go)."""
    folder = Path(run_dir)
    checkpoint = folder / "checkpoint.pt"
    if not checkpoint.is_file():
        return (f"interrupted before the first checkpoint: nothing to resume in {folder}; run "
                "the same command again to start over")
    saved = time.strftime("%Y-%m-%d %H:%M:%S", time.localtime(checkpoint.stat().st_mtime))
    return (f"interrupted: the last checkpoint, saved {saved}, is {checkpoint}; run ata train "
            f"--resume {folder} to go on from it (the steps after it run again)")
