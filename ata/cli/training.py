"""`ata train`."""

from __future__ import annotations

from pathlib import Path
from typing import List, Optional

import typer

from ata.cli.common import (SetOption, _split, app, user_errors)
from ata.experiment import terminal
from ata.experiment.terminal import console, err_console, note


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
          out: Optional[Path] = typer.Option(None, "--out", "-o", metavar="DIR",
                                             help="Run folder."),
          resume: Optional[Path] = typer.Option(None, "--resume", metavar="DIR",
                                                help="Resume the run in this folder."),
          quiet: bool = typer.Option(False, "--quiet", "-q", help="No progress bar.")) -> None:
    """Train the learned components of a mission with the trainer it names (ata_hrl: ATA-HRL
    and its ablations; tr_pomdp: the TR-POMDP agents, also after the attention ITA for AtRL-TR)."""
    from ata.experiment import runner
    from ata.experiment.execute import Interrupted
    from ata.experiment.folders import prepare_out_dir
    from ata.training import TrainRun

    if resume is not None:
        if mission is not None or set_ or plugins:
            err_console.print("[yellow]note:[/] --resume uses the run folder's resolved "
                              "mission; the MISSION, --plugins and --set given are ignored")
        source = resume / "mission.resolved.toml"
        session = runner.load_session(str(source))
        run_dir = resume
    else:
        names = _split(plugins) if plugins is not None else None
        source = mission or str(runner.training_mission_for(names or ["ctr", "aux"]))
        # a mission file brings its own plugins; --plugins, when given, adds to them
        session = runner.load_session(source, list(set_ or []), names if mission else None)
        run_dir = (prepare_out_dir(out, kind="train") if out
                   else runner.default_out_dir(session.mission, prefix="train-"))
    trainer = runner.build_trainer(session)
    m = session.mission
    try:
        with terminal.training_bar(f"train {m.settings.name}", trainer, quiet) as on_row:
            run = TrainRun(run_dir, m.to_toml(), trainer.log_fields, resume=resume is not None,
                           on_row=on_row)
            on_row(None)
            report = trainer.run(run, resume=resume is not None)
    except KeyboardInterrupt:
        raise Interrupted(runner.training_saved(run_dir)) from None
    best = report.get("best_eval", float("nan"))
    console.print(f"trained in {report['wall_s']:.0f} s of training time; best held-out "
                  f"score {best:.1f}")
    for key, value in (report.get("aux") or {}).items():
        console.print(f"  {key}: {value:.5f}")
    console.print(f"run folder: {run_dir} (checkpoint.pt, best.pt, log.csv)")
