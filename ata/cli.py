"""The command line: `ata run`, `ata check`, `ata plugins`. Thin: parse, build a session, call
the library, render."""

from __future__ import annotations

import functools
import sys
from pathlib import Path
from typing import Callable, List, Optional

import typer
from rich.console import Console
from rich.markup import escape
from rich.padding import Padding
from rich.progress import (BarColumn, Progress, ProgressColumn, TaskProgressColumn,
                           TextColumn, TimeElapsedColumn, TimeRemainingColumn)
from rich.table import Column, Table
from rich.text import Text

from ata import __version__

app = typer.Typer(add_completion=False, no_args_is_help=True,
                  help="ATA: adaptive task allocation in multi-human multi-robot teams.")


def _help_without_type_tags() -> None:
    """Recent typer prints a Python type after every parameter in help pages (``<bool>`` after
    a flag, ``<list[str]>`` after an argument). Our parameters name their values in their
    metavars (FILE, DIR, N) and flags take none: print no type tag but an option's metavar."""
    from typer import core

    for cls in (getattr(core, "TyperArgument", None), getattr(core, "TyperOption", None)):
        if cls is not None and hasattr(cls, "display_type_rich"):
            cls.display_type_rich = lambda self, ctx: (
                None if getattr(self, "is_flag", False) or isinstance(self, core.TyperArgument)
                else self.metavar)


_help_without_type_tags()


class _LazyConsole:
    """A rich console made at first use in each command, so that it sees the terminal (and
    COLUMNS) of the invocation, not of the import."""

    def __init__(self, **kwargs):
        self.kwargs = kwargs

    def __getattr__(self, name):
        return getattr(Console(**self.kwargs), name)


console = _LazyConsole()
err_console = _LazyConsole(stderr=True)

SetOption = typer.Option(None, "--set", "-s", metavar="TABLE.KEY=VALUE",
                         help="Override a mission key, e.g. --set mission.seed=3 (repeatable).")
PluginsOption = typer.Option(None, "--plugins", metavar="NAME[,NAME]",
                             help="Optional plugins to load, comma-separated.")


class SpeedColumn(ProgressColumn):
    """Scenarios simulated per second."""

    def render(self, task) -> Text:
        return Text(f"{task.speed or 0:,.1f} scenarios/s", style="cyan")


def user_errors(func: Callable) -> Callable:
    """Turn bad input into one clear message and exit status 2, without a traceback."""

    @functools.wraps(func)
    def wrapper(*args, **kwargs):
        import pluggy

        from ata.core.errors import ContractError, MissionError
        try:
            return func(*args, **kwargs)
        except (ContractError, MissionError, pluggy.PluginValidationError) as exc:
            lead = {ContractError: "a component broke the kernel's contract: ",
                    pluggy.PluginValidationError: "a plugin failed validation: "}.get(type(exc), "")
            # escape: the message names tables as [mission], which rich would take for markup
            err_console.print(f"[bold red]error:[/] {lead}{escape(str(exc))}", highlight=False,
                              soft_wrap=True)
            raise typer.Exit(2) from None

    return wrapper


def _say_resuming(log, out_dir: Path, what: str) -> None:
    """One line when an output folder's record already holds finished work."""
    if log.resumed == log.units:
        text = f"resuming {out_dir}: all {log.units} {what} were done before"
    elif log.resumed:
        text = (f"resuming {out_dir}: {log.resumed} of {log.units} {what} were done before; "
                f"running the other {log.units - log.resumed}")
    else:
        return
    err_console.print(escape(text), highlight=False, soft_wrap=True)


def _interrupted(log, out_dir: Path, what: str) -> typer.Exit:
    """Say what an interrupted run saved and how to go on; the exit to raise (130)."""
    err_console.print(escape(f"interrupted: {log.saved()} of {log.units} {what} are saved in "
                             f"{out_dir}; run the same command with --out {out_dir} to go on"),
                      highlight=False, soft_wrap=True)
    return typer.Exit(130)


def _split(plugins: Optional[str]) -> list[str]:
    return [p.strip() for p in (plugins or "").split(",") if p.strip()]


def _version_callback(value: bool) -> None:
    if value:
        console.print(f"ata {__version__}")
        raise typer.Exit()


