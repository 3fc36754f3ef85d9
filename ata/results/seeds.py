"""A method across its training seeds: the mean with a two-level bootstrap interval (seeds, then
scenarios), the interquartile mean, the spread between seeds, and the probability that a seed of
one method beats a seed of another.

Which rows are one method's seeds: a method named ``LABEL seed S`` is training seed S of LABEL,
the names `ata eval` gives a folder of seeds' runs (`ata.training.folders.trained_methods`) and
the names a published set gives each seed's rows. A method of any other name is one seed.

All statistics are per (setting, level) cell, on the scenarios every seed of the method (and of
the other method of a pair) ran: the seeds of one method run the same held-out scenarios, so
scenarios are paired across seeds.

- **Two-level bootstrap** (`two_level`): a resample draws k of the k seeds with replacement and
  n of the n scenarios with replacement, and takes the mean over the drawn seeds of each drawn
  seed's mean over the drawn scenarios. The scenario draw is one for every drawn seed (and for
  both methods of a pair): the scenarios are the same for every seed, so their share of the
  variance is shared too; drawing them apart for each seed would shrink it k-fold. The interval
  is the percentile interval of the resampled means, so it counts the variance between seeds
  and the variance between scenarios (`tests/test_seeds_bootstrap.py` checks each alone and
  both together against their known widths). With one seed there is nothing to resample
  between seeds: the interval is the scenario-level bootstrap (`rows.bootstrap_ci`), labelled so.
- **IQM**: the interquartile mean of the per-seed means (the mean of the middle half of the
  seeds' means, after rliable, whose runs here are the seeds: a seed that trained badly moves
  it less than the mean), with its interval from the same resamples.
- **Spread**: the lowest and highest per-seed mean, and their standard deviation.
- **P(a seed of A beats a seed of B)**: over every pair (seed i of A, seed j of B), whether
  A_i's mean over the paired scenarios is above B_j's, ties counting half (rliable's probability
  of improvement with the cell as its one task; the Mann-Whitney U over the seeds' means, divided
  by kA kB).

Deterministic: the draws come from a fixed seed (`rows.BOOTSTRAP_SEED`). Vectorised: a block of
resamples draws its scenario counts as one multinomial matrix (resamples x scenarios), so each
resample's per-seed means are one matrix product.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass

import numpy as np

from ata.results.rows import BOOTSTRAP_SEED, RESAMPLES, Results, bootstrap_ci

SEED_NAME = re.compile(r"^(?P<label>.+) seed (?P<seed>\d+)$")
BLOCK = 1 << 22
"""Scenario counts drawn at once (resamples x scenarios, 32 MiB)."""


def split_seed(method: str) -> tuple[str, int | None]:
    """(label, training seed) of a method's name: ``("mine", 2)`` for ``mine seed 2``, the name
    and None for any other."""
    m = SEED_NAME.match(method)
    return (m["label"], int(m["seed"])) if m else (method, None)


def plain_methods(methods: list[str]) -> list[str]:
    """The methods that are not one training seed of a method (``NAME seed S``), in order."""
    return [m for m in methods if split_seed(m)[1] is None]


def seed_groups(methods: list[str]) -> dict[str, list[str]]:
    """Each label's methods (its seeds' names), labels in the order first met, seeds in order.
    A method ``X seed S`` groups under X; a plain ``X`` beside them stays apart (as ``X``): it
    is another run (the default weights), not one more seed."""
    groups: dict[str, list[str]] = {}
    for m in methods:
        label, seed = split_seed(m)
        groups.setdefault(label if seed is not None else f"\0{m}", []).append(m)
    out = {}
    for key, members in groups.items():
        if key.startswith("\0"):
            key = key[1:]
            if key in groups:            # "X" beside "X seed S": keep both, apart
                key = f"{key} (one run)"
        out[key] = sorted(members, key=lambda m: split_seed(m)[1] or 0)
    return out


def seeded(methods: list[str]) -> dict[str, list[str]]:
    """The methods with rows from training seeds: NAME -> its seeds' names (``NAME seed S``),
    in seed order (a plain NAME beside them is not one of them)."""
    return {split_seed(ms[0])[0]: ms for ms in seed_groups(methods).values()
            if split_seed(ms[0])[1] is not None}


def has_seeds(res: Results) -> bool:
    """Whether some method of the results has rows from several training seeds."""
    return any(len(v) > 1 for v in seed_groups(res.methods).values())


def seed_matrix(res: Results, methods: list[str], setting: str, level: str,
                column: str = "score", also: list[tuple[Results, list[str]]] = ()
                ) -> list[np.ndarray]:
    """The (seeds x scenarios) matrix of `column` of each list of methods (`methods` of `res`,
    then each of `also`), on the (seed, scenario id) keys every one of them ran at the cell, in
    one order."""
    lists = [(res, methods), *also]
    keyed = []
    for r, ms in lists:
        for m in ms:
            sel = r.select(m, setting, level)
            c = r.columns
            keyed.append({(str(s), int(i)): float(v) for s, i, v in
                          zip(c["seed"][sel], c["scenario"][sel], c[column][sel])})
    common = sorted(set.intersection(*(set(k) for k in keyed))) if keyed else []
    out, at = [], 0
    for _, ms in lists:
        out.append(np.array([[keyed[at + k][key] for key in common] for k in range(len(ms))],
                            dtype=float).reshape(len(ms), len(common)))
        at += len(ms)
    return out


def iqm(values: np.ndarray, axis: int = -1) -> np.ndarray | float:
    """The interquartile mean along `axis`: the mean of the middle half (rliable's: the
    floor(n / 4) lowest and highest values left out; all of 1 to 3 values)."""
    v = np.sort(np.asarray(values, dtype=float), axis=axis)
    n = v.shape[axis]
    cut = n // 4
    out = np.take(v, np.arange(cut, n - cut), axis=axis).mean(axis=axis)
    return float(out) if np.ndim(out) == 0 else out


def _draws(gen: np.random.Generator, resamples: int, n: int, ks: list[int]
           ) -> list[tuple[np.ndarray, list[np.ndarray]]]:
    """Blocks of (scenario counts (b x n), the seeds drawn for each of `ks` (b x k each))."""
    block = max(1, BLOCK // max(n, 1))
    out = []
    for start in range(0, resamples, block):
        b = min(block, resamples - start)
        counts = gen.multinomial(n, np.full(n, 1.0 / n), size=b)
        out.append((counts, [gen.integers(0, k, size=(b, k)) for k in ks]))
    return out


def resampled_seed_means(scores: list[np.ndarray], resamples: int = RESAMPLES,
                         seed: int = BOOTSTRAP_SEED) -> list[np.ndarray]:
    """Two-level bootstrap of each (seeds x scenarios) matrix, on one scenario draw for all:
    per matrix, the (resamples x k) means of the drawn seeds over the drawn scenarios."""
    n = scores[0].shape[1]
    gen = np.random.default_rng(seed)
    parts: list[list[np.ndarray]] = [[] for _ in scores]
    for counts, picks in _draws(gen, resamples, n, [s.shape[0] for s in scores]):
        for k, (s, pick) in enumerate(zip(scores, picks)):
            means = counts @ s.T / n                       # (b x seeds): each seed's mean
            parts[k].append(np.take_along_axis(means, pick, axis=1))
    return [np.concatenate(p) for p in parts]


def _interval(boots: np.ndarray, level: float = 0.95) -> tuple[float, float]:
    low, high = np.quantile(boots, [(1.0 - level) / 2.0, (1.0 + level) / 2.0])
    return float(low), float(high)


def two_level(scores: np.ndarray, resamples: int = RESAMPLES, level: float = 0.95,
              seed: int = BOOTSTRAP_SEED) -> tuple[float, float, float]:
    """(mean, low, high) of a (seeds x scenarios) matrix: the mean over seeds of their means,
    and its percentile interval from the two-level bootstrap (seeds, then scenarios)."""
    scores = np.asarray(scores, dtype=float)
    if scores.size == 0:
        return math.nan, math.nan, math.nan
    boots = resampled_seed_means([scores], resamples, seed)[0].mean(axis=1)
    return (float(scores.mean()), *_interval(boots, level))


@dataclass
class AcrossSeeds:
    """One method (its seeds) at one (setting, level)."""

    label: str
    setting: str
    level: str
    seeds: int
    scenarios: int            # on which every seed ran
    mean: float
    low: float
    high: float
    iqm: float
    iqm_low: float
    iqm_high: float
    lowest: float             # the lowest per-seed mean
    highest: float
    sd: float                 # of the per-seed means (NaN for one seed)

    @property
    def two_level(self) -> bool:
        """Whether the interval counts seeds (else: scenarios alone, one seed)."""
        return self.seeds > 1


def across_seeds(scores: np.ndarray, label: str = "", setting: str = "", level: str = "",
                 resamples: int = RESAMPLES, seed: int = BOOTSTRAP_SEED) -> AcrossSeeds:
    """The across-seed statistics of a (seeds x scenarios) matrix."""
    scores = np.asarray(scores, dtype=float)
    k, n = scores.shape
    per_seed = scores.mean(axis=1)
    if k == 1:
        mean, low, high = bootstrap_ci(scores[0], resamples, seed=seed)
        ilow, ihigh = low, high
    else:
        boots = resampled_seed_means([scores], resamples, seed)[0]
        mean = float(per_seed.mean())
        low, high = _interval(boots.mean(axis=1))
        ilow, ihigh = _interval(iqm(boots, axis=1))
    return AcrossSeeds(label, setting, level, k, n, mean, low, high, iqm(per_seed), ilow, ihigh,
                       float(per_seed.min()), float(per_seed.max()),
                       float(per_seed.std(ddof=1)) if k > 1 else math.nan)


def beat_probability(a: np.ndarray, b: np.ndarray) -> float:
    """P(a seed of A beats a seed of B): the share of (i, j) with A_i's mean above B_j's over
    the paired scenarios (the matrices' columns), ties counting half."""
    ma, mb = np.asarray(a, float).mean(axis=1), np.asarray(b, float).mean(axis=1)
    if not ma.size or not mb.size:
        return math.nan
    gt = ma[:, None] > mb[None, :]
    eq = ma[:, None] == mb[None, :]
    return float(np.mean(gt + 0.5 * eq))


@dataclass
class PairAcross:
    """A - B across both methods' seeds at one (setting, level)."""

    a: str
    b: str
    setting: str
    level: str
    seeds_a: int
    seeds_b: int
    scenarios: int
    mean: float
    low: float
    high: float
    beats: float              # P(a seed of A beats a seed of B)

    @property
    def two_level(self) -> bool:
        return self.seeds_a > 1 or self.seeds_b > 1


def pair_across(a: np.ndarray, b: np.ndarray, label_a: str = "", label_b: str = "",
                setting: str = "", level: str = "", resamples: int = RESAMPLES,
                seed: int = BOOTSTRAP_SEED) -> PairAcross:
    """A - B of two (seeds x scenarios) matrices on the same scenarios: the difference of their
    means over seeds with its two-level interval (each method's seeds drawn apart, one scenario
    draw for both: the pairing kept), or, one seed each, the scenario-level paired bootstrap."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    mean = float(a.mean(axis=1).mean() - b.mean(axis=1).mean())
    if a.shape[0] == 1 and b.shape[0] == 1:
        mean, low, high = bootstrap_ci(a[0] - b[0], resamples, seed=seed)
    else:
        ra, rb = resampled_seed_means([a, b], resamples, seed)
        low, high = _interval(ra.mean(axis=1) - rb.mean(axis=1))
    return PairAcross(label_a, label_b, setting, level, a.shape[0], b.shape[0], a.shape[1],
                      mean, low, high, beat_probability(a, b))


# -- tables -------------------------------------------------------------------------------------
@dataclass
class SeedTable:
    """One (setting, level)'s table as text (the shape of `ata.results.compare.Table`)."""

    setting: str
    level: str
    what: str
    header: list[str]
    rows: list[list[str]]

    @property
    def title(self) -> str:
        return f"setting {self.setting}, {self.level} uncertainty: {self.what}"


SUMMARY_WHAT = "across training seeds"
PAIR_WHAT = "A - B across training seeds"
SUMMARY_HEADER = ["method", "seeds", "scenarios", "mean [95% CI]", "interval", "IQM",
                  "spread of seed means"]
PAIR_HEADER = ["A - B", "seeds", "scenarios", "difference [95% CI]", "interval",
               "P(seed of A beats seed of B)"]


def interval_kind(two: bool) -> str:
    return "seeds, scenarios" if two else "scenarios (1 seed)"


def seeds_text(k: int) -> str:
    return f"{k} seed" + ("s" if k != 1 else "")


def summary_row(s: AcrossSeeds) -> list[str]:
    spread = "-" if s.seeds == 1 else \
        f"{s.lowest:.1f} to {s.highest:.1f} (sd {s.sd:.1f})"
    return [s.label, seeds_text(s.seeds), str(s.scenarios),
            f"{s.mean:.1f} [{s.low:.1f}, {s.high:.1f}]", interval_kind(s.two_level),
            f"{s.iqm:.1f}", spread]


def pair_row(p: PairAcross) -> list[str]:
    return [f"{p.a} - {p.b}", f"{p.seeds_a} / {p.seeds_b}", str(p.scenarios),
            f"{p.mean:+.1f} [{p.low:+.1f}, {p.high:+.1f}]", interval_kind(p.two_level),
            f"{p.beats:.2f}"]


def _group_of(groups: dict[str, list[str]], method: str | None) -> str | None:
    """The group a pair's name means: the label of a method's seeds where one is so named (beside
    ``X seed S``, ``X`` means X's seeds; its plain run is ``X (one run)``), else the group
    holding that method."""
    if method in groups:
        return method
    return next((label for label, members in groups.items() if method in members), None)


def seed_tables(res: Results, reference: str | None = None, resamples: int = RESAMPLES,
                column: str = "score") -> list[SeedTable]:
    """`ata report`'s across-seed tables, per (setting, level): every method (its seeds
    grouped) with its mean, two-level interval, IQM and spread; then the reference's label
    (default: the first) against every other, A - B and P(a seed of A beats a seed of B)."""
    groups = seed_groups(res.methods)
    ref = _group_of(groups, reference) or next(iter(groups))   # a name of no group: the first
    out = []
    for setting in res.settings:
        for level in res.levels:
            here = {g: [m for m in ms if res.select(m, setting, level).any()]
                    for g, ms in groups.items()}
            here = {g: ms for g, ms in here.items() if ms}
            if not here:
                continue
            rows = []
            for g, ms in here.items():
                scores = seed_matrix(res, ms, setting, level, column)[0]
                if scores.shape[1]:
                    rows.append(summary_row(across_seeds(scores, g, setting, level,
                                                         resamples)))
            out.append(SeedTable(setting, level, SUMMARY_WHAT, list(SUMMARY_HEADER), rows))
            if ref not in here:
                continue
            pairs = [_pair(res, here[ref], ref, res, ms, g, setting, level, resamples, column)
                     for g, ms in here.items() if g != ref]
            rows = [pair_row(p) for p in pairs if p is not None]
            if rows:
                out.append(SeedTable(setting, level, PAIR_WHAT, list(PAIR_HEADER), rows))
    return out


def _pair(ra: Results, ma: list[str], la: str, rb: Results, mb: list[str], lb: str,
          setting: str, level: str, resamples: int, column: str) -> PairAcross | None:
    a, b = seed_matrix(ra, ma, setting, level, column, also=[(rb, mb)])
    if not a.shape[1]:
        return None
    return pair_across(a, b, la, lb, setting, level, resamples)


def published_tables(mine: Results, theirs: Results, bases: list[str],
                     resamples: int = RESAMPLES, column: str = "score",
                     methods: list[str] | None = None) -> list[SeedTable]:
    """`ata compare A published`'s across-seed tables, per (setting, level) of A: each of A's
    methods (its seeds grouped) and each published method of `bases` (its seeds grouped), with
    the mean, two-level interval, IQM and spread on the scenarios each ran; then every A method
    - every published one on the scenarios both ran, with P(a seed of A beats a seed of B)."""
    ours = {g: ms for g, ms in seed_groups(mine.methods).items()
            if methods is None or any(m in methods or g in methods for m in ms)}
    published = seed_groups([m for m in theirs.methods if m in bases
                             or split_seed(m)[0] in bases])
    out = []
    for setting in mine.settings:
        for level in mine.levels:
            rows, pairs = [], []
            for source, groups in ((mine, ours), (theirs, published)):
                for g, ms in groups.items():
                    ms = [m for m in ms if source.select(m, setting, level).any()]
                    scores = seed_matrix(source, ms, setting, level, column)[0] if ms else None
                    if scores is not None and scores.shape[1]:
                        name = g if source is mine else f"{g} (published)"
                        rows.append(summary_row(across_seeds(scores, name, setting, level,
                                                             resamples)))
            for g, ms in ours.items():
                for h, hs in published.items():
                    ms_here = [m for m in ms if mine.select(m, setting, level).any()]
                    hs_here = [m for m in hs if theirs.select(m, setting, level).any()]
                    if ms_here and hs_here:
                        p = _pair(mine, ms_here, g, theirs, hs_here, h, setting, level,
                                  resamples, column)
                        if p is not None:
                            pairs.append(pair_row(p))
            if pairs:
                out.append(SeedTable(setting, level, SUMMARY_WHAT, list(SUMMARY_HEADER), rows))
                out.append(SeedTable(setting, level, PAIR_WHAT + " (B published)",
                                     list(PAIR_HEADER), pairs))
    return out


def seed_markdown(res: Results, pairs: list[tuple[str, str]], resamples: int = RESAMPLES,
                  column: str = "score") -> list[str]:
    """The across-seed tables of docs/RESULTS.md (`ata report --markdown`), a column per
    (setting, level): each method (its seeds grouped) with its seeds, mean [two-level 95% CI],
    IQM and the range of its seeds' means; then the `pairs` (by method or label, each pair of
    labels once) A - B [two-level 95% CI] with P(a seed of A beats a seed of B)."""
    groups = seed_groups(res.methods)
    cells = [(s, lv) for s in res.settings for lv in res.levels]
    rows = []
    for g, ms in groups.items():
        row, most = [], 0
        for s, lv in cells:
            here = [m for m in ms if res.select(m, s, lv).any()]
            scores = seed_matrix(res, here, s, lv, column)[0] if here else np.zeros((0, 0))
            if not scores.size:
                row.append("-")
                continue
            x = across_seeds(scores, g, s, lv, resamples)
            most = max(most, x.seeds)
            spread = f"; {x.lowest:.1f} to {x.highest:.1f}" if x.seeds > 1 else ""
            row.append(f"{x.mean:.1f} [{x.low:.0f}, {x.high:.0f}]; IQM {x.iqm:.1f}{spread}")
        # a plain run beside seeds is labelled "X (one run)" already
        rows.append([g if g.endswith("(one run)") else f"{g} ({seeds_text(most)})", *row])
    header = [f"({s}) {lv}" for s, lv in cells]
    what = "" if column == "score" else f" of `{column}`"
    lines = [f"Across training seeds{what}: the mean over seeds [95% CI of a two-level "
             "bootstrap, seeds then scenarios; one seed: over scenarios], the IQM of the seeds' "
             "means and their range:", "", *_md(["method", *header], rows), ""]
    done, rows = set(), []
    for a, b in pairs:
        la, lb = _group_of(groups, a), _group_of(groups, b)
        if la is None or lb is None or (la, lb) in done or la == lb:
            continue
        done.add((la, lb))
        row = [f"{la} - {lb}"]
        for s, lv in cells:
            ma = [m for m in groups[la] if res.select(m, s, lv).any()]
            mb = [m for m in groups[lb] if res.select(m, s, lv).any()]
            p = _pair(res, ma, la, res, mb, lb, s, lv, resamples, column) if ma and mb else None
            row.append("-" if p is None else
                       f"{p.mean:+.1f} [{p.low:+.1f}, {p.high:+.1f}]; P {p.beats:.2f}")
        rows.append(row)
    lines += [f"Paired differences{what} across training seeds, A - B [two-level 95% CI]; P: "
              "the probability that a seed of A beats a seed of B:", "",
              *_md(["paired difference", *header], rows), ""]
    return lines


def _md(header: list[str], rows: list[list[str]]) -> list[str]:
    """A Markdown table (as `ata.results.report.md_table`, which imports this module)."""
    return (["| " + " | ".join(header) + " |",
             "|" + "|".join(["---"] + ["---:"] * (len(header) - 1)) + "|"]
            + ["| " + " | ".join(r) + " |" for r in rows])
