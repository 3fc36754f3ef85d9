"""`ata site`: the results page of published sets and result folders, written as one static
folder that any web server can host (no network at view time).

The folder holds index.html (the sets, a leaderboard per setting and level, `ata report`'s
figures), a page per method of each set and one per method with training seeds (the seeds as
one, then each seed), site.css and site.js, the figures as PNG, site.json (the leaderboards'
numbers, and the rows across seeds) and verified.json (the reruns that make a set
"reproduced", `ata.site.verify`). The same sets, code and records give the same HTML and JSON
files byte for byte: nothing in them holds a date or a machine's path.
"""

from __future__ import annotations

import json
import math
import os
import shutil
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable

from ata.core.errors import MissionError
from ata.results.report import (ABLATION_PREFIX, DEFAULT_REFERENCE, Report, figure_caption,
                                figures as draw, pyplot)
from ata.results.rows import RESAMPLES
from ata.results.seed_figure import STEM as SEEDS_STEM, drawn as seeds_drawn
from ata.runtime.folders import prepare_out_dir, refuse_other_kind, writing
from ata.site.assets import CSS, JS
from ata.site.pages import (Tier, index_html, method_html, page_name, seeds_html,
                            seeds_page_name)
from ata.site.board import Board, build_board, merged, report_cells, report_paired
from ata.site.sources import Source, load_source
from ata.site.verify import read_records, tier, verify

MARK = "site.json"
"""The file that marks a folder as a results page (`ata.runtime.folders.KINDS`)."""


@dataclass
class Site:
    out: Path
    sources: list[Source]
    board: Board
    tiers: dict[int, Tier]
    files: list[str]


def build_site(specs: list[str], out: str | Path, *, base: str | None = None,
               verify_per_cell: int = 0, verified: list[str | Path] = (),
               with_figures: bool = True, draw_figures: bool = True,
               resamples: int = RESAMPLES, command: str | None = None,
               notify: Callable[[str], None] | None = None) -> Site:
    """Read the sets (`published`, `published:NAME|PATH`, result folders), rerun
    `verify_per_cell` scenarios of every method and cell of each published set when asked,
    and write the page into `out`, whole (a folder there is replaced only if it is a page).
    `draw_figures=False` names the figures in the page without drawing them (for a test that
    compares a page's HTML and JSON, which do not depend on matplotlib's version)."""
    if not specs:
        raise MissionError("", None, "give published sets or result folders: ata site "
                           "published runs/mine -o site")
    out = Path(out)
    refuse_other_kind(out, "site")
    if out.is_dir() and any(out.iterdir()) and not (out / MARK).is_file():
        raise MissionError("--out", None, f"{out} holds files and is not a results page "
                           f"(no {MARK}); choose another folder")
    if with_figures and draw_figures:
        pyplot()                # a missing matplotlib fails before anything is read or run
    sources = [load_source(s) for s in specs]
    taken: set[str] = set()
    for src in sources:                 # two sets of one name: the later one's pages apart
        name, k = src.name, 2
        while src.slug in taken:
            src.name, k = f"{name}-{k}", k + 1
        taken.add(src.slug)
    if verify_per_cell and not any(src.kind == "published" for src in sources):
        raise MissionError("--verify", None, "no published set to rerun: --verify reruns a "
                           "sample of each published set (ata publish a folder first)")
    records = read_records(list(verified))
    for k, src in enumerate(sources):
        if verify_per_cell and src.kind == "published":
            if notify:
                notify(f"rerunning {verify_per_cell} scenario(s) of every method and cell of "
                       f"{src.name}")
            records.append(verify(src, verify_per_cell))
    tiers = {k: tier(src, records) for k, src in enumerate(sources)}
    board = build_board(sources, base, resamples)
    command = command or "ata site " + " ".join(s.spec for s in sources) + " -o site"
    files: dict[str, bytes] = {}
    with tempfile.TemporaryDirectory() as tmp:
        shown = _figures(board, sources, Path(tmp), draw_figures, resamples) \
            if with_figures else []
        for path in sorted(Path(tmp).glob("*.png")):     # PNG alone: half the bytes to host
            files[path.name] = path.read_bytes()
    files["index.html"] = index_html(sources, board, tiers, shown, command).encode()
    for k, src in enumerate(sources):
        for name, info in src.methods.items():
            entries = [e for e in board.entries if e.source is src and e.method == name]
            if entries:
                files[page_name(src, name)] = method_html(
                    src, info, entries[0].label, entries, tiers[k], board.base).encode()
        for group in dict.fromkeys(g.group for g in board.seeded if g.source is src):
            rows = [g for g in board.seeded if g.source is src and g.group == group]
            members = [e for e in board.entries if e.source is src and e.seed_of == group]
            files[seeds_page_name(src, group)] = seeds_html(src, group, rows, members, tiers[k],
                                                            board.base).encode()
    files["site.css"] = CSS.encode()
    files["site.js"] = JS.encode()
    # every record of these sets' rows (once each), whether it made its set reproduced or not:
    # a page rebuilt from them says the same
    digests = {src.digest for src in sources if src.digest}
    kept = {json.dumps(r, sort_keys=True): r for r in records if r.get("rows_sha256") in digests}
    files["verified.json"] = (json.dumps(list(kept.values()), indent=1, sort_keys=True)
                              + "\n").encode()
    files[MARK] = (json.dumps(site_data(sources, board, tiers, command), indent=1,
                              sort_keys=True) + "\n").encode()
    _write(out, files)
    return Site(out, sources, board, tiers, sorted(files))


