"""`ata train`."""

from __future__ import annotations

import importlib.util
from pathlib import Path
from typing import List, Optional

import typer

import ata.cli.terminal as terminal
from ata.cli.common import AddressOption, SetOption, _split, app, user_errors
from ata.cli.terminal import console, escape, note


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
    from ata.experiment.training import train as train_mission   # on use: start-up time

    def on_start(folder: Path, values: list[int] | None) -> None:
        if not quiet:
            _curves_note(folder)
            if values:
                note(f"{len(values)} seeds on the {executor} executor, each in a folder of "
                     "its own")

    def on_seed(report: dict) -> None:
        console.print(f"seed {report['seed']}: best held-out score {report['best_eval']:.1f} "
                      f"in {report['wall_s']:.0f} s of training time", highlight=False)

    done = train_mission(mission, list(set_ or []), _split(plugins) if plugins is not None
                         else None, preset, seeds, out, resume, executor=executor,
                         workers=workers, address=address,
                         bar=lambda title, trainer: terminal.training_bar(title, trainer, quiet),
                         notify=note, on_start=on_start, on_seed=on_seed)
    folder = done.folder
    if done.report is None:
        _curves_note(folder, done=True)
        console.print(f"seeds folder: {escape(str(folder))}; curves across seeds: ata report "
                      f"{escape(str(folder))}", highlight=False)
        console.print(f"evaluate every seed against greedy: ata eval {escape(str(folder))} -o "
                      f"{escape(str(folder / 'eval'))}, then ata report {escape(str(folder))}",
                      highlight=False)
        return
    report = done.report
    best = report.get("best_eval", float("nan"))
    console.print(f"trained in {report['wall_s']:.0f} s of training time; best held-out "
                  f"score {best:.1f}")
    for key, value in (report.get("aux") or {}).items():
        console.print(f"  {key}: {value:.5f}")
    console.print(f"run folder: {escape(str(folder))} (checkpoint.pt, best.pt, log.csv)",
                  highlight=False)
    _curves_note(folder, done=True)
    console.print(f"evaluate the trained weights: ata run {escape(str(folder))}",
                  highlight=False)


def _curves_note(folder: Path, done: bool = False) -> None:
    """Where the live curves are (as training starts, or the curves once it is done), or how
    to get them."""
    if importlib.util.find_spec("tensorboard") is None:
        if not done:
            note("no live curves: pip install 'ata[tensorboard]' to have TensorBoard event "
                 "files written beside log.csv")
    elif done:
        console.print(f"curves: tensorboard --logdir {escape(str(folder))} (or ata report "
                      f"{escape(str(folder))})", highlight=False)
    else:
        note(f"live curves: tensorboard --logdir {folder}")
