"""The results page's leaderboards: per (team setting, uncertainty level), every method of every
set with its mean and 95% interval, fraction of U, the paired difference method - base on the
same scenarios with its interval, P(method beats base), time per scenario and training seeds.

The statistics are `ata report`'s (`ata.results.rows`: the percentile bootstrap, 2000 resamples,
its fixed seed; ties count half). A method of one set is paired with the base of another only
where both cells ran in the same model revision (the world's code and settings), on the
scenarios both ran. A method's training seeds (``NAME seed S``) are each an entry too (their
pages, site.json), and together one row across seeds (`ata.site.seeds`), which is the row the
leaderboards show.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ata.core.errors import MissionError
from ata.published.sets import cell_name
from ata.results.report import Cell, Paired
from ata.results.rows import (RESAMPLES, Results, beat_probability, bootstrap_ci, level_key,
                              nanmean, paired)
from ata.results.seeds import seeded, split_seed
from ata.site.seeds import SeedEntry, build_seed_entries
from ata.site.sources import Source

DEFAULT_BASE = "greedy"
NAN = float("nan")
COLUMNS = ("method", "setting", "uncertainty", "scenario", "seed", "score", "upper_bound",
           "fraction_of_u", "classified_share", "reallocations")
"""The columns the merged rows of the figures keep."""


@dataclass
class Entry:
    """One method of one set at one (setting, level): a row of a leaderboard."""

    source: Source
    method: str
    label: str            # the method's name on the page (the set's name added on a clash)
    setting: str
    level: str
    n: int
    mean: float
    low: float
    high: float
    fraction_of_u: float
    classified_share: float
    reallocations: float
    time_s: float | None
    diff: tuple[float, float, float] = (NAN, NAN, NAN)     # method - base: mean, low, high
    paired_n: int = 0
    beats: float = NAN                                    # P(method beats base)
    unpaired: str = ""                                    # why no pairs, where none
    seed_of: str = ""             # the method whose training seed this is (NAME seed S), if any

    @property
    def cell(self) -> str:
        return cell_name(self.setting, self.level)


@dataclass
class Board:
    base: str             # the base's label
    entries: list[Entry]
    settings: list[str]
    levels: list[str]
    seeded: list[SeedEntry] = field(default_factory=list)
    """Each method with training seeds as one row per cell (`ata.site.seeds`)."""

    def table(self, setting: str, level: str) -> list[Entry]:
        return [e for e in self.entries if e.setting == setting and e.level == level]

    def seed_table(self, setting: str, level: str) -> list[SeedEntry]:
        return [e for e in self.seeded if e.setting == setting and e.level == level]

    def groups(self) -> list[tuple[str, str]]:
        return [(s, lv) for s in self.settings for lv in self.levels if self.table(s, lv)]


def labels(sources: list[Source]) -> dict[tuple[int, str], str]:
    """(source index, method) -> its name on the page: the method's own, with ' [SET]' added
    where an earlier set has a method of that name (before a training seed's ' seed S', so that
    the set's seeds stay one method's: ``NAME [SET] seed S``)."""
    out, taken = {}, set()
    for k, src in enumerate(sources):
        for method in src.results.methods:
            label = src.results.label(method)
            if label in taken:
                name, seed = split_seed(label)
                label = f"{name} [{src.name}]" + (f" seed {seed}" if seed is not None else "")
            taken.add(label)
            out[(k, method)] = label
    return out


def build_board(sources: list[Source], base: str | None = None,
                resamples: int = RESAMPLES) -> Board:
    """Every (set, method, setting, level) as an Entry, paired with the base: the method named
    `base` (its label, or its name) in the first set that has it; default greedy, else the
    first method of the first set."""
    names = labels(sources)
    where = [(k, m) for (k, m), label in names.items() if base in (label, m)] if base else \
        [(k, m) for (k, m) in names if m == DEFAULT_BASE] or [next(iter(names))]
    if not where:
        raise MissionError("--base", None, f"no method {base!r} in the sets; methods: "
                           + ", ".join(dict.fromkeys(names.values())))
    bk, bm = where[0]
    bsrc = sources[bk]
    entries = []
    settings = sorted({s for src in sources for s in src.results.settings})
    levels = sorted({lv for src in sources for lv in src.results.levels}, key=level_key)
    seed_of = [{m: g for g, ms in seeded(src.results.methods).items() for m in ms}
               for src in sources]
    for setting in settings:
        for level in levels:
            cell = cell_name(setting, level)
            bsel = bsrc.results.select(bm, setting, level)
            bmodel = bsrc.methods[bm].cells.get(cell, {}).get("model") if bm in bsrc.methods \
                else None
            for k, src in enumerate(sources):
                for method in src.results.methods:
                    sel = src.results.select(method, setting, level)
                    if not sel.any():
                        continue
                    entry = _entry(src, method, names[(k, method)], setting, level, sel,
                                   resamples)
                    entry.seed_of = seed_of[k].get(method, "")
                    info = src.methods.get(method)
                    model = info.cells.get(cell, {}).get("model") if info else None
                    if (k, method) == (bk, bm):
                        entry.unpaired = "the base"
                    elif not bsel.any():
                        entry.unpaired = "no rows of the base in this cell"
                    elif not model or model != bmodel:
                        entry.unpaired = "another model revision than the base's"
                    else:
                        mine, theirs = paired(src.results, sel, bsrc.results, bsel)
                        entry.paired_n = int(mine.size)
                        if mine.size:
                            entry.diff = bootstrap_ci(mine - theirs, resamples)
                            entry.beats = beat_probability(mine, theirs)
                        else:
                            entry.unpaired = "no scenario in common with the base"
                    entries.append(entry)
    return Board(names[(bk, bm)], entries, settings, levels,
                 build_seed_entries(sources, (bk, bm), settings, levels, resamples))


def _entry(src: Source, method: str, label: str, setting: str, level: str, sel: np.ndarray,
           resamples: int) -> Entry:
    c = src.results.columns
    realloc = c.get("reallocations")
    info = src.methods.get(method)
    time_s = info.cells.get(cell_name(setting, level), {}).get("time_s") if info else None
    return Entry(src, method, label, setting, level, int(sel.sum()),
                 *bootstrap_ci(c["score"][sel], resamples),
                 fraction_of_u=nanmean(c["fraction_of_u"][sel]),
                 classified_share=nanmean(c["classified_share"][sel]),
                 reallocations=nanmean(realloc[sel]) if realloc is not None else NAN,
                 time_s=None if time_s is None or math.isnan(time_s) else float(time_s))


def merged(sources: list[Source]) -> Results:
    """Every set's rows as one evaluation, each method under its page label (for the figures)."""
    names = labels(sources)
    parts: dict[str, list[np.ndarray]] = {c: [] for c in COLUMNS}
    for k, src in enumerate(sources):
        cols = src.results.columns
        size = len(cols["method"])
        for c in COLUMNS:
            if c == "method":
                parts[c].append(np.array([names[(k, m)] for m in cols["method"]], dtype=object))
            else:
                parts[c].append(cols[c] if c in cols else np.full(size, NAN))
    columns = {c: np.concatenate(v) for c, v in parts.items()}
    return Results(columns=columns, methods=list(dict.fromkeys(names.values())),
                   settings=sorted(set(columns["setting"])),
                   levels=sorted(set(columns["uncertainty"]), key=level_key))


def report_cells(board: Board) -> list[Cell]:
    """The entries as `ata.results.report.Cell`s, for `ata report`'s figures."""
    return [Cell(method=e.label, setting=e.setting, level=e.level, n=e.n, mean=e.mean,
                 low=e.low, high=e.high, fraction_of_u=e.fraction_of_u,
                 classified_share=e.classified_share, reallocations=e.reallocations,
                 beats=NAN) for e in board.entries]


def report_paired(board: Board) -> list[Paired]:
    """The paired differences method - base, for `ata report`'s fig_paired."""
    return [Paired(e.label, board.base, e.setting, e.level, e.paired_n, *e.diff)
            for e in board.entries if e.paired_n]
