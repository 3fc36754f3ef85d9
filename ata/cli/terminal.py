"""What the commands draw on the terminal: consoles made per command, the progress bar of `ata
run` and `ata eval`, tables with every value whole at any width (`tables.layout`), messages."""

from __future__ import annotations

import contextlib
import sys
from typing import Any, Iterator

import re

from rich.console import Console
from rich.markup import escape as _markup_escape
from rich.progress import (BarColumn, Progress, ProgressColumn, TaskProgressColumn, TextColumn,
                           TimeElapsedColumn, TimeRemainingColumn)
from rich.table import Column, Table
from rich.text import Text

from ata.cli.tables import layout


WORD_LIMIT = 120
"""Characters of one word (a run without spaces: a name, a path) shown at most: a 10 MB
mission name is one short word in a message, not 10 MB on the terminal."""
TEXT_LIMIT = 4000
"""Characters of one message shown at most."""
_CONTROL = re.compile(r"[\x00-\x08\x0b-\x1f\x7f-\x9f]")
_LONG_WORD = re.compile(r"\S{%d,}" % (WORD_LIMIT + 1))


def plain(text: str, newlines: bool = True) -> str:
    """Text for the terminal from what a user wrote (names, titles, paths, and messages that
    quote them): control characters shown as ``\\xNN`` (an ANSI escape in a mission title
    cannot move the cursor or forge a line; with `newlines` False a newline is shown so too),
    each overlong word and the whole shortened in the middle."""
    text = _CONTROL.sub(lambda m: f"\\x{ord(m.group()):02x}", str(text))
    if not newlines:
        text = text.replace("\n", "\\x0a")
    text = _LONG_WORD.sub(lambda m: _shorten(m.group(), WORD_LIMIT), text)
    return _shorten(text, TEXT_LIMIT)


def _shorten(text: str, limit: int) -> str:
    if len(text) <= limit:
        return text
    keep = limit // 2
    return f"{text[:keep]}...({len(text) - 2 * keep:,} characters left out)...{text[-keep:]}"


def escape(text: str) -> str:
    """`plain` text, with rich's markup escaped (a message names tables as [mission])."""
    return _markup_escape(plain(text))


def help_without_type_tags() -> None:
    """Recent typer prints a Python type after every parameter in help pages (``<bool>`` after
    a flag, ``<list[str]>`` after an argument). Our parameters name their values in their
    metavars (FILE, DIR, N) and flags take none: print no type tag but an option's metavar."""
    from typer import core   # on use: start-up time

    for cls in (getattr(core, "TyperArgument", None), getattr(core, "TyperOption", None)):
        if cls is not None and hasattr(cls, "display_type_rich"):
            cls.display_type_rich = lambda self, ctx: (
                None if getattr(self, "is_flag", False) or isinstance(self, core.TyperArgument)
                else self.metavar)


def one_line_warnings() -> None:
    """An optional extra that failed (`ata.runtime.extras.ExtraWarning`) is one ``warning:``
    line on stderr, not Python's two lines naming our source; other warnings as Python shows
    them."""
    import warnings   # on use: start-up time

    from ata.runtime.extras import ExtraWarning   # on use: start-up time
    shown = warnings.showwarning

    def show(message, category, filename, lineno, file=None, line=None) -> None:
        if issubclass(category, ExtraWarning):
            warn([str(message)])
        else:
            shown(message, category, filename, lineno, file, line)
    warnings.showwarning = show


MIN_WIDTH = 40
"""The narrowest console drawn: a smaller width (COLUMNS=0) would print nothing at all; the
terminal wraps what is wider."""


class LazyConsole:
    """A rich console made at first use in each command, so that it sees the terminal (and
    COLUMNS) of the invocation, not of the import. Output degrades but never vanishes: at
    least `MIN_WIDTH` columns, and a character the stream's encoding lacks (an ASCII locale,
    PYTHONIOENCODING=ascii) is replaced instead of ending the command."""

    def __init__(self, **kwargs):
        self.kwargs = kwargs

    def __getattr__(self, name):
        return getattr(self._console(), name)

    def _console(self) -> Console:
        stream = sys.stderr if self.kwargs.get("stderr") else sys.stdout
        # an ASCII locale's stdout is 'surrogateescape', which fails on 'é' as 'strict' does
        if getattr(stream, "errors", None) in ("strict", "surrogateescape") \
                and hasattr(stream, "reconfigure") \
                and "utf" not in str(getattr(stream, "encoding", "") or "").lower():
            try:
                stream.reconfigure(errors="replace")
            except (OSError, ValueError):     # a stream that cannot be reconfigured now
                pass
        console = Console(**self.kwargs)
        if console.width < MIN_WIDTH:
            console = Console(**self.kwargs, width=MIN_WIDTH)
        return console


console = LazyConsole()
err_console = LazyConsole(stderr=True)


def add_broken_plugins(table: Table, broken: list) -> Table:
    """`table` with `ata plugins`' rows of the plugins left out: the components each declared
    or had registered (unknown when its module did not import), marked broken."""
    for item in broken:
        module = item.entry_point.partition(" = ")[2]
        for kind, name in item.components or [("(unknown)", "-")]:
            table.add_row(name, kind, f"{module} (broken)", item.package)
    return table


