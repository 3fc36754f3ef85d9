"""`ata report`, `ata compare` and `ata show`: what runs wrote, read."""

from __future__ import annotations

from pathlib import Path
from typing import List, Optional

import typer

from ata.cli.common import (MarkdownOption, ResamplesOption, SetOption, _split, _split_or_none, app,
                            user_errors)
import ata.cli.terminal as terminal
from ata.cli.terminal import console, escape, note


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
               False, "--markdown", help="Print the tables of docs/RESULTS.md as Markdown "
                                         "instead: every method's score, the paired "
                                         "differences of --pair (or of the suite's pairs) "
                                         "and the time per scenario."),
           pair: Optional[List[str]] = typer.Option(
               None, "--pair", metavar="A,B", help="A paired difference A - B for --markdown "
                                                   "(repeatable)."),
           column: str = typer.Option(
               "score", "--column", "-c", metavar="COL",
               help="The column of --markdown's paired differences (default: score; "
                    "expected_score for the expected points)."),
           resamples: int = ResamplesOption) -> None:
    """Tables (with bootstrap confidence intervals) and figures of an evaluation, or the
    learning curves of a training run."""
    from ata.core.errors import MissionError   # on use: start-up time
    from ata.results import markdown as results_md   # on use: start-up time
    from ata.results import report as rep   # on use: start-up time
    from ata.results import training_report   # on use: start-up time
    from ata.results.rows import check_column, read_results   # on use: start-up time
    from ata.runtime.machine import provenance_text   # on use: start-up time
    from ata.published.sets import read_from_sets   # on use: start-up time

    if any(training_report.is_training_folder(d) for d in run_dir):
        if len(run_dir) > 1:
            raise MissionError("", None, "a training run folder is reported alone: "
                               "ata report RUN_DIR")
        log, written = training_report.write_curves(run_dir[0], out, not no_figures)
        terminal.table(f"training log {log.path}", *training_report.curves_rows(log))
        for t in training_report.seed_tables(log):
            terminal.table(t.title, t.header, t.rows)
    elif markdown:
        pairs = [tuple(_split(p)) for p in pair or []]
        if any(len(p) != 2 for p in pairs):
            raise MissionError("--pair", None, "names two methods: --pair A,B")
        res = read_results(run_dir)
        check_column(res, column, str(run_dir[0]))
        print(results_md.results_markdown(res, pairs or None, resamples,
                                          made_on=results_md.made_on(run_dir), column=column),
              end="")
        return
    else:
        result, written = rep.write_report(run_dir, reference, not no_figures, resamples,
                                           paired_reference, out)
        if result.results.replaced:
            note("cells taken from a later folder: " + rep.replaced_text(result.results))
        terminal.report_tables(result)
        for folder in run_dir:
            made = provenance_text(folder)
            if made is not None:
                console.print(f"made with: {escape(made)}", highlight=False)
            for line in read_from_sets(folder):
                console.print(f"published rows read: {escape(line)}", highlight=False)
    console.print("wrote " + ", ".join(escape(str(p)) for p in written), highlight=False)


@app.command()
@user_errors
def compare(folders: List[Path] = typer.Argument(
                ..., metavar="A [B]",
                help="One `ata eval` folder, or two folders of `ata eval` or `ata run`; B may "
                     "be published rows, published[:NAME|:PATH]. A table per cell of every "
                     "method against --base; with --full each method - --base, A - B method "
                     "by method, or A - each published method."),
            column: Optional[List[str]] = typer.Option(
                None, "--column", "-c", metavar="COL",
                help="A results.csv column: score (the default), expected_score, "
                     "reallocations, ... (repeatable)."),
            base: Optional[str] = typer.Option(
                None, "--base", metavar="METHOD",
                help="The method subtracted: of B, else of A (default greedy, else B's first "
                     "method, or A's); against published rows NAME[,NAME] (default: greedy, "
                     "or every one with --full or --power)."),
            methods: Optional[str] = typer.Option(None, "--methods", metavar="NAME[,NAME]",
                                                  help="Only these methods of A."),
            power: bool = typer.Option(
                False, "--power", help="The scenarios a paired 95% CI needs to clear 0, at "
                                       "the difference that expected_score estimates."),
            means: bool = typer.Option(False, "--means",
                                       help="The columns' means per method and cell instead."),
            full: bool = typer.Option(
                False, "--full",
                help="Every pairing's table instead of one table per cell: each method of A - "
                     "the same method of B (or - --base), or each method of A - each "
                     "published method (or each of --base)."),
            markdown: bool = MarkdownOption,
            resamples: int = ResamplesOption) -> None:
    """Paired differences on the same scenarios, with bootstrap 95% CIs, on any results column:
    by default one table per setting and level, every method of A (and of B) with its mean,
    its difference to --base and P(beats --base); every pairing with --full; the scenarios a CI
    needs to clear 0 (--power); or column means (--means)."""
    from ata.core.errors import MissionError   # on use: start-up time
    from ata.results import compare as cmp   # on use: start-up time
    from ata.published import sets as published   # on use: start-up time
    from ata.results.rows import read_results   # on use: start-up time

    if len(folders) > 2:
        raise MissionError("", None, "compares one folder (methods against --base) or two "
                           "(A - B): ata compare A [B]")
    if power and means:
        raise MissionError("--means", None, "give --power or --means, not both")
    if len(folders) == 2 and published.is_published(folders[1]):
        _against_published(folders, column, base, _split_or_none(methods), power, means, full,
                           markdown, resamples)
        return
    results = [read_results(f) for f in folders]
    columns = list(dict.fromkeys(column or ["score"]))
    other = results[1] if len(results) > 1 else None
    if means:
        tables = cmp.mean_tables([(str(f), r) for f, r in zip(folders, results)], columns,
                                 _split_or_none(methods))
    elif power or full:
        tables = cmp.compare(results[0], other, columns, base=base,
                             methods=_split_or_none(methods), power=power, resamples=resamples)
    else:
        tables = cmp.leaderboards(results[0], other, columns, base=base,
                                  methods=_split_or_none(methods), resamples=resamples)
        if other is not None and not markdown:
            note(f"A: {folders[0]}; B: {folders[1]}", wrap=True)
    _print_tables(tables, markdown)


