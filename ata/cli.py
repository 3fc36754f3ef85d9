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
from rich.progress import (BarColumn, Progress, ProgressColumn, TaskProgressColumn,
                           TextColumn, TimeElapsedColumn, TimeRemainingColumn)
from rich.table import Table
from rich.text import Text

from ata import __version__

app = typer.Typer(add_completion=False, no_args_is_help=True,
                  help="ATA: adaptive task allocation in multi-human multi-robot teams.")


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
    """Scenario-epochs simulated per second."""

    def render(self, task) -> Text:
        return Text(f"{task.speed or 0:,.0f} scenario-epochs/s", style="cyan")


def user_errors(func: Callable) -> Callable:
    """Turn bad input into one clear message and exit status 2, without a traceback."""

    @functools.wraps(func)
    def wrapper(*args, **kwargs):
        import pluggy

        from ata.core.errors import MissionError
        try:
            return func(*args, **kwargs)
        except MissionError as exc:
            # escape: the message names tables as [mission], which rich would take for markup
            err_console.print(f"[bold red]error:[/] {escape(str(exc))}", highlight=False,
                              soft_wrap=True)
            raise typer.Exit(2) from None
        except pluggy.PluginValidationError as exc:
            err_console.print(f"[bold red]error:[/] a plugin failed validation: "
                              f"{escape(str(exc))}", highlight=False, soft_wrap=True)
            raise typer.Exit(2) from None

    return wrapper


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
            None, help="Mission file (TOML). Default: the built-in mission, setting (a), "
                       "medium uncertainty."),
        set_: Optional[List[str]] = SetOption,
        plugins: Optional[str] = PluginsOption,
        out: Optional[Path] = typer.Option(None, "--out", "-o",
                                           help="Run folder (default: runs/NAME-TIME)."),
        workers: Optional[int] = typer.Option(None, "--workers", "-w", min=1,
                                              help="Worker processes (default: the mission's)."),
        quiet: bool = typer.Option(False, "--quiet", "-q", help="No progress bar.")) -> None:
    """Run a mission and print its summary; write results beside the resolved mission."""
    from ata.core import runner

    session = runner.load_session(mission, set_ or [], _split(plugins))
    m = session.mission
    total = m.settings.scenarios * m.clock.n_epochs
    columns = [TextColumn("[bold]{task.description}"), BarColumn(), TaskProgressColumn(),
               SpeedColumn(), TimeElapsedColumn(), TimeRemainingColumn()]
    with Progress(*columns, console=Console(stderr=True), disable=quiet) as progress:
        task = progress.add_task(f"{m.settings.name}: {m.settings.scenarios} scenarios",
                                 total=total)
        result = runner.run_mission(session, progress=lambda n: progress.advance(task, n),
                                    workers=workers)
    out_dir = runner.write_run(out or runner.default_out_dir(m), session, result)
    render_summary(session, result)
    console.print(f"results: {out_dir}")


def render_summary(session, result) -> None:
    """The summary table of a run."""
    from ata.core.runner import summarize

    m, s = session.mission, summarize(result)
    slots = m.slots
    table = Table(title=f"{m.settings.name}: setting {m.settings.setting} "
                        f"({m.sizes.humans} humans, {m.sizes.robots} robots, {m.sizes.tasks} POIs), "
                        f"{m.settings.uncertainty} uncertainty, seed {m.settings.seed}")
    table.add_column("method")
    table.add_column("scenarios", justify="right")
    table.add_column("total team performance (95% CI)", justify="right")
    table.add_column("fraction of U", justify="right")
    table.add_column("POIs classified", justify="right")
    table.add_column("reallocations", justify="right")
    table.add_column("wall time", justify="right")
    method = f"{slots.initial} / {slots.condition} / {slots.reallocation}"
    table.add_row(method, str(s["scenarios"]),
                  f"{s['score_mean']:.1f} ± {s['score_ci95']:.1f}",
                  f"{s['fraction_of_u']:.3f}",
                  f"{100 * s.get('classified_share_mean', float('nan')):.1f}%",
                  f"{s['reallocations_mean']:.2f}", f"{s['wall_s']:.1f} s")
    console.print(table)
    for warning in result.warnings:
        err_console.print(f"[yellow]warning:[/] {escape(warning)}", highlight=False)


