"""`ata run`, `ata eval` and `ata check`: missions and suites run."""

from __future__ import annotations

from pathlib import Path
from typing import List, Optional

import typer

from ata.cli.common import (AddressOption, ForceOption, IsolateOption, PluginsOption, QuietOption,
                            SetOption, TimeoutOption, _split, _split_or_none, app, user_errors)
import ata.cli.terminal as terminal
from ata.cli.terminal import console, escape, note


@app.command()
@user_errors
def run(mission: Optional[str] = typer.Argument(
            None, metavar="MISSION", help="Mission file (TOML) or builtin:NAME. Default: the "
                                          "built-in mission, setting (a), medium uncertainty."),
        set_: Optional[List[str]] = SetOption,
        plugins: Optional[str] = PluginsOption,
        scenarios: Optional[int] = typer.Option(None, "--scenarios", "-n", min=1, metavar="N",
                                                help="Scenarios to run (default: the "
                                                     "mission's; --set mission.scenarios=N)."),
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
    from ata.runtime import bytecode   # on use: start-up time
    if isolate:
        bytecode.guard()       # before the modules that run the world are loaded
    from ata.experiment import runner   # on use: start-up time
    from ata.isolation import require_sandbox   # on use: start-up time
    from ata.session import IN_PROCESS   # on use: start-up time

    backend = require_sandbox(decision_timeout) if isolate else IN_PROCESS
    overrides = list(set_ or []) + ([f"mission.scenarios={scenarios}"] if scenarios else [])
    session, out_dir, result = runner.run(
        mission, overrides, _split(plugins), out, workers=workers, executor=executor,
        address=address, chunk_size=chunk_size, cache=cache, force=force, backend=backend,
        notify=note, progress=terminal.progress_bar(quiet))
    m = session.mission
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
    from ata.runtime import bytecode   # on use: start-up time
    if isolate:
        bytecode.guard()       # before the modules that run the world are loaded
    from ata.experiment import evaluate as ev   # on use: start-up time
    from ata.isolation import require_sandbox   # on use: start-up time
    from ata.results import report as rep   # on use: start-up time
    from ata.results.rows import read_results   # on use: start-up time
    from ata.session import IN_PROCESS   # on use: start-up time

    backend = require_sandbox(decision_timeout) if isolate else IN_PROCESS
    out_dir, result = ev.evaluate_suites(
        list(paths), out, executor=executor, workers=workers, address=address,
        chunk_size=chunk_size, scenarios=scenarios, seed=seed,
        methods=_split_or_none(methods), settings=_split_or_none(settings),
        levels=_split_or_none(levels), cache=cache, no_cache=no_cache, force=force,
        backend=backend, notify=note, progress=terminal.progress_bar(quiet))
    terminal.report_tables(rep.summarize(read_results(out_dir)))
    terminal.warn(result.warnings)
    console.print(f"{len(result.rows)} rows in {result.wall_s:.1f} s; results: "
                  f"{escape(str(out_dir))} (ata report {escape(str(out_dir))} for report.md and "
                  "figures)", highlight=False)

@app.command()
@user_errors
def check(mission: str = typer.Argument(
              ..., metavar="MISSION|REFERENCE",
              help="Mission file (TOML); with --component, a component: PATH.py:Class, "
                   "module:Class or a registered name."),
          set_: Optional[List[str]] = SetOption,
          plugins: Optional[str] = PluginsOption,
          show: bool = typer.Option(False, "--show", help="Print the resolved mission."),
          component: Optional[str] = typer.Option(
              None, "--component", metavar="KIND",
              help="Check a component of this kind (policy, condition, injector, ...) with "
                   "ata.testing.check_component instead: --set NAME.KEY=V sets its settings, "
                   "--set mission.KEY=V the small mission's."),
          seed: Optional[int] = typer.Option(None, "--seed", min=0, metavar="N",
                                             help="With --component: the root seed (default: "
                                                  "drawn anew)."),
          isolate: bool = typer.Option(False, "--isolate",
                                       help="With --component: run the checks in the sandbox, "
                                            "so that nothing of an untrusted component runs "
                                            "outside it (see docs/isolation.md).")) -> None:
    """Validate a mission file without running it; or, with --component, check that a
    component keeps the contract (docs/plugins.md, "Checking a component")."""
    from ata.experiment import runner   # on use: start-up time
    from ata.session import load_session   # on use: start-up time

    if component is not None:
        from ata.isolation.check import check_isolated   # on use: start-up time
        from ata.testing import check_reference   # on use: start-up time
        checker = check_isolated if isolate else check_reference
        try:
            name = checker(component, mission, set_ or [], _split(plugins), seed)
        except AssertionError as exc:
            from ata.cli.terminal import err_console   # on use: start-up time
            err_console.print(f"[red]failed[/]: {escape(str(exc))}", highlight=False)
            raise typer.Exit(1) from None
        console.print(f"[green]ok[/]: {component} {escape(name)} ({escape(mission)}) keeps "
                      "the contract" + (" (checked in the sandbox)" if isolate else ""),
                      highlight=False)
        return
    session = load_session(mission, set_ or [], _split(plugins))
    m = session.mission
    runner.build_once(session)   # a component that cannot fill its slot fails
    console.print(f"[green]ok[/]: {escape(mission)}: setting {m.settings.setting} "
                  f"({m.sizes.humans} humans, {m.sizes.robots} robots, {m.sizes.tasks} POIs), "
                  f"{m.settings.scenarios} scenarios, {m.settings.uncertainty} uncertainty "
                  f"(fatigue variance {m.fatigue_variance}, event probability "
                  f"{m.event_probability})", highlight=False)
    if show:
        console.print(m.to_toml(), highlight=False, markup=False)