@app.callback()
def main(version: bool = typer.Option(False, "--version", callback=_version_callback,
                                      is_eager=True, help="Show the version and exit.")) -> None:
    """ATA: adaptive task allocation in multi-human multi-robot teams."""


@app.command()
@user_errors
def run(mission: Optional[str] = typer.Argument(
            None, metavar="MISSION", help="Mission file (TOML). Default: the built-in "
                                          "mission, setting (a), medium uncertainty."),
        set_: Optional[List[str]] = SetOption,
        plugins: Optional[str] = PluginsOption,
        out: Optional[Path] = typer.Option(None, "--out", "-o", metavar="DIR",
                                           help="Run folder (default: runs/NAME-TIME)."),
        workers: Optional[int] = typer.Option(None, "--workers", "-w", min=1, metavar="N",
                                              help="Worker processes (default: the mission's)."),
        executor: Optional[str] = typer.Option(None, "--executor", "-e", metavar="NAME",
                                               help="serial, process or ray (default: serial "
                                                    "for one worker, else process)."),
        address: Optional[str] = typer.Option(None, "--address", metavar="ADDRESS",
                                              help="Ray cluster address (default: "
                                                   "$RAY_ADDRESS, else a local Ray)."),
        cache: Optional[Path] = typer.Option(None, "--cache", metavar="DIR",
                                             help="Cache folder for results that depend on the "
                                                  "scenario alone (MILP initial allocations; "
                                                  "default: none)."),
        force: bool = typer.Option(False, "--force",
                                   help="Start over in an --out folder that holds the results "
                                        "of another run."),
        quiet: bool = typer.Option(False, "--quiet", "-q", help="No progress bar.")) -> None:
    """Run a mission and print its summary; write results beside the resolved mission.

    The run is a plan of one job on the chunked runner of `ata eval`. Each finished batch is
    saved in the run folder as it ends: rerun the same command with the same --out to go on
    after an interruption (only what is missing runs)."""
    from ata.experiment import runner
    from ata.experiment.executors import make_executor
    from ata.experiment.runlog import RunLog
    from ata.experiment.units import chunks_of

    session = runner.load_session(mission, set_ or [], _split(plugins))
    m = session.mission
    workers = workers or m.settings.workers
    # the executor is checked, the components are built (checkpoints read) and the output
    # folder is made and checked before any scenario runs
    pool = make_executor(executor or ("serial" if workers <= 1 else "process"), workers,
                         address)
    runner.build_once(m, session.registry)
    out_dir = runner.prepare_out_dir(out) if out else runner.default_out_dir(m)
    chunks = chunks_of(m, workers)
    log = RunLog(out_dir, runner.plan_key(session, chunks), len(chunks), force=force,
                 describe={"mission": m.settings.name, "scenarios": m.settings.scenarios})
    _say_resuming(log, out_dir, "batches")
    done = sum(int(p["scenario"].size) for p in log.done.values())
    columns = [TextColumn("[bold]{task.description}"), BarColumn(), TaskProgressColumn(),
               SpeedColumn(), TimeElapsedColumn(), TimeRemainingColumn()]
    try:
        with pool, Progress(*columns, console=Console(stderr=True), disable=quiet) as progress:
            task = progress.add_task(f"{m.settings.name}: {m.settings.scenarios} scenarios",
                                     total=m.settings.scenarios, completed=done)
            result = runner.run_mission(session, progress=lambda n: progress.advance(task, n),
                                        log=log, chunks=chunks, executor=pool, cache=cache)
            progress.update(task, completed=m.settings.scenarios)   # no float shortfall
    except KeyboardInterrupt:
        raise _interrupted(log, out_dir, "batches") from None
    finally:
        log.close()
    runner.write_run(out_dir, session, result)
    render_summary(session, result)
    console.print(f"results: {out_dir}")