@app.command()
@user_errors
def train(mission: Optional[str] = typer.Argument(
              None, help="Training mission (TOML) naming a trainer in \\[components]. Default: "
                         "the built-in training mission of the --plugins given."),
          set_: Optional[List[str]] = SetOption,
          plugins: Optional[str] = typer.Option(
              None, "--plugins", metavar="NAME[,NAME]",
              help="Without a mission file, pick the built-in training mission of these "
                   "optional plugins: ctr,aux (the default) the full ATA-HRL; ctr w/o.AUX; ita "
                   "the ITA alone; trp TR-POMDP; ita,trp AtRL-TR. w/o.C: add --set "
                   "components.condition=always."),
          out: Optional[Path] = typer.Option(None, "--out", "-o", help="Run folder."),
          resume: Optional[Path] = typer.Option(None, "--resume",
                                                help="Resume the run in this folder."),
          quiet: bool = typer.Option(False, "--quiet", "-q", help="No progress bar.")) -> None:
    """Train the learned components of a mission with the trainer it names (ata_hrl: ATA-HRL
    and its ablations; dqn: the TR-POMDP agents, also after the attention ITA for AtRL-TR)."""
    from ata.core import runner
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
        stamp = runner.default_out_dir(session.mission)
        run_dir = out or stamp.with_name("train-" + stamp.name)
    trainer = runner.build_trainer(session)
    m = session.mission
    columns = [TextColumn("[bold]{task.description}"), BarColumn(), TaskProgressColumn(),
               TextColumn("{task.fields[status]}"), TimeElapsedColumn(), TimeRemainingColumn()]
    with Progress(*columns, console=Console(stderr=True), disable=quiet) as progress:
        task = progress.add_task(f"train {m.settings.name}", total=trainer.total_steps(),
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
def check(mission: str = typer.Argument(..., help="Mission file (TOML)."),
          set_: Optional[List[str]] = SetOption,
          plugins: Optional[str] = PluginsOption,
          show: bool = typer.Option(False, "--show", help="Print the resolved mission.")) -> None:
    """Validate a mission file without running it."""
    from ata.core import runner
    from ata.core.kernel import Simulation

    session = runner.load_session(mission, set_ or [], _split(plugins))
    # build the components once, on one scenario: a component that cannot fill its slot fails
    Simulation(session.mission.replace(scenarios=1), session.registry, [0])
    m = session.mission
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
                                         help="Also list each component's settings."),
            optional: Optional[str] = PluginsOption) -> None:
    """List every plugin, its version and the components it registers."""
    from ata.core.registry import (OPTIONAL_PLUGINS, collect_components, get_plugin_manager,
                                   plugin_version)
    from ata.core.settings import describe

    pm = get_plugin_manager(optional=_split(optional))
    registry = collect_components(pm)
    table = Table(title="ata plugins")
    table.add_column("plugin")
    table.add_column("version")
    table.add_column("components")
    table.add_column("hooks")
    for name, plugin in sorted(pm.list_name_plugin(), key=lambda x: x[0]):
        comps = [f"{c.kind}:{c.name}" for c in registry.components.values() if c.plugin == name]
        hooks = ", ".join(sorted(h.name for h in pm.get_hookcallers(plugin) or []))
        table.add_row(name, plugin_version(pm, plugin), "\n".join(comps) or "-", hooks)
    console.print(table)
    loaded = {pm.get_name(p) for p in pm.get_plugins()}
    missing = [n for n, mod in OPTIONAL_PLUGINS.items() if mod not in loaded]
    if missing:
        console.print(f"optional plugins not loaded (use --plugins): {', '.join(missing)}")
    if verbose:
        for info in sorted(registry.components.values(), key=lambda c: (c.kind, c.name)):
            cls = getattr(info.factory, "Settings", None)
            sub = Table(title=escape(f"[{info.name}] ({info.kind}, from {info.plugin})"),
                        title_justify="left")
            sub.add_column("key")
            sub.add_column("type")
            sub.add_column("default")
            sub.add_column("meaning")
            for key, tp, default, text in (describe(cls) if cls else []):
                sub.add_row(key, tp, escape(repr(default)), escape(text))
            console.print(sub)


def _split_or_none(text: Optional[str]) -> Optional[list[str]]:
    return _split(text) or None


