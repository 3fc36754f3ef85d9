"""What every command shares: the typer app, the common options and the handling of user errors."""

from __future__ import annotations

import functools
import inspect
from typing import Callable, Optional

import typer
import typer.core

from ata import __version__
import ata.cli.terminal as terminal
from ata.cli.terminal import console, err_console, escape, note

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
terminal.one_line_warnings()

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
                                  "install 'ata[sandbox]'); see docs/isolation.md.")
TimeoutOption = typer.Option(60.0, "--decision-timeout", min=0.001, max=86400.0,
                             metavar="SECONDS",
                             help="With --isolate: the time limit of one decision call of a "
                                  "batch (default 60, at most a day).")


def user_errors(func: Callable) -> Callable:
    """Turn bad input into one clear message and exit status 2, without a traceback; an
    interrupted run into what it saved and exit status 130."""

    @functools.wraps(func)
    def wrapper(*args, **kwargs):
        import pluggy   # on use: start-up time

        from ata.core.errors import ContractError, MissionError   # on use: start-up time
        from ata.experiment.execute import Interrupted   # on use: start-up time
        from ata.runtime.executors import WorkerDied   # on use: start-up time
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
        except WorkerDied as exc:
            err_console.print(f"[bold red]error:[/] {escape(str(exc))}", highlight=False,
                              soft_wrap=True)
            raise typer.Exit(1) from None
        except SystemExit as exc:
            # ata itself ends a command with typer.Exit: a SystemExit comes from code the
            # command loaded (a method file calling sys.exit at import), which would otherwise
            # end it silently with the status it chose
            err_console.print(f"[bold red]error:[/] code the command loaded called sys.exit("
                              f"{escape(repr(exc.code))}) (a plugin, or a file a mission "
                              "names): a component must raise an exception instead",
                              highlight=False, soft_wrap=True)
            raise typer.Exit(2) from None

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