def note(text: str, wrap: bool = False) -> None:
    """A message for the user on stderr (resuming, interrupted, notes); with `wrap`, wrapped
    between words at the terminal's width."""
    err_console.print(escape(text), highlight=False, soft_wrap=not wrap)


def warn(warnings: list[str]) -> None:
    for warning in warnings:
        err_console.print(f"[yellow]warning:[/] {escape(warning)}", highlight=False,
                          soft_wrap=True)


class SpeedColumn(ProgressColumn):
    """Scenarios simulated per second."""

    def render(self, task) -> Text:
        return Text(f"{task.speed or 0:,.1f} scenarios/s", style="cyan")


def progress_bar(quiet: bool):
    """The progress bar of `ata run` and `ata eval` on stderr (an `execute.ProgressFactory`)."""

    @contextlib.contextmanager
    def bar(title: str, total: int, done: int) -> Iterator[Any]:
        columns = [TextColumn("[bold]{task.description}"), BarColumn(), TaskProgressColumn(),
                   TextColumn("{task.completed:,.0f}/{task.total:,.0f}"), SpeedColumn(),
                   TimeElapsedColumn(), TimeRemainingColumn()]
        with Progress(*columns, console=Console(stderr=True), disable=quiet) as progress:
            task = progress.add_task(escape(title), total=total, completed=done)
            yield lambda n: progress.advance(task, n)
            progress.update(task, completed=total)   # no float shortfall

    return bar


@contextlib.contextmanager
def training_bar(title: str, trainer: Any, quiet: bool) -> Iterator[Any]:
    """`ata train`'s progress bar on stderr; its value is told of each log.csv row (the status
    beside the bar), or of None to catch up with the trainer's steps."""
    # the bar and the times keep their width; the status gives way (cut short) at 80 columns
    columns = [TextColumn("[bold]{task.description}",
                          table_column=Column(no_wrap=True, min_width=len(title))),
               BarColumn(bar_width=16, table_column=Column(no_wrap=True, min_width=16)),
               TaskProgressColumn(table_column=Column(no_wrap=True, min_width=4)),
               TimeElapsedColumn(table_column=Column(no_wrap=True, min_width=7)),
               TimeRemainingColumn(table_column=Column(no_wrap=True, min_width=7)),
               TextColumn("{task.fields[status]}",
                          table_column=Column(no_wrap=True, overflow="ellipsis", ratio=1))]
    with Progress(*columns, console=Console(stderr=True), disable=quiet) as progress:
        task = progress.add_task(title, total=trainer.total_steps(), status="")

        def on_row(row: dict | None) -> None:
            if row is None:
                progress.update(task, completed=trainer.done_steps())
                return
            parts = [f"{row['phase']} {row['step']}"]
            for key, label in (("episodes_per_s", "ep/s"), ("mean_score", "score"),
                               ("epsilon", "eps"), ("eval_score", "held-out"),
                               ("aux_fatigue_mse", "fatigue mse")):
                if row.get(key):
                    parts.append(f"{label} {row[key]}")
            progress.update(task, completed=trainer.done_steps(), status=" | ".join(parts))

        yield on_row


def table(title: str, header: list[str], rows: list[list[str]],
          sections: list[int] | tuple[int, ...] = ()) -> None:
    """A table with every value whole at the terminal's width: split into several, each with
    the first column, where it is too wide; long headers wrap between words; a rule after each
    row of `sections` (indices)."""
    header = [plain(h, newlines=False) for h in header]
    rows = [[plain(v, newlines=False) for v in row] for row in rows]
    parts = layout(header, rows, console.width)
    for k, part in enumerate(parts):
        more = f" ({k + 1} of {len(parts)})" if len(parts) > 1 else ""
        drawn = Table(title=_markup_escape(plain(title + more, newlines=False)))
        for i, width in zip(part.columns, part.widths):
            drawn.add_column(_markup_escape(header[i]), justify="left" if i == 0 else "right",
                             width=width, overflow="fold")
        for k, row in enumerate(rows):
            drawn.add_row(*[_markup_escape(row[i]) for i in part.columns],
                          end_section=k in sections)
        console.print(drawn)


def key_values(title: str, rows: list[tuple[str, str]]) -> None:
    """A key per line (`ata run`'s summary): readable at 80 columns."""
    from rich import box   # on use: start-up time

    drawn = Table(title=_markup_escape(plain(title, newlines=False)), box=box.SIMPLE,
                  show_header=False, title_justify="left")
    drawn.add_column("what", style="bold", no_wrap=True)
    drawn.add_column("value", overflow="fold")
    for key, value in rows:
        drawn.add_row(_markup_escape(plain(key, newlines=False)),
                      _markup_escape(plain(value, newlines=False)))
    console.print(drawn)


def report_tables(report) -> None:
    """An evaluation report's tables, one per (setting, level) (`report.table_rows`)."""
    from ata.results.report import table_rows, title   # on use: start-up time

    for setting, level in report.groups():
        table(title(setting, level), *table_rows(report, setting, level, short=True))
    for t in report.seeds:
        table(t.title, t.header, t.rows)


def show_summary(shown) -> None:
    """What `ata show` replayed (an `ata.viz.show` result): the scenario, its score and events,
    whether the run folder's score was met again, and the files written."""
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