def _figures(board: Board, sources: list[Source], folder: Path, draw_them: bool = True,
             resamples: int = RESAMPLES) -> list[tuple[str, str]]:
    """`ata report`'s figures of the merged rows into `folder`: (stem, caption) of each."""
    res = merged(sources)
    reference = DEFAULT_REFERENCE if DEFAULT_REFERENCE in res.methods else board.base
    report = Report(reference=reference, results=res, cells=report_cells(board))
    paired = report_paired(board)
    stems = planned(report, paired)
    if draw_them:
        drawn = [p.stem for p in draw(report, folder, paired, resamples)
                 if p.suffix == ".png"]
        if drawn != stems:
            raise AssertionError(f"figures drawn {drawn}, planned {stems}")
    return [(stem, figure_caption(stem, report, paired).replace("`", "")) for stem in stems]


def planned(report: Report, paired: list) -> list[str]:
    """The stems of the figures `ata.results.report.figures` draws of `report` (it skips those
    without data)."""
    cells = report.cells
    out = [f"fig_setting_{s}" for s in report.results.settings
           if any(c.setting == s for c in cells)]
    if any(c.method.startswith(ABLATION_PREFIX) for c in cells):
        out.append("fig_ablations")
    return out + (["fig_paired"] if paired else []) + \
        ([SEEDS_STEM] if seeds_drawn(report.results) else [])


def _number(x: Any) -> Any:
    return None if isinstance(x, float) and not math.isfinite(x) else x


def site_data(sources: list[Source], board: Board, tiers: dict[int, Tier],
              command: str) -> dict[str, Any]:
    """site.json: the sets and every leaderboard row, for programs."""
    order = {id(src): k for k, src in enumerate(sources)}
    sets = [{"name": src.name, "spec": src.spec, "release": src.release, "tier": tiers[k][0],
             "tier_reason": tiers[k][2], "ata": src.ata,
             "model_revision": src.model_revision, "rows_sha256": src.digest,
             "seed_public": src.seed_public, "isolated": src.isolated,
             "machine": src.machine, "packages": src.packages}
            for k, src in enumerate(sources)]
    rows = []
    for e in board.entries:
        info = e.source.methods.get(e.method)
        rows.append({
            "set": e.source.name, "tier": tiers[order[id(e.source)]][0], "method": e.label,
            "setting": e.setting, "uncertainty": e.level, "scenarios": e.n,
            "mean": _number(e.mean), "ci95": [_number(e.low), _number(e.high)],
            "fraction_of_u": _number(e.fraction_of_u), "paired_scenarios": e.paired_n,
            "diff_to_base": [_number(x) for x in e.diff] if e.paired_n else None,
            "unpaired": e.unpaired or None,
            "p_beats_base": _number(e.beats), "time_per_scenario_s": e.time_s,
            "training_seeds": info.training_seeds() if info and info.learned else None})
    across = []
    for g in board.seeded:
        st, pair = g.stats, g.pair
        across.append({
            "set": g.source.name, "tier": tiers[order[id(g.source)]][0], "method": g.label,
            "seed_methods": g.methods, "setting": g.setting, "uncertainty": g.level,
            "seeds": st.seeds, "scenarios": st.scenarios, "mean": _number(st.mean),
            "ci95": [_number(st.low), _number(st.high)], "iqm": _number(st.iqm),
            "iqm_ci95": [_number(st.iqm_low), _number(st.iqm_high)],
            "seed_means": {"lowest": _number(st.lowest), "highest": _number(st.highest),
                           "sd": _number(st.sd)},
            "fraction_of_u": _number(g.fraction_of_u),
            "diff_to_base": [_number(x) for x in (pair.mean, pair.low, pair.high)]
            if pair else None, "unpaired": g.unpaired or None,
            "p_seed_beats_base": _number(pair.beats) if pair else None,
            "p_beats_base": _number(g.beats), "time_per_scenario_s": g.time_s})
    return {"command": command, "base": board.base, "sets": sets, "rows": rows,
            "across_seeds": across}


def _write(out: Path, files: dict[str, bytes]) -> None:
    """The page's files as the folder `out`, whole: written in a folder beside it that then
    takes its name (an earlier page there is replaced once the new one is whole)."""
    target = Path(os.path.abspath(out))
    prepare_out_dir(target.parent)
    tmp = target.with_name(f".{target.name}.{os.getpid()}.new")
    old = target.with_name(f".{target.name}.{os.getpid()}.old")
    try:
        shutil.rmtree(tmp, ignore_errors=True)
        tmp.mkdir()
        with writing(tmp):
            for name, data in files.items():
                (tmp / name).write_bytes(data)
            had = target.exists()
            if had:
                os.rename(target, old)
            try:
                os.rename(tmp, target)
            except OSError:
                if had:                 # the earlier page stays as it was
                    os.rename(old, target)
                raise
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
        shutil.rmtree(old, ignore_errors=True)
