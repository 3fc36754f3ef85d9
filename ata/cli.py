"""The command line: `ata run`, `eval`, `report`, `compare`, `train`, `check`, `plugins`, `show`.
Thin: each command parses, calls the library (`ata.experiment`), renders."""

from __future__ import annotations

import functools
import inspect
import sys
from pathlib import Path
from typing import Callable, List, Optional

import typer
import typer.core
from rich.padding import Padding
from rich.table import Table
from rich.text import Text

from ata import __version__
from ata.experiment import terminal
from ata.experiment.terminal import console, err_console, escape, note

class _ReflowedHelp(typer.core.TyperGroup):
    """Commands whose help is their docstring, wrapped to the terminal: typer's rich mode keeps
    every line break of a docstring (wrapped at 100 columns in the source), which cut the help
    mid-sentence at other widths; a paragraph's lines are joined here, once, at start-up."""

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        for command in self.commands.values():
            if command.help:
                command.help = "\n\n".join(" ".join(paragraph.split()) for paragraph in
                                            inspect.cleandoc(command.help).split("\n\n"))


app = typer.Typer(add_completion=False, no_args_is_help=True, cls=_ReflowedHelp,
                  help="ATA: adaptive task allocation in multi-human multi-robot teams.")
terminal.help_without_type_tags()

SetOption = typer.Option(None, "--set", "-s", metavar="TABLE.KEY=VALUE",
                         help="Override a mission key, e.g. --set mission.seed=3 (repeatable).")
PluginsOption = typer.Option(None, "--plugins", metavar="NAME[,NAME]",
                             help="Optional plugins to load, comma-separated (a component "
                                  "named in the mission loads its plugin without it).")
AddressOption = typer.Option(None, "--address", metavar="ADDRESS",
                             help="Ray cluster address (default: $RAY_ADDRESS, else a local Ray).")
ForceOption = typer.Option(False, "--force", help="Start over in an --out folder that holds the "
                                                  "results of another plan.")
QuietOption = typer.Option(False, "--quiet", "-q", help="No progress bar.")
ResamplesOption = typer.Option(2000, "--resamples", min=10, max=1_000_000, metavar="N",
                               help="Bootstrap resamples (at most 1,000,000: time grows).")
MarkdownOption = typer.Option(False, "--markdown", help="Print the tables as Markdown.")
IsolateOption = typer.Option(False, "--isolate",
                             help="Run the decision components (untrusted methods) in a "
                                  "sandboxed process apart from the world (bubblewrap; pip "
                                  "install 'ata[sandbox]'); see docs/evaluation.md.")
TimeoutOption = typer.Option(60.0, "--decision-timeout", min=0.001, metavar="SECONDS",
                             help="With --isolate: the time limit of one decision call of a "
                                  "batch (default 60).")


def user_errors(func: Callable) -> Callable:
    """Turn bad input into one clear message and exit status 2, without a traceback; an
    interrupted run into what it saved and exit status 130."""

    @functools.wraps(func)
    def wrapper(*args, **kwargs):
        import pluggy

        from ata.core.errors import ContractError, MissionError
        from ata.experiment.execute import Interrupted
        try:
            return func(*args, **kwargs)
        except (ContractError, MissionError, pluggy.PluginValidationError) as exc:
            lead = {ContractError: "a component broke the kernel's contract: ",
                    pluggy.PluginValidationError: "a plugin failed validation: "}.get(type(exc), "")
            # escape: the message names tables as [mission], which rich would take for markup
            err_console.print(f"[bold red]error:[/] {lead}{escape(str(exc))}", highlight=False,
                              soft_wrap=True)
            raise typer.Exit(2) from None
        except Interrupted as exc:
            note(str(exc))
            raise typer.Exit(130) from None

    return wrapper


def _split(plugins: Optional[str]) -> list[str]:
    return [p.strip() for p in (plugins or "").split(",") if p.strip()]