def render_summary(session, result) -> None:
    """The summary of a run: a key per line, readable at 80 columns."""
    from rich import box

    from ata.experiment.runner import summarize

    m, s = session.mission, summarize(result)
    table = Table(title=escape(f"{m.display_name()}: {m.settings.name}"), box=box.SIMPLE,
                  show_header=False, title_justify="left")
    table.add_column("what", style="bold", no_wrap=True)
    table.add_column("value", overflow="fold")
    table.add_row("method", escape(m.method_label()))
    table.add_row("team", f"setting {m.settings.setting}: {m.sizes.humans} humans, "
                          f"{m.sizes.robots} robots, {m.sizes.tasks} POIs")
    table.add_row("uncertainty", f"{m.settings.uncertainty} (fatigue variance "
                                 f"{m.fatigue_variance}, event probability "
                                 f"{m.event_probability})")
    first = m.settings.first_scenario
    table.add_row("scenarios", f"{s['scenarios']} (ids {first}..{first + s['scenarios'] - 1}, "
                               f"root seed {m.settings.seed})")
    table.add_row("team performance", f"{s['score_mean']:.1f} ± {s['score_ci95']:.1f} "
                                      "(mean ± 95% CI half-width)")
    table.add_row("fraction of U", f"{s['fraction_of_u']:.3f} (U: the capacity-free bound)")
    table.add_row("POIs classified",
                  f"{100 * s.get('classified_share_mean', float('nan')):.1f}%")
    table.add_row("reallocations", f"{s['reallocations_mean']:.2f} per scenario")
    table.add_row("wall time", f"{s['wall_s']:.1f} s")
    console.print(table)
    for warning in result.warnings:
        err_console.print(f"[yellow]warning:[/] {escape(warning)}", highlight=False)


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
        run_dir = (runner.prepare_out_dir(out) if out
                   else runner.default_out_dir(session.mission, prefix="train-"))
    trainer = runner.build_trainer(session)
    m = session.mission
    # the bar and the times keep their width; the status gives way (cut short) at 80 columns
    title = f"train {m.settings.name}"
    columns = [TextColumn("[bold]{task.description}",
                          table_column=Column(no_wrap=True, min_width=len(title))),
               BarColumn(bar_width=16, table_column=Column(no_wrap=True, min_width=16)),
               TaskProgressColumn(table_column=Column(no_wrap=True, min_width=4)),
               TimeElapsedColumn(table_column=Column(no_wrap=True, min_width=7)),
               TimeRemainingColumn(table_column=Column(no_wrap=True, min_width=7)),
               TextColumn("{task.fields[status]}",
                          table_column=Column(no_wrap=True, overflow="ellipsis", ratio=1))]
    with Progress(*columns, console=Console(stderr=True), disable=quiet) as progress:
        task = progress.add_task(title, total=trainer.total_steps(),
                                 status="")

        def on_row(row: dict) -> None:
            parts = [f"{row['phase']} {row['step']}"]
            for key, label in (("episodes_per_s", "ep/s"), ("mean_score", "score"),
                               ("epsilon", "eps"), ("eval_score", "held-out"),
                               ("aux_fatigue_mse", "fatigue mse")):
                if row.get(key):
                    parts.append(f"{label} {row[key]}")
            progress.update(task, completed=trainer.done_steps(), status=" | ".join(parts))

        run = TrainRun(run_dir, m.to_toml(), trainer.log_fields, resume=resume is not None,
                       on_row=on_row)
        progress.update(task, completed=trainer.done_steps())
        report = trainer.run(run, resume=resume is not None)
    best = report.get("best_eval", float("nan"))
    console.print(f"trained in {report['wall_s']:.0f} s of training time; best held-out "
                  f"score {best:.1f}")
    for key, value in (report.get("aux") or {}).items():
        console.print(f"  {key}: {value:.5f}")
    console.print(f"run folder: {run_dir} (checkpoint.pt, best.pt, log.csv)")


@app.command()
@user_errors
def check(mission: str = typer.Argument(..., metavar="MISSION", help="Mission file (TOML)."),
          set_: Optional[List[str]] = SetOption,
          plugins: Optional[str] = PluginsOption,
          show: bool = typer.Option(False, "--show", help="Print the resolved mission.")) -> None:
    """Validate a mission file without running it."""
    from ata.experiment import runner

    session = runner.load_session(mission, set_ or [], _split(plugins))
    m = session.mission
    runner.build_once(m, session.registry)   # a component that cannot fill its slot fails
    console.print(f"[green]ok[/]: {escape(mission)}: setting {m.settings.setting} "
                  f"({m.sizes.humans} humans, {m.sizes.robots} robots, {m.sizes.tasks} POIs), "
                  f"{m.settings.scenarios} scenarios, {m.settings.uncertainty} uncertainty "
                  f"(fatigue variance {m.fatigue_variance}, event probability "
                  f"{m.event_probability})", highlight=False)
    if show:
        console.print(m.to_toml(), highlight=False, markup=False)


