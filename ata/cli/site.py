"""`ata site`: the results page of published sets and result folders."""

from __future__ import annotations

from pathlib import Path
from typing import List, Optional

import typer

from ata.cli.common import ResamplesOption, app, user_errors
from ata.cli.terminal import console, escape, note


@app.command()
@user_errors
def site(sets: List[str] = typer.Argument(
             ..., metavar="SET...",
             help="published (the shipped set), published:NAME or published:PATH, or a result "
                  "folder of `ata eval` or `ata run`."),
         out: Path = typer.Option(Path("site"), "--out", "-o", metavar="DIR",
                                  help="The page's folder (default: site); an earlier page "
                                       "there is replaced."),
         base: Optional[str] = typer.Option(
             None, "--base", metavar="METHOD",
             help="The method every other is paired with (default: greedy, else the first)."),
         verify: int = typer.Option(
             0, "--verify", metavar="N",
             help="Rerun N scenarios of every method and cell of each published set here; "
                  "identical rows make the set 'reproduced'."),
         verified: Optional[List[Path]] = typer.Option(
             None, "--verified", metavar="FILE",
             help="Reruns recorded before (a page's verified.json; repeatable): those of this "
                  "set and this code count as --verify's."),
         no_figures: bool = typer.Option(False, "--no-figures", help="Draw no figures."),
         resamples: int = ResamplesOption) -> None:
    """A static results page (leaderboards, figures, a page per method with its provenance)
    that any web server can host."""
    from ata.site import build_site   # on use: start-up time

    words = ["ata site", *sets, "-o", str(out)]
    words += [f"--base {base}"] if base else []
    words += [f"--verify {verify}"] if verify else []
    words += [f"--verified {p}" for p in verified or []]
    result = build_site(list(sets), out, base=base, verify_per_cell=verify,
                        verified=list(verified or []), with_figures=not no_figures,
                        resamples=resamples, command=" ".join(words), notify=note)
    for k, src in enumerate(result.sources):
        name, _, why = result.tiers[k]
        console.print(f"{escape(src.name)}: {name} ({escape(why)})", highlight=False)
    console.print(f"wrote {escape(str(out))}/index.html and {len(result.files) - 1} more files",
                  highlight=False)