def _split_or_none(text: Optional[str]) -> Optional[list[str]]:
    return _split(text) or None


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
            None, metavar="MISSION", help="Mission file (TOML) or builtin:NAME. Default: the "
                                          "built-in mission, setting (a), medium uncertainty."),
        set_: Optional[List[str]] = SetOption,
        plugins: Optional[str] = PluginsOption,
        out: Optional[Path] = typer.Option(None, "--out", "-o", metavar="DIR",
                                           help="Run folder (default: runs/NAME-TIME)."),
        workers: Optional[int] = typer.Option(None, "--workers", "-w", min=1, metavar="N",
                                              help="Worker processes (default: the mission's)."),
        executor: Optional[str] = typer.Option(None, "--executor", "-e", metavar="NAME",
                                               help="serial, process or ray (default: serial "
                                                    "for one worker, else process)."),
        address: Optional[str] = AddressOption,
        chunk_size: Optional[int] = typer.Option(
            None, "--chunk-size", min=1, metavar="N",
            help="Scenarios per batch at most (default 100; mission.batch_size caps it too): "
                 "each batch is saved as it ends, bigger ones step faster."),
        cache: Optional[Path] = typer.Option(None, "--cache", metavar="DIR",
                                             help="Cache folder for results that depend on the "
                                                  "scenario alone (MILP initial allocations; "
                                                  "default: none)."),
        force: bool = ForceOption,
        quiet: bool = QuietOption,
        isolate: bool = IsolateOption,
        decision_timeout: float = TimeoutOption) -> None:
    """Run a mission and print its summary; write results beside the resolved mission.

    The run is a plan of one job on the chunked runner of `ata eval`. Each finished batch is
    saved in the run folder as it ends: rerun the same command with the same --out to go on
    after an interruption (only what is missing runs)."""
    from ata.experiment import execute, runner
    from ata.experiment.isolate import require_sandbox

    iso = require_sandbox(decision_timeout) if isolate else None
    session = runner.load_session(mission, set_ or [], _split(plugins))
    m = session.mission
    workers = workers or m.settings.workers
    # the components are built (checkpoints read) before any folder is made or scenario runs
    runner.build_once(m, session.registry, iso)
    plan = runner.mission_plan(session, workers, chunk_size or runner.RUN_CHUNK)
    out_dir, result = execute.run_plan(
        plan, lambda done: (done.out_dir, runner.write_done(session, done)), out,
        executor=executor or ("serial" if workers <= 1 else "process"), workers=workers,
        address=address, cache=cache, force=force, notify=note,
        progress=terminal.progress_bar(quiet), isolate=iso)
    terminal.key_values(f"{m.display_name()}: {m.settings.name}",
                        runner.summary_rows(session, result))
    terminal.warn(result.warnings)
    console.print(f"results: {escape(str(out_dir))}", highlight=False)


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
          address: Optional[str] = AddressOption,
          chunk_size: Optional[int] = typer.Option(
              None, "--chunk-size", min=1, metavar="N",
              help="Scenarios per work unit (default 250): each unit is saved as it ends, "
                   "bigger ones run faster."),
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
          force: bool = ForceOption,
          quiet: bool = QuietOption,
          isolate: bool = IsolateOption,
          decision_timeout: float = TimeoutOption) -> None:
    """Evaluate methods on held-out scenarios across team settings and uncertainty levels.

    Each finished work unit is saved in the output folder as it ends: rerun the same command
    with the same --out to go on after an interruption (only what is missing runs)."""
    from ata.core.errors import MissionError
    from ata.experiment import evaluate as ev
    from ata.experiment import execute
    from ata.experiment import report as rep
    from ata.experiment.isolate import require_sandbox
    from ata.experiment.results import read_results
    from ata.runtime.executors import EXECUTORS

    iso = require_sandbox(decision_timeout) if isolate else None
    if executor not in EXECUTORS:
        raise MissionError("--executor", None, f"unknown executor {executor!r}; choose one of "
                           + ", ".join(EXECUTORS))
    chunk_size = chunk_size or ev.DEFAULT_CHUNK
    # every job is built and validated before any scenario runs or anything is written
    suites, jobs = ev.plan(list(paths), scenarios=scenarios, seed=seed,
                           methods=_split_or_none(methods), settings=_split_or_none(settings),
                           levels=_split_or_none(levels), isolate=iso)
    cache_dir = None if no_cache else (cache or ev.default_cache_dir())
    plan = ev.eval_plan(suites, jobs, chunk_size, describe={
        "paths": list(paths), "jobs": len(jobs), "chunk_size": chunk_size})
    arguments = {"paths": list(paths), "chunk_size": chunk_size, "scenarios": scenarios,
                 "seed": seed, "methods": methods, "settings": settings, "levels": levels,
                 "cache": str(cache_dir) if cache_dir else None,
                 "first_scenario": ev.EVAL_FIRST_SCENARIO,
                 "isolate": iso.key() if iso else None}
    out_dir, result = execute.run_plan(
        plan, lambda done: (done.out_dir, ev.write_done(suites, jobs, chunk_size, arguments,
                                                        done)),
        out, executor=executor, workers=workers, address=address, cache=cache_dir, force=force,
        notify=note, progress=terminal.progress_bar(quiet), isolate=iso)
    terminal.report_tables(rep.summarize(read_results(out_dir)))
    terminal.warn(result.warnings)
    console.print(f"{len(result.rows)} rows in {result.wall_s:.1f} s; results: "
                  f"{escape(str(out_dir))} (ata report {escape(str(out_dir))} for report.md and "
                  "figures)", highlight=False)