@app.command()
@user_errors
def plugins(verbose: bool = typer.Option(False, "--verbose", "-v",
                                         help="Also list each component's hooks and settings "
                                              "(type, default, allowed values)."),
            optional: Optional[str] = PluginsOption) -> None:
    """List every component by name, the plugin it comes from and its version. Optional
    plugins (the learned methods) are listed too, marked with the --plugins name that loads
    them."""
    from rich import box

    from ata.core.registry import OPTIONAL_PLUGINS, collect_components, get_plugin_manager
    from ata.core.settings import describe

    pm = get_plugin_manager(optional=_split(optional))
    loaded = {pm.get_name(p) for p in pm.get_plugins()}
    # every optional plugin, loaded or not, so that a user can discover them here
    everything = get_plugin_manager(optional=list(OPTIONAL_PLUGINS))
    registry = collect_components(everything)
    optional_of = {module: name for name, module in OPTIONAL_PLUGINS.items()}
    table = Table(title="ata plugins", box=box.SIMPLE_HEAD, title_justify="left")
    table.add_column("component", no_wrap=True)
    table.add_column("kind", no_wrap=True)
    table.add_column("plugin (in ata.plugins)", overflow="fold")
    table.add_column("version", no_wrap=True)
    for info in sorted(registry.components.values(), key=lambda c: (c.kind, c.name)):
        plugin = info.plugin.removeprefix("ata.plugins.")
        if info.plugin in optional_of:
            plugin = f"{plugin} (--plugins {optional_of[info.plugin]})"
        table.add_row(info.name, info.kind, plugin, info.dist)
    console.print(table)
    missing = [n for n, mod in OPTIONAL_PLUGINS.items() if mod not in loaded]
    if missing:
        console.print(f"Optional plugins (the learned methods) load with --plugins NAME or a "
                      f"mission's [mission] plugins; not loaded now: {', '.join(missing)}.",
                      highlight=False, markup=False)
    if verbose:
        # one block per component, a key per line: readable at any terminal width
        for info in sorted(registry.components.values(), key=lambda c: (c.kind, c.name)):
            cls = getattr(info.factory, "Settings", None)
            hooks = ", ".join(h for h in sorted(dir(info.factory))
                              if h.startswith("ata_") and h != "ata_register_components")
            console.print()
            console.print(Text(f"[{info.name}]", style="bold") + Text(
                f" {info.kind}, from {info.plugin}; hooks: {hooks or 'none'}"))
            rows = describe(cls) if cls else []
            if not rows:
                console.print("  no settings", highlight=False)
            for key, tp, default, allowed, text in rows:
                kind = f"{tp}, {allowed}" if allowed else tp
                console.print(Text(f"  {key}", style="cyan") + Text(f" = {default!r}  ({kind})"))
                console.print(Padding(Text(text), (0, 0, 0, 6)))


def _split_or_none(text: Optional[str]) -> Optional[list[str]]:
    return _split(text) or None