def _print_tables(tables, markdown: bool) -> None:
    from ata.results import compare as cmp   # on use: start-up time

    if markdown:
        print(cmp.markdown(tables), end="")
        return
    for table in tables:
        terminal.table(table.title, table.header, table.rows, getattr(table, "sections", ()))


def _against_published(folders: List[Path], column: Optional[List[str]], base: Optional[str],
                       methods: Optional[List[str]], power: bool, means: bool, full: bool,
                       markdown: bool, resamples: int) -> None:
    """`ata compare A published[:NAME]`, after `published.check_pairing`, on the published
    rows: by default a table per cell of A's methods and every published method against
    greedy (or each --base); with --full or --power each method of A against each published
    method (or each --base); with --means the columns' means of both."""
    from ata.core.errors import MissionError   # on use: start-up time
    from ata.results import compare as cmp   # on use: start-up time
    from ata.results import seeds   # on use: start-up time
    from ata.published import sets as published   # on use: start-up time
    from ata.results.rows import read_results   # on use: start-up time

    mine = read_results(folders[0])
    theirs, manifest, where = published.read_published(folders[1])
    columns = list(dict.fromkeys(column or ["score"]))
    compact = not (full or power or means)
    default = [cmp.BASE if cmp.BASE in theirs.methods else theirs.methods[0]] if compact \
        else list(theirs.methods)
    bases = _split(base) if base else default
    unknown = [b for b in bases if b not in theirs.methods]
    if unknown:
        raise MissionError("--base", None, f"no published method {unknown[0]!r}; name one of "
                           "the published methods: " + ", ".join(theirs.methods))
    # the default table shows every published method: each must be this code's
    published.check_pairing(mine, folders[0], manifest,
                            list(theirs.methods) if compact or means else bases, where)
    tables = []
    if means:
        tables = cmp.mean_tables([(str(folders[0]), mine), (published.shown(where), theirs)],
                                 columns, methods)
    for name in [] if means else bases:
        if compact:
            # a published training seed's rows (NAME seed S) are in the tables across seeds
            plain = seeds.plain_methods(theirs.methods) + [name]
            tables += cmp.leaderboards(mine, theirs, columns, base=name, methods=methods,
                                       tags=("A", "published"), b_methods=plain,
                                       resamples=resamples)
        else:
            tables += cmp.compare(mine, theirs, columns, base=name, methods=methods,
                                  power=power, resamples=resamples)
    # across training seeds (ata.results.seeds): each method's seeds grouped, A - B with its
    # two-level interval and P(a seed of A beats a seed of B); by default only where A has a
    # method of several seeds (the published set's seeds alone: with --full)
    across = not (power or means) and (full or seeds.has_seeds(mine))
    if across:
        tables += seeds.published_tables(mine, theirs, bases if base else list(theirs.methods),
                                         resamples, columns[0], methods)
    if not markdown:
        note(f"none rerun: paired with the published rows of "
             f"{published.describe(where, manifest)}", wrap=True)
        if not across and not (power or means) and seeds.has_seeds(theirs):
            note("the published set holds training seeds (NAME seed S) of "
                 + ", ".join(g for g, ms in seeds.seed_groups(theirs.methods).items()
                             if len(ms) > 1)
                 + ": --full adds each method against them across seeds", wrap=True)
    _print_tables(tables, markdown)


@app.command()
@user_errors
def publish(eval_dir: Path = typer.Argument(..., metavar="EVAL_DIR",
                                            help="An `ata eval` folder."),
            out: Path = typer.Option(..., "--out", "-o", metavar="DIR",
                                     help="The folder to write (rows.csv.gz, manifest.json); "
                                          "ata/published/NAME ships it as published:NAME.")) \
        -> None:
    """Publish an evaluation's per-scenario rows with the code and weight digests, model
    revision and scenarios they were made with, for `ata compare A published:NAME` to pair new
    methods against without rerunning them (docs/reports.md, "Published rows")."""
    from ata.published import sets as published   # on use: start-up time

    folder = published.publish(eval_dir, out)
    console.print(f"wrote {escape(str(folder / published.ROWS))}, "
                  f"{escape(str(folder / published.MANIFEST))}", highlight=False)


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
    from ata.viz.show import show as show_scenario   # on use: start-up time

    terminal.show_summary(show_scenario(target, scenario, list(set_ or []), out, animate,
                                        progress=terminal.progress_bar(False)))