@app.command()
@user_errors
def report(run_dir: List[Path] = typer.Argument(
               ..., metavar="DIR...",
               help="`ata eval` or `ata run` folders (several are read as one, a cell of a "
                    "later one replacing the same cell of an earlier one; outputs go to the "
                    "first), or one `ata train` run folder (its learning curves)."),
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
           markdown: bool = typer.Option(
               False, "--markdown", help="Print the two tables of docs/RESULTS.md as Markdown "
                                         "instead: every method's score, and the paired "
                                         "differences of --pair (or of the suite's pairs)."),
           pair: Optional[List[str]] = typer.Option(
               None, "--pair", metavar="A,B", help="A paired difference A - B for --markdown "
                                                   "(repeatable)."),
           resamples: int = ResamplesOption) -> None:
    """Tables (with bootstrap confidence intervals) and figures of an evaluation, or the
    learning curves of a training run."""
    from ata.core.errors import MissionError
    from ata.experiment import curves
    from ata.experiment import report as rep
    from ata.experiment.results import read_results

    if any(curves.is_training_folder(d) for d in run_dir):
        if len(run_dir) > 1:
            raise MissionError("", None, "a training run folder is reported alone: "
                               "ata report RUN_DIR")
        log, written = curves.write_curves(run_dir[0], out, not no_figures)
        terminal.table(f"training log {log.path}", *curves.curves_rows(log))
    elif markdown:
        pairs = [tuple(_split(p)) for p in pair or []]
        if any(len(p) != 2 for p in pairs):
            raise MissionError("--pair", None, "names two methods: --pair A,B")
        print(rep.results_markdown(read_results(run_dir), pairs or None, resamples), end="")
        return
    else:
        result, written = rep.write_report(run_dir, reference, not no_figures, resamples,
                                           paired_reference, out)
        if result.results.replaced:
            note("cells taken from a later folder: " + rep.replaced_text(result.results))
        terminal.report_tables(result)
    console.print("wrote " + ", ".join(escape(str(p)) for p in written), highlight=False)


@app.command()
@user_errors
def compare(folders: List[Path] = typer.Argument(
                ..., metavar="A [B]",
                help="One `ata eval` folder (each method against --base), or two folders of "
                     "`ata eval` or `ata run` (A - B, method by method)."),
            column: Optional[List[str]] = typer.Option(
                None, "--column", "-c", metavar="COL",
                help="A results.csv column: score (the default), expected_score, "
                     "reallocations, ... (repeatable)."),
            base: Optional[str] = typer.Option(
                None, "--base", metavar="METHOD",
                help="The method subtracted: of A (default greedy, else the first), or of B."),
            methods: Optional[str] = typer.Option(None, "--methods", metavar="NAME[,NAME]",
                                                  help="Only these methods of A."),
            power: bool = typer.Option(
                False, "--power", help="The scenarios a paired 95% CI needs to clear 0, at "
                                       "the difference that expected_score estimates."),
            means: bool = typer.Option(False, "--means",
                                       help="The columns' means per method and cell instead."),
            markdown: bool = MarkdownOption,
            resamples: int = ResamplesOption) -> None:
    """Paired differences on the same scenarios, with bootstrap 95% CIs, on any results column;
    the scenarios a CI needs to clear 0 (--power); or column means (--means)."""
    from ata.core.errors import MissionError
    from ata.experiment import compare as cmp
    from ata.experiment.results import read_results

    if len(folders) > 2:
        raise MissionError("", None, "compares one folder (methods against --base) or two "
                           "(A - B): ata compare A [B]")
    if power and means:
        raise MissionError("--means", None, "give --power or --means, not both")
    results = [read_results(f) for f in folders]
    columns = list(dict.fromkeys(column or ["score"]))
    if means:
        tables = cmp.mean_tables([(str(f), r) for f, r in zip(folders, results)], columns,
                                 _split_or_none(methods))
    else:
        tables = cmp.compare(results[0], results[1] if len(results) > 1 else None, columns,
                             base=base, methods=_split_or_none(methods), power=power,
                             resamples=resamples)
    if markdown:
        print(cmp.markdown(tables), end="")
    for table in [] if markdown else tables:
        terminal.table(table.title, table.header, table.rows)


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
    registry = collect_components(everything, declared=True)
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
    console.print(terminal.add_broken_plugins(table, registry.broken))
    missing = [n for n, mod in OPTIONAL_PLUGINS.items() if mod not in loaded]
    if missing:
        console.print(f"Optional plugins (the learned methods) load when a mission names one "
                      f"of their components, or with --plugins NAME; not loaded now: "
                      f"{', '.join(missing)}.",
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
             help="Folder for the pictures (default: RUN_DIR/show-N, or runs/show-NAME-N)."),
         animate: bool = typer.Option(
             False, "--animate", help="Also write the map through time as an animated GIF "
                                      "(show_map.gif, one frame per epoch).")) -> None:
    """Replay one scenario with a recorded trace and draw its map, a timeline per member and
    the humans' states (show_map, show_timeline, show_humans; PNG and SVG), and with --animate
    the map through time (show_map.gif); see docs/show.md."""
    from ata.viz.show import show as show_scenario

    terminal.show_summary(show_scenario(target, scenario, list(set_ or []), out, animate,
                                        progress=terminal.progress_bar(False)))

if __name__ == "__main__":  # pragma: no cover
    sys.exit(app())
