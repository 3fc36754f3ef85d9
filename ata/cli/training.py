"""`ata train`."""

from __future__ import annotations

from pathlib import Path
from typing import List, Optional

import typer

from ata.cli.common import AddressOption, SetOption, _split, app, user_errors
from ata.experiment import terminal
from ata.experiment.interrupts import Interrupts
from ata.experiment.terminal import console, err_console, escape, note


@app.command()
@user_errors
def train(mission: Optional[str] = typer.Argument(
              None, metavar="MISSION",
              help="Training mission (TOML) naming a trainer in \\[components]. Default: the "
                   "built-in training mission of the --plugins given."),
          set_: Optional[List[str]] = SetOption,
          plugins: Optional[str] = typer.Option(
              None, "--plugins", metavar="NAME[,NAME]",
              help="Without a mission file, pick the built-in training mission of these "
                   "optional plugins: ctr,aux (the default) the full ATA-HRL; ctr w/o.AUX; ita "
                   "the ITA alone; trp TR-POMDP; ita,trp AtRL-TR. w/o.C: add --set "
                   "components.condition=always."),
          preset: Optional[str] = typer.Option(
              None, "--preset", metavar="NAME",
              help="A recipe of the trainer, under the --set given: smoke trains every phase "
                   "in about a minute, to try a change."),
          seeds: Optional[str] = typer.Option(
              None, "--seeds", metavar="N|S,S",
              help="Train N seeds (0..N-1) or these seeds, each in DIR/seed-S, side by side "
                   "on --executor."),
          executor: str = typer.Option("process", "--executor", "-e", metavar="NAME",
                                       help="With --seeds: serial, process or ray."),
          workers: Optional[int] = typer.Option(None, "--workers", "-w", min=1, metavar="N",
                                                help="With --seeds: seeds at once (default: "
                                                     "one per core)."),
          address: Optional[str] = AddressOption,
          out: Optional[Path] = typer.Option(None, "--out", "-o", metavar="DIR",
                                             help="Run folder."),
          resume: Optional[Path] = typer.Option(None, "--resume", metavar="DIR",
                                                help="Resume the run (or the seeds) in this "
                                                     "folder."),
          quiet: bool = typer.Option(False, "--quiet", "-q", help="No progress bar.")) -> None:
    """Train the learned components of a mission with the trainer it names (ata_hrl: ATA-HRL
    and its ablations; tr_pomdp: the TR-POMDP agents, also after the attention ITA for AtRL-TR)."""
    from ata.experiment import runner
    from ata.experiment.execute import Interrupted
    from ata.experiment.folders import prepare_out_dir
    from ata.training import TrainRun
    from ata.training import seeds as sd
    from ata.core.errors import MissionError
    from ata.training.presets import preset_overrides

    if resume is not None:
        if mission is not None or set_ or plugins or preset or seeds:
            err_console.print("[yellow]note:[/] --resume uses the run folder's resolved "
                              "mission; the MISSION, --plugins, --preset, --seeds and --set "
                              "given are ignored")
        if sd.is_seeds_folder(resume):
            _train_seeds(resume, sd.read_seeds(resume)["seeds"], executor, workers, address,
                         quiet)
            return
        session = runner.load_session(str(resume / "mission.resolved.toml"))
        run_dir = resume
    else:
        names = _split(plugins) if plugins is not None else None
        source = mission or str(runner.training_mission_for(names or ["ctr", "aux"]))
        extra = names if mission else None   # a mission file brings its own plugins
        overrides = list(set_ or [])
        session = runner.load_session(source, overrides, extra)
        name = session.mission.slots.trainer
        if preset:
            factory = session.registry.get("trainer", name, "[components] trainer").factory
            overrides = preset_overrides(name, factory, preset) + overrides
            session = runner.load_session(source, overrides, extra)
        default = (lambda: runner.default_out_dir(session.mission, prefix="train-"))
        run_dir = prepare_out_dir(out, kind="train") if out else default()
        if seeds is not None:
            values = sd.parse_seeds(seeds)
            if sd.is_seeds_folder(run_dir):
                raise MissionError("--out", None, f"{run_dir} holds seeds already: go on "
                                   f"with ata train --resume {run_dir}, or choose another "
                                   "folder")
            for s in values:
                folder = run_dir / sd.seed_dir_name(s)
                one = runner.load_session(source, overrides + [f"{name}.seed={s}"], extra)
                one = _with_weights(runner, source, overrides + [f"{name}.seed={s}"], extra,
                                    one, folder)
                folder.mkdir(parents=True, exist_ok=True)
                if not (folder / "log.csv").exists():
                    (folder / "mission.resolved.toml").write_text(one.mission.to_toml(),
                                                                  encoding="utf-8")
            sd.write_seeds(run_dir, values, {"trainer": name, "mission": source,
                                             "overrides": overrides, "preset": preset})
            m = session.mission
            sd.write_suite(run_dir, values, m.settings.name, m.settings.setting,
                           m.settings.uncertainty)
            _train_seeds(run_dir, values, executor, workers, address, quiet)
            return
        session = _with_weights(runner, source, overrides, extra, session, run_dir)
    trainer = runner.build_trainer(session)
    m = session.mission
    if not quiet:
        _curves_note(run_dir)
    run = None
    try:
        # a Ctrl-C lost where it landed (numba compiling a loop) stops at the next row the
        # trainer logs or tells of
        with Interrupts() as interrupts, \
                terminal.training_bar(f"train {m.settings.name}", trainer, quiet) as bar:
            def on_row(row: dict | None) -> None:
                interrupts.check()
                bar(row)
            run = TrainRun(run_dir, m.to_toml(), trainer.log_fields, resume=resume is not None,
                           on_row=on_row)
            on_row(None)
            report = trainer.run(run, resume=resume is not None)
    except KeyboardInterrupt:
        raise Interrupted(runner.training_saved(run_dir)) from None
    finally:
        if run is not None:
            run.close()
    sd.write_report(run_dir, report)
    best = report.get("best_eval", float("nan"))
    console.print(f"trained in {report['wall_s']:.0f} s of training time; best held-out "
                  f"score {best:.1f}")
    for key, value in (report.get("aux") or {}).items():
        console.print(f"  {key}: {value:.5f}")
    console.print(f"run folder: {escape(str(run_dir))} (checkpoint.pt, best.pt, log.csv)",
                  highlight=False)
    _curves_note(run_dir, done=True)
    console.print(f"evaluate the trained weights: ata run {escape(str(run_dir))}",
                  highlight=False)


