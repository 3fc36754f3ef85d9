"""The results page's rows across training seeds: per set, method with seeds and (team setting,
uncertainty level), the seeds as one row, with `ata report`'s statistics across seeds
(`ata.results.seeds`: the mean over the seeds with its two-level bootstrap interval, the IQM, the
spread of the seeds' means, method - base across seeds and P(a seed beats the base)).

A method's seeds are the methods of one set named ``NAME seed S`` (`ata.results.seeds`); a plain
``NAME`` beside them is another run (the default weights) and keeps its own row. The
leaderboards show a method's seeds as their row across seeds, and its page lists each seed.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ata.published.sets import cell_name
from ata.results.rows import RESAMPLES, nanmean
from ata.results.seeds import (AcrossSeeds, PairAcross, across_seeds, pair_across, seed_matrix,
                               seeded, split_seed)
from ata.site.sources import Source

NAN = float("nan")


@dataclass
class SeedEntry:
    """A method's training seeds in one set at one (setting, level): a leaderboard's row."""

    source: Source
    group: str             # the seeds' common name (NAME of ``NAME seed S``)
    label: str             # the row's name on the page
    methods: list[str]     # the seeds' method names, in seed order
    setting: str
    level: str
    stats: AcrossSeeds
    fraction_of_u: float
    time_s: float | None
    pair: PairAcross | None = None      # across seeds - the base
    beats: float = NAN                  # P(a seed beats the base on a scenario), ties half
    unpaired: str = ""                  # why no pairs, where none
    default: PairAcross | None = None   # across seeds - the plain NAME of the set, if any

    @property
    def cell(self) -> str:
        return cell_name(self.setting, self.level)

    @property
    def seeds(self) -> list[int]:
        return [split_seed(m)[1] for m in self.methods]


def seed_label(group: str, k: int) -> str:
    return f"{group} ({k} seed{'s' if k != 1 else ''})"


def build_seed_entries(sources: list[Source], base: tuple[int, str], settings: list[str],
                       levels: list[str], resamples: int = RESAMPLES) -> list[SeedEntry]:
    """Every (set, method with seeds, setting, level) as a SeedEntry, paired with the base
    (`base`: its set's index and method) on the scenarios every seed and the base ran, where
    every seed's cell ran in the base's model revision."""
    bk, bm = base
    bsrc = sources[bk]
    out, taken = [], set()
    for k, src in enumerate(sources):
        for group, methods in seeded(src.results.methods).items():
            label = seed_label(group, len(methods))
            if label in taken:
                label = f"{label} [{src.name}]"
            taken.add(label)
            for setting in settings:
                for level in levels:
                    entry = _entry(src, group, label, methods, setting, level, bsrc, bm,
                                   resamples)
                    if entry is not None:
                        out.append(entry)
    return out


def _model(src: Source, method: str, cell: str) -> str | None:
    info = src.methods.get(method)
    return info.cells.get(cell, {}).get("model") if info else None


def _entry(src: Source, group: str, label: str, methods: list[str], setting: str, level: str,
           bsrc: Source, bm: str, resamples: int) -> SeedEntry | None:
    res = src.results
    ran = [m for m in methods if res.select(m, setting, level).any()]
    if not ran:
        return None
    scores = seed_matrix(res, ran, setting, level)[0]
    if scores.shape[1] == 0:
        return None
    cell = cell_name(setting, level)
    sel = np.zeros(len(res.columns["method"]), bool)
    for m in ran:
        sel |= res.select(m, setting, level)
    times = [src.methods[m].cells.get(cell, {}).get("time_s") if m in src.methods else None
             for m in ran]
    time_s = None if any(t is None or not math.isfinite(t) for t in times) else \
        float(np.mean(times))
    entry = SeedEntry(src, group, label, ran, setting, level,
                      across_seeds(scores, label, setting, level, resamples),
                      nanmean(res.columns["fraction_of_u"][sel]), time_s)
    if not bsrc.results.select(bm, setting, level).any():
        entry.unpaired = "no rows of the base in this cell"
    elif any(_model(src, m, cell) != _model(bsrc, bm, cell) or not _model(src, m, cell)
             for m in ran):
        entry.unpaired = "another model revision than the base's"
    else:
        mine, theirs = seed_matrix(res, ran, setting, level, also=[(bsrc.results, [bm])])
        if mine.shape[1] == 0:
            entry.unpaired = "no scenario in common with the base"
        else:
            entry.pair = pair_across(mine, theirs, label, bm, setting, level, resamples)
            entry.beats = float(np.mean((mine > theirs) + 0.5 * (mine == theirs)))
    if group in res.methods and res.select(group, setting, level).any():
        mine, plain = seed_matrix(res, ran, setting, level, also=[(res, [group])])
        if mine.shape[1]:
            entry.default = pair_across(mine, plain, label, group, setting, level, resamples)
    return entry