@app.command("eval")
@user_errors
def eval_(paths: List[str] = typer.Argument(
              ..., metavar="FILE",
              help="Suite files (a suite table and method tables) or mission files; see "
                   "docs/evaluation.md."),
          out: Optional[Path] = typer.Option(None, "--out", "-o",
                                             help="Output folder (default: runs/eval-NAME-TIME)."),
          executor: str = typer.Option("process", "--executor", "-e",
                                       help="serial, process (local worker processes) or ray."),
          workers: Optional[int] = typer.Option(None, "--workers", "-w", min=1,
                                                help="Worker processes (process: default one "
                                                     "per core) or local Ray CPUs."),
          address: Optional[str] = typer.Option(None, "--address",
                                                help="Ray cluster address (default: "
                                                     "$RAY_ADDRESS, else a local Ray)."),
          chunk_size: int = typer.Option(50, "--chunk-size", min=1,
                                         help="Scenarios per work unit."),
          scenarios: Optional[int] = typer.Option(None, "--scenarios", "-n", min=1,
                                                  help="Scenarios per (method, setting, level) "
                                                       "(default: the suite's, else 500)."),
          seed: Optional[int] = typer.Option(None, "--seed", min=0,
                                             help="Root seed (default: the suite's, else 0)."),
          methods: Optional[str] = typer.Option(None, "--methods", metavar="NAME[,NAME]",
                                                help="Run only these methods."),
          settings: Optional[str] = typer.Option(None, "--settings", metavar="S[,S]",
                                                 help="Run only these team settings."),
          levels: Optional[str] = typer.Option(None, "--levels", metavar="LEVEL[,LEVEL]",
                                               help="Run only these uncertainty levels."),
          cache: Optional[Path] = typer.Option(None, "--cache",
                                               help="Cache folder for results that depend on "
                                                    "the scenario alone (MILP initial "
                                                    "allocations); default $ATA_CACHE, else "
                                                    "~/.cache/ata."),
          no_cache: bool = typer.Option(False, "--no-cache", help="Use no cache."),
          quiet: bool = typer.Option(False, "--quiet", "-q", help="No progress bar.")) -> None:
    """Evaluate methods on held-out scenarios across team settings and uncertainty levels."""
    from ata.core import evaluate as ev
    from ata.core import report as rep
    from ata.core.errors import MissionError
    from ata.core.executors import EXECUTORS, make_executor

    if executor not in EXECUTORS:
        raise MissionError("--executor", None, f"unknown executor {executor!r}; choose one of "
                           + ", ".join(EXECUTORS))
    # every job is built and validated before any scenario runs or anything is written
    suites, jobs = ev.plan(list(paths), scenarios=scenarios, seed=seed,
                           methods=_split_or_none(methods), settings=_split_or_none(settings),
                           levels=_split_or_none(levels))
    cache_dir = None if no_cache else (cache or ev.default_cache_dir())
    total = ev.total_scenarios(jobs)
    columns = [TextColumn("[bold]{task.description}"), BarColumn(), TaskProgressColumn(),
               TextColumn("{task.completed:,.0f}/{task.total:,.0f} scenarios"),
               TimeElapsedColumn(), TimeRemainingColumn()]
    with make_executor(executor, workers, address) as pool:
        with Progress(*columns, console=Console(stderr=True), disable=quiet) as progress:
            task = progress.add_task(f"eval: {len(jobs)} (method, setting, level)", total=total)
            result = ev.evaluate(jobs, pool, chunk_size=chunk_size, cache=cache_dir,
                                 progress=lambda n: progress.advance(task, n))
        described = pool.describe()
    arguments = {"paths": list(paths), "executor": described, "chunk_size": chunk_size,
                 "scenarios": scenarios, "seed": seed, "methods": methods,
                 "settings": settings, "levels": levels,
                 "cache": str(cache_dir) if cache_dir else None,
                 "first_scenario": ev.EVAL_FIRST_SCENARIO}
    out_dir = ev.write_eval(out or ev.default_out_dir(suites), suites, jobs, result, arguments)
    report = rep.summarize(rep.read_results(out_dir))
    _render_report(report)
    for warning in result.warnings:
        err_console.print(f"[yellow]warning:[/] {escape(warning)}", highlight=False)
    console.print(f"{len(result.rows)} rows in {result.wall_s:.1f} s; results: {out_dir} "
                  f"(ata report {out_dir} for report.md and figures)", highlight=False)


def _render_report(report) -> None:
    from ata.core.report import table_rows, title

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
                                                     "first)."),
           reference: Optional[str] = typer.Option(
               None, "--reference", "-r",
               help="The method the others are compared with (default: ATA-HRL if present, "
                    "else the first method)."),
           no_figures: bool = typer.Option(False, "--no-figures", help="Write no figures."),
           resamples: int = typer.Option(2000, "--resamples", min=10,
                                         help="Bootstrap resamples.")) -> None:
    """Tables (with bootstrap confidence intervals) and figures of an evaluation."""
    from ata.core import report as rep

    result, written = rep.write_report(run_dir, reference, not no_figures, resamples)
    _render_report(result)
    console.print("wrote " + ", ".join(str(p) for p in written), highlight=False)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(app())