def _with_weights(runner, source, overrides, extra, session, run_dir: Path):
    """The session with the trained components' checkpoint keys naming the run's best.pt (if
    the trainer trains any), for the run folder's resolved mission."""
    from ata.training.presets import weights_overrides
    trainer = runner.build_trainer(session)
    weights = weights_overrides(trainer, (run_dir / "best.pt").resolve())
    return runner.load_session(source, overrides + weights, extra) if weights else session


def _curves_note(folder: Path, done: bool = False) -> None:
    """Where the live curves are (as training starts, or the curves once it is done), or how
    to get them."""
    import importlib.util
    if importlib.util.find_spec("tensorboard") is None:
        if not done:
            note("no live curves: pip install 'ata[tensorboard]' to have TensorBoard event "
                 "files written beside log.csv")
    elif done:
        console.print(f"curves: tensorboard --logdir {escape(str(folder))} (or ata report "
                      f"{escape(str(folder))})", highlight=False)
    else:
        note(f"live curves: tensorboard --logdir {folder}")


def _train_seeds(folder: Path, seeds: list[int], executor: str, workers: int | None,
                 address: Optional[str], quiet: bool) -> None:
    """Every seed's run of a folder of seeds, side by side on the executor; each resumes from
    its own checkpoint."""
    from ata.runtime.executors import make_executor
    from ata.training import seeds as sd

    units = [{"seed": s, "dir": str(folder / sd.seed_dir_name(s))} for s in seeds]
    if not quiet:
        _curves_note(folder)
        note(f"{len(units)} seeds on the {executor} executor, each in a folder of its own")
    from ata.experiment.execute import Interrupted
    try:
        with make_executor(executor, workers or None, address) as ex:
            for _, report in ex.run(sd.train_seed, units):
                console.print(f"seed {report['seed']}: best held-out score "
                              f"{report['best_eval']:.1f} in {report['wall_s']:.0f} s of "
                              "training time", highlight=False)
    except KeyboardInterrupt:
        raise Interrupted(f"interrupted: each seed keeps its last checkpoint; run ata train "
                          f"--resume {folder} to go on from them") from None
    _curves_note(folder, done=True)
    console.print(f"seeds folder: {escape(str(folder))}; curves across seeds: ata report "
                  f"{escape(str(folder))}", highlight=False)
    console.print(f"evaluate every seed against greedy: ata eval {escape(str(folder))} -o "
                  f"{escape(str(folder / 'eval'))}, then ata report {escape(str(folder))}",
                  highlight=False)