@app.command("eval")
@user_errors
def eval_(paths: List[str] = typer.Argument(
              ..., metavar="FILE",
              help="Suite files (a suite table and method tables) or mission files; see "
                   "docs/evaluation.md."),
          out: Optional[Path] = typer.Option(None, "--out", "-o", metavar="DIR",
                                             help="Output folder (default: runs/eval-NAME-TIME)."),
          executor: str = typer.Option("process", "--executor", "-e", metavar="NAME",
                                       help="serial, process (local worker processes) or ray."),
          workers: Optional[int] = typer.Option(None, "--workers", "-w", min=1, metavar="N",
                                                help="Worker processes (process: default one "
                                                     "per core) or local Ray CPUs."),
          address: Optional[str] = typer.Option(None, "--address", metavar="ADDRESS",
                                                help="Ray cluster address (default: "
                                                     "$RAY_ADDRESS, else a local Ray)."),
          chunk_size: int = typer.Option(50, "--chunk-size", min=1, metavar="N",
                                         help="Scenarios per work unit."),
          scenarios: Optional[int] = typer.Option(None, "--scenarios", "-n", min=1, metavar="N",
                                                  help="Scenarios per (method, setting, level) "
                                                       "(default: the suite's, else 500)."),
          seed: Optional[int] = typer.Option(None, "--seed", min=0, metavar="N",
                                             help="Root seed (default: the suite's, else 0)."),
          methods: Optional[str] = typer.Option(None, "--methods", metavar="NAME[,NAME]",
                                                help="Run only these methods."),
          settings: Optional[str] = typer.Option(None, "--settings", metavar="S[,S]",
                                                 help="Run only these team settings."),
          levels: Optional[str] = typer.Option(None, "--levels", metavar="LEVEL[,LEVEL]",
                                               help="Run only these uncertainty levels."),
          cache: Optional[Path] = typer.Option(None, "--cache", metavar="DIR",
                                               help="Cache folder for results that depend on "
                                                    "the scenario alone (MILP initial "
                                                    "allocations); default $ATA_CACHE, else "
                                                    "~/.cache/ata."),
          no_cache: bool = typer.Option(False, "--no-cache", help="Use no cache."),
          force: bool = typer.Option(False, "--force",
                                     help="Start over in an --out folder that holds the "
                                          "results of another plan."),
          quiet: bool = typer.Option(False, "--quiet", "-q", help="No progress bar.")) -> None:
    """Evaluate methods on held-out scenarios across team settings and uncertainty levels.

    Each finished work unit is saved in the output folder as it ends: rerun the same command
    with the same --out to go on after an interruption (only what is missing runs)."""
    import numpy as np

    from ata.experiment import evaluate as ev
    from ata.experiment import report as rep
    from ata.experiment import runner
    from ata.core.errors import MissionError
    from ata.experiment.executors import EXECUTORS, make_executor
    from ata.experiment.runlog import RunLog

    if executor not in EXECUTORS:
        raise MissionError("--executor", None, f"unknown executor {executor!r}; choose one of "
                           + ", ".join(EXECUTORS))
    # every job is built and validated before any scenario runs or anything is written
    suites, jobs = ev.plan(list(paths), scenarios=scenarios, seed=seed,
                           methods=_split_or_none(methods), settings=_split_or_none(settings),
                           levels=_split_or_none(levels))
    cache_dir = None if no_cache else (cache or ev.default_cache_dir())
    out_dir = runner.prepare_out_dir(out) if out else ev.default_out_dir(suites)
    total = ev.total_scenarios(jobs)
    columns = [TextColumn("[bold]{task.description}"), BarColumn(), TaskProgressColumn(),
               TextColumn("{task.completed:,.0f}/{task.total:,.0f} scenarios"),
               TimeElapsedColumn(), TimeRemainingColumn()]
    log = RunLog(out_dir, ev.plan_key(jobs, chunk_size), ev.unit_count(jobs, chunk_size),
                 force=force, describe={"paths": list(paths), "jobs": len(jobs),
                                        "chunk_size": chunk_size})
    _say_resuming(log, out_dir, "work units")
    done_before = sum(int(np.asarray(p["scenario"]).size) for p in log.done.values())
    try:
        with make_executor(executor, workers, address) as pool:
            with Progress(*columns, console=Console(stderr=True), disable=quiet) as progress:
                task = progress.add_task(f"eval: {len(jobs)} (method, setting, level)",
                                         total=total, completed=done_before)
                result = ev.evaluate(jobs, pool, chunk_size=chunk_size, cache=cache_dir,
                                     progress=lambda n: progress.advance(task, n), log=log)
                progress.update(task, completed=total)   # no float shortfall
            described = pool.describe()
    except KeyboardInterrupt:
        raise _interrupted(log, out_dir, "work units") from None
    finally:
        log.close()
    arguments = {"paths": list(paths), "executor": described, "chunk_size": chunk_size,
                 "scenarios": scenarios, "seed": seed, "methods": methods,
                 "settings": settings, "levels": levels,
                 "cache": str(cache_dir) if cache_dir else None,
                 "first_scenario": ev.EVAL_FIRST_SCENARIO, "resumed_units": log.resumed}
    ev.write_eval(out_dir, suites, jobs, result, arguments)
    report = rep.summarize(rep.read_results(out_dir))
    _render_report(report)
    for warning in result.warnings:
        err_console.print(f"[yellow]warning:[/] {escape(warning)}", highlight=False)
    console.print(f"{len(result.rows)} rows in {result.wall_s:.1f} s; results: {out_dir} "
                  f"(ata report {out_dir} for report.md and figures)", highlight=False)


def _render_report(report) -> None:
    from ata.experiment.report import table_rows, title

    for setting, level in report.groups():
        header, rows = table_rows(report, setting, level, short=True)
        table = Table(title=escape(title(setting, level)))
        for i, name in enumerate(header):
            table.add_column(escape(name), justify="left" if i == 0 else "right",
                             no_wrap=i == 2)
        for row in rows:
            table.add_row(*[escape(x) for x in row])
        console.print(table)


@app.command()
@user_errors
def report(run_dir: List[Path] = typer.Argument(..., metavar="DIR...",
                                                help="`ata eval` output folders (several are "
                                                     "read together; outputs go to the "
                                                     "first), or one `ata train` run folder "
                                                     "(its learning curves)."),
           reference: Optional[str] = typer.Option(
               None, "--reference", "-r", metavar="NAME",
               help="The method the others are compared with in the tables (default: ATA-HRL "
                    "if present, else the first method)."),
           paired_reference: Optional[str] = typer.Option(
               None, "--paired-reference", metavar="NAME",
               help="The method subtracted in fig_paired, method - NAME (default: greedy if "
                    "present, else the first method)."),
           out: Optional[Path] = typer.Option(None, "--out", "-o", metavar="DIR",
                                              help="Write here (default: the first DIR)."),
           no_figures: bool = typer.Option(False, "--no-figures", help="Write no figures."),
           resamples: int = typer.Option(2000, "--resamples", min=10, metavar="N",
                                         help="Bootstrap resamples.")) -> None:
    """Tables (with bootstrap confidence intervals) and figures of an evaluation, or the
    learning curves of a training run."""
    from ata.experiment import report as rep
    from ata.core.errors import MissionError

    if any(rep.is_training_folder(d) for d in run_dir):
        if len(run_dir) > 1:
            raise MissionError("", None, "a training run folder is reported alone: "
                               "ata report RUN_DIR")
        log, written = rep.write_curves(run_dir[0], out, not no_figures)
        header, rows = rep.curves_rows(log)
        table = Table(title=escape(f"training log {log.path}"))
        for i, name in enumerate(header):
            table.add_column(escape(name), justify="left" if i == 0 else "right")
        for row in rows:
            table.add_row(*[escape(x) for x in row])
        console.print(table)
    else:
        result, written = rep.write_report(run_dir, reference, not no_figures, resamples,
                                           paired_reference, out)
        _render_report(result)
    console.print("wrote " + ", ".join(str(p) for p in written), highlight=False)


@app.command()
@user_errors
def show(target: Optional[str] = typer.Argument(
             None, metavar="RUN_DIR|MISSION",
             help="A run folder (read through its mission.resolved.toml) or a mission file. "
                  "Default: the built-in mission."),
         scenario: Optional[int] = typer.Option(
             None, "--scenario", "-n", metavar="N",
             help="The scenario id to replay (default: the mission's first)."),
         set_: Optional[List[str]] = SetOption,
         out: Optional[Path] = typer.Option(
             None, "--out", "-o", metavar="DIR",
             help="Folder for the pictures (default: RUN_DIR/show-N, or runs/show-NAME-N).")
         ) -> None:
    """Replay one scenario with a recorded trace and draw its map, a timeline per member and
    the humans' states (show_map, show_timeline, show_humans; PNG and SVG); see docs/show.md."""
    from ata.viz.show import show as show_scenario

    shown = show_scenario(target, scenario, list(set_ or []), out)
    ep = shown.episode
    changing = sum(1 for _, n in ep.reallocations if n)
    failures = int((ep.fail_time <= ep.horizon_s).sum())
    console.print(f"{escape(ep.mission)}: scenario {ep.scenario} (seed {ep.seed}): score "
                  f"{ep.score:.1f} of U {ep.upper_bound:.1f}; {len(ep.reallocations)} "
                  f"reallocations ({changing} changing POIs), {failures} robot failures",
                  highlight=False)
    if shown.run_score is not None:
        if shown.run_score == ep.score:
            console.print(f"the same score as the run: {escape(str(shown.results))}",
                          highlight=False)
        else:
            err_console.print(f"[yellow]warning:[/] the replay scored {ep.score!r}, the run "
                              f"{shown.run_score!r} ({escape(str(shown.results))}): not the "
                              "code or plugin versions that made the run", highlight=False)
    console.print("wrote " + ", ".join(escape(str(p)) for p in shown.written), highlight=False)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(app())
