"""`ata compare`: paired differences on any results column, the scenarios a paired CI needs to
clear 0, and column means, of one result folder or two.

By default (`leaderboards`) one compact table per (setting, level) against one base method
(greedy unless named): every method's mean with its 95% interval, its paired difference to the
base with its interval, and P(beats base), all on the same scenarios, those that the base and
every method of the first folder ran (a second folder's methods are read on those). The full
matrix of pairings (`compare`: each method of A against the same method of B, or against each
`base`) is behind ``--full``.

One folder (an evaluation): each method against a base method, on the scenarios both ran. Two
folders (evaluations or `ata run` folders): each method of A against the same method of B (or
against `base` of B), on the scenarios both ran; two folders of one method and one cell each
(two runs) are compared whatever their names. Pairs are matched by (seed, scenario id) within
the same (setting, uncertainty level).

Differences are A - B, the mean over the paired scenarios with its 95% percentile-bootstrap
interval (`results.bootstrap_ci`, as `ata report` computes its own). The power estimate follows
the normal approximation: a 95% CI of the paired difference of a column clears 0 from about
n = (1.96 sd / d)^2 scenarios, sd the standard deviation of the paired differences and d the
true difference, estimated by the mean paired difference of `expected_score` (the score without
the noise of the classification outcomes) where the results have it, else of the column itself.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Iterator

import numpy as np

from ata.core.errors import MissionError
from ata.results.report import md_table
from ata.results.rows import (BOOTSTRAP_SEED, RESAMPLES, Results, beat_probability,
                              bootstrap_ci, check_column, nanmean, paired)

BASE = "greedy"
"""The default base of a one-folder comparison, else the first method."""
EXPECTED = "expected_score"
"""The column whose paired mean estimates the true difference in the power estimate."""
Z = 1.959964


@dataclass
class Table:
    """One (setting, level)'s table, as text: `what` it shows, its header and rows."""

    setting: str
    level: str
    what: str
    header: list[str]
    rows: list[list[str]]
    sections: list[int] = field(default_factory=list)
    """Rows after which a rule is drawn (the end of the first folder's methods)."""

    @property
    def title(self) -> str:
        return f"setting {self.setting}, {self.level} uncertainty: {self.what}"


def markdown(tables: list[Table]) -> str:
    """The tables in Markdown: those of one kind (the same `what` and header) as one table
    with a column for the (setting, level), under a heading."""

    kinds: dict[tuple[str, tuple[str, ...]], list[Table]] = {}
    for t in tables:
        kinds.setdefault((t.what, tuple(t.header)), []).append(t)
    lines: list[str] = []
    for (what, header), group in kinds.items():
        rows = [[t.rows[k][0], f"({t.setting}) {t.level}", *t.rows[k][1:]]
                for t in group for k in range(len(t.rows))]
        lines += [f"### {what}", "", *md_table([header[0], "cell", *header[1:]], rows), ""]
    return "\n".join(lines)


@dataclass
class Pairing:
    """Method `a` of the first results against method `b` of the second (or the same) results,
    on the scenarios both ran at each shared (setting, level); `label` names it in tables."""

    a: str
    b: str
    label: str


def pairings(a: Results, b: Results | None = None, base: str | None = None,
             methods: list[str] | None = None) -> list[Pairing]:
    """What a comparison pairs: with one folder, each method (of `methods`, if given) against
    `base` (default greedy, else the first method); with two, each method of A against the same
    method of B, or against `base` of B."""
    wanted = [m for m in a.methods if methods is None or m in methods]
    for m in methods or []:
        if m not in a.methods:
            raise MissionError("--methods", None, f"no method {m!r} in the results; methods: "
                               + ", ".join(a.methods))
    if b is None:
        base = base or (BASE if BASE in a.methods else a.methods[0])
        if base not in a.methods:
            raise MissionError("--base", None, f"no method {base!r} in the results; methods: "
                               + ", ".join(a.methods))
        return [Pairing(m, base, a.label(m)) for m in wanted if m != base]
    if base is not None:
        if base not in b.methods:
            raise MissionError("--base", None, f"no method {base!r} in the second folder's "
                               "results; methods: " + ", ".join(b.methods))
        return [Pairing(m, base, a.label(m) if m == base else f"{a.label(m)} - {b.label(base)}")
                for m in wanted]
    if len(a.cells()) == 1 and len(b.cells()) == 1:
        ma, mb = a.methods[0], b.methods[0]
        return [Pairing(ma, mb, a.label(ma) if ma == mb else f"{a.label(ma)} - {b.label(mb)}")]
    found = [Pairing(m, m, a.label(m)) for m in wanted if m in b.methods]
    if not found:
        raise MissionError("", None, "no method of the first folder is in the second ("
                           + ", ".join(b.methods) + "); name the one to compare with: --base "
                           "METHOD")
    return found


@dataclass
class Pair:
    """The paired values of one pairing at one (setting, level)."""

    pairing: Pairing
    setting: str
    level: str
    a: Results
    b: Results
    sel_a: np.ndarray
    sel_b: np.ndarray

    def values(self, column: str) -> tuple[np.ndarray, np.ndarray]:
        return paired(self.a, self.sel_a, self.b, self.sel_b, column)


def pairs(a: Results, b: Results | None, found: list[Pairing]) -> Iterator[Pair]:
    """Every (pairing, setting, level) with paired scenarios, cell by cell in report order; two
    single-cell folders are paired across their cells."""
    other = a if b is None else b
    across = b is not None and len(a.cells()) == 1 and len(b.cells()) == 1
    cells = [(s, lv) for s in a.settings for lv in a.levels]
    for setting, level in cells:
        for p in found:
            sel_a = a.select(p.a, setting, level)
            cell_b = other.cells()[0][1:] if across else (setting, level)
            sel_b = other.select(p.b, *cell_b)
            if sel_a.any() and sel_b.any():
                # two runs at other settings or levels: the table says both, A's first
                pair = Pair(p, *(x if x == y else f"{x} - {y}"
                                 for x, y in zip((setting, level), cell_b)),
                            a, other, sel_a, sel_b)
                if pair.values("score")[0].size:
                    yield pair


def _digits(values: list[float]) -> int:
    """Decimals that show a table's numbers: 1 from 10 up, 2 from 1, else 3."""
    top = max((abs(v) for v in values if math.isfinite(v)), default=0.0)
    return 1 if top >= 10 else 2 if top >= 1 else 3


def _signed(x: float, digits: int) -> str:
    """x with its sign, rounded; no "-0.0" for a value that rounds to 0."""
    return f"{round(x, digits) + 0.0:+.{digits}f}"


def _groups(items: list[Pair]) -> dict[tuple[str, str], list[Pair]]:
    out: dict[tuple[str, str], list[Pair]] = {}
    for p in items:
        out.setdefault((p.setting, p.level), []).append(p)
    return out


def difference_tables(items: list[Pair], columns: list[str], versus: str,
                      resamples: int = RESAMPLES, seed: int = BOOTSTRAP_SEED) -> list[Table]:
    """A table per (setting, level): each pairing's paired scenarios, how many differ in the
    first column, and A - B of each column, mean [95% bootstrap CI]. `versus` says what is
    subtracted (in the titles)."""
    stats = {(id(p), c): bootstrap_ci(np.subtract(*p.values(c)), resamples, seed=seed)
             for p in items for c in columns}
    digits = {c: _digits([x for p in items for x in stats[(id(p), c)]]) for c in columns}
    out = []
    for (setting, level), group in _groups(items).items():
        rows = []
        for p in group:
            va, vb = p.values(columns[0])
            row = [p.pairing.label, str(va.size), str(int((va != vb).sum()))]
            for c in columns:
                d = digits[c]
                mean, low, high = (_signed(x, d) for x in stats[(id(p), c)])
                row.append(f"{mean} [{low}, {high}]")
            rows.append(row)
        header = ["method", "paired", f"differing in {columns[0]}"] + \
            [f"{c} difference [95% CI]" for c in columns]
        out.append(Table(setting, level, versus, header, rows))
    return out


def power_tables(items: list[Pair], column: str, versus: str) -> list[Table]:
    """A table per (setting, level): each pairing's paired difference of `column` and of the
    estimate of the true difference (`EXPECTED` where both folders have it, else `column`),
    mean ± 1.96 SE (sd over scenarios), and the scenarios a 95% CI of `column`'s difference
    needs to clear 0 at that estimate ("never" where the estimate is not above 0)."""
    out = []
    for (setting, level), group in _groups(items).items():
        truth = EXPECTED if all(EXPECTED in p.a.columns and EXPECTED in p.b.columns
                                for p in group) else column
        rows = []
        for p in group:
            d = np.subtract(*p.values(column))
            e = np.subtract(*p.values(truth))
            rows.append([p.pairing.label, str(d.size), _mean_se(d)]
                        + ([_mean_se(e)] if truth != column else []) + [_needed(d, e)])
        header = ["method", "paired", f"{column} difference ± 1.96 SE (sd)"] \
            + ([f"{truth} difference ± 1.96 SE (sd)"] if truth != column else []) \
            + [f"scenarios for a {column} CI above 0"]
        out.append(Table(setting, level, versus, header, rows))
    return out


def power_needed(drawn: np.ndarray, expected: np.ndarray) -> float:
    """(1.96 sd(drawn) / mean(expected))^2, the scenarios a 95% CI of the drawn paired
    difference needs to clear 0 if the true difference is the expected one; inf unless that is
    above 0."""
    mean = float(np.mean(expected))
    if mean <= 0 or drawn.size < 2:
        return math.inf
    return (Z * float(np.std(drawn, ddof=1)) / mean) ** 2


def _mean_se(d: np.ndarray) -> str:
    if d.size < 2:
        return f"{float(d.mean()):+.1f}"
    sd = float(np.std(d, ddof=1))
    return f"{float(d.mean()):+.1f} ± {Z * sd / math.sqrt(d.size):.1f} (sd {sd:.0f})"


def _needed(d: np.ndarray, e: np.ndarray) -> str:
    n = power_needed(d, e)
    return "never (estimate <= 0)" if math.isinf(n) else f"{n:.0f}"


def mean_tables(folders: list[tuple[str, Results]], columns: list[str],
                methods: list[str] | None = None) -> list[Table]:
    """A table per (setting, level): each method's rows and the mean of each column (with the
    folder it comes from, when there are two)."""
    cells: dict[tuple[str, str], list[list[str]]] = {}
    for name, res in folders:
        for column in columns:
            check_column(res, column, name, methods)
        for m, s, lv in res.cells():
            if methods is not None and m not in methods:
                continue
            sel = res.select(m, s, lv)
            means = [np.asarray(res.columns[c][sel], dtype=float) for c in columns]
            cells.setdefault((s, lv), []).append(
                [res.label(m)] + ([name] if len(folders) > 1 else []) + [str(int(sel.sum()))]
                + ["-" if not np.isfinite(v).any() else f"{nanmean(v):.3f}" for v in means])
    header = ["method"] + (["folder"] if len(folders) > 1 else []) + ["rows"] + \
        [f"{c}, mean" for c in columns]
    return [Table(s, lv, "column means", header, rows) for (s, lv), rows in cells.items()]


def compare(a: Results, b: Results | None, columns: list[str], *, base: str | None = None,
            methods: list[str] | None = None, power: bool = False,
            resamples: int = RESAMPLES) -> list[Table]:
    """`ata compare`'s tables: the paired differences of `columns` (or, with `power`, the
    scenarios each needs for its CI to clear 0)."""
    # the rows compared: the methods asked for and the one subtracted (all, without --methods)
    rows = None if methods is None else list(methods) + ([base] if base else [])
    for res, name in ((a, "the first folder"), (b, "the second folder")):
        if res is not None:
            for c in columns:
                check_column(res, c, name, rows)
    found = pairings(a, b, base, methods)
    items = list(pairs(a, b, found))
    if not items:
        if b is None and len({m for m, _, _ in a.cells()}) == 1:
            raise MissionError("", None, "this folder holds one method: give a second folder "
                               "to pair it with (ata compare RUN OTHER_RUN), or pair it with "
                               "the published rows (ata compare RUN published)")
        raise MissionError("", None, "no paired scenarios: the folders share no (seed, "
                           "scenario id) of a pair of methods at the same setting and level")
    if b is None:
        versus = f"method - {found[0].b}, paired"
    else:
        versus = f"A's method - B's {base}, paired" if base else "A - B, paired"
    if power:
        return [t for c in columns for t in power_tables(items, c, versus)]
    return difference_tables(items, columns, versus, resamples)


# -- the default: one compact table per cell against one base --------------------------------
@dataclass
class Entry:
    """A method of one of the folders as a leaderboard shows it; `tested`: of the first folder
    (the scenarios of the base and of every tested method are the cell's)."""

    res: Results
    method: str
    label: str
    tested: bool


def board_entries(a: Results, b: Results | None, methods: list[str] | None = None,
                  tags: tuple[str, str] = ("A", "B"),
                  b_methods: list[str] | None = None) -> list[Entry]:
    """The methods a leaderboard shows: A's (those of `methods`, if given), then B's (those of
    `b_methods`, if given); a name found in both folders is tagged with its folder's tag
    (``random (A)``)."""
    for m in methods or []:
        if m not in a.methods:
            raise MissionError("--methods", None, f"no method {m!r} in the results; methods: "
                               + ", ".join(a.methods))
    mine = [m for m in a.methods if methods is None or m in methods]
    theirs = [m for m in b.methods if b_methods is None or m in b_methods] \
        if b is not None else []
    both = set(mine) & set(theirs)

    def label(res: Results, m: str, tag: str) -> str:
        return f"{res.label(m)} ({tag})" if m in both else res.label(m)
    return [Entry(a, m, label(a, m, tags[0]), True) for m in mine] + \
        [Entry(b, m, label(b, m, tags[1]), False) for m in theirs]


def board_base(a: Results, b: Results | None, base: str | None,
               entries: list[Entry]) -> tuple[Entry, list[Entry]]:
    """The base of a leaderboard and the entries with it: `base` (of B, else of A), by default
    greedy (B's, else A's), else B's first method (A's first, with one folder)."""
    folders = [x for x in (b, a) if x is not None]
    if base is not None:
        where = next((x for x in folders if base in x.methods), None)
        if where is None:
            known = list(dict.fromkeys(m for x in folders for m in x.methods))
            raise MissionError("--base", None, f"no method {base!r} in the results; methods: "
                               + ", ".join(known))
        name = base
    else:
        where = next((x for x in folders if BASE in x.methods), folders[0])
        name = BASE if BASE in where.methods else where.methods[0]
    found = next((e for e in entries if e.res is where and e.method == name), None)
    if found is None:                      # left out by --methods: shown all the same
        found = Entry(where, name, where.label(name), where is a)
        entries = ([found] + entries) if where is a else entries + [found]
    return found, entries


def _keys(res: Results, sel: np.ndarray) -> dict[tuple[str, int], int]:
    """The rows `sel` selects by (seed, scenario id), in their order."""
    c = res.columns
    return {(str(s), int(i)): int(k) for k, s, i in
            zip(np.nonzero(sel)[0], c["seed"][sel], c["scenario"][sel])}


def _ci_digits(stats: list[tuple[float, float, float]]) -> int:
    """Decimals that show intervals: two significant digits of the narrowest half-width (0 to
    4: "+2.3 [+0.4, +4.1]", "-982 [-1099, -867]"), or by size where every interval is a
    point."""
    widths = [(h - lo) / 2 for _, lo, h in stats if math.isfinite(h - lo) and h > lo]
    if not widths:
        values = [x for s in stats for x in s]
        return _digits(values) if any(x != 0 for x in values) else 1
    return int(min(4, max(0, 1 - math.floor(math.log10(min(widths))))))


BEATS = "P(beats {})"
"""The header of a leaderboard's last column: the share of the paired scenarios where a method
scores more than the base, ties counting half."""


def leaderboards(a: Results, b: Results | None, columns: list[str], *,
                 base: str | None = None, methods: list[str] | None = None,
                 tags: tuple[str, str] = ("A", "B"), b_methods: list[str] | None = None,
                 resamples: int = RESAMPLES, seed: int = BOOTSTRAP_SEED) -> list[Table]:
    """`ata compare`'s default: a table per (setting, level) and column: every method of A (of
    `methods`, if given) and of B (of `b_methods`, if given) with its mean [95% CI], its paired
    difference method - base [95% CI] and P(beats base) (`board_base` chooses the base), on the
    scenarios that the base and every method of A ran there (a row with fewer says so in a
    column `n`). Two folders of one cell each are paired across their cells."""
    rows = None if methods is None else list(methods) + ([base] if base else [])
    for res, name in ((a, "the first folder"), (b, "the second folder")):
        if res is not None:
            for c in columns:
                check_column(res, c, name, rows if res is a else None)
    if b is None and len(a.methods) == 1:
        raise MissionError("", None, "this folder holds one method: give a second folder "
                           "to pair it with (ata compare RUN OTHER_RUN), or pair it with "
                           "the published rows (ata compare RUN published)")
    entries = board_entries(a, b, methods, tags, b_methods)
    ref, entries = board_base(a, b, base, entries)
    across = b is not None and len(a.cells()) == 1 and len(b.cells()) == 1
    out: list[Table] = []
    for setting, level in [(s, lv) for s in a.settings for lv in a.levels]:
        cell_b = b.cells()[0][1:] if across else (setting, level)

        def rows_of(e: Entry) -> dict[tuple[str, int], int]:
            return _keys(e.res, e.res.select(e.method, *((setting, level) if e.res is a
                                                         else cell_b)))
        ref_keys = rows_of(ref)
        # the scenarios of the cell: those the base and every other method of A ran (of B,
        # where A holds only the base)
        tested = [k for k in (rows_of(e) for e in entries if e.tested and e is not ref) if k] \
            or [k for k in (rows_of(e) for e in entries if e is not ref) if k]
        if not ref_keys or not tested:
            continue
        common = set(ref_keys).intersection(*tested)
        order = [k for k in ref_keys if k in common]          # the base's row order
        if not order:
            continue
        where = tuple(x if x == y else f"{x} - {y}" for x, y in zip((setting, level), cell_b))
        for column in columns:
            r_all = np.asarray(ref.res.columns[column], dtype=float)
            shown, sections = [], []
            for e in entries:
                keys = ref_keys if e is ref else rows_of(e)
                use = [k for k in order if k in keys]
                if not use:
                    continue
                v = np.asarray(e.res.columns[column], dtype=float)[[keys[k] for k in use]]
                r = r_all[[ref_keys[k] for k in use]]
                mean = bootstrap_ci(v, resamples, seed=seed)
                diff = None if e is ref else bootstrap_ci(v - r, resamples, seed=seed)
                beats = None if e is ref else beat_probability(v, r)
                shown.append((e, len(use), mean, diff, beats))
                if e.tested:
                    sections = [len(shown) - 1]
            if len(shown) < 2:
                continue
            counts = {s[1] for s in shown}
            table_rows = []
            for e, n, (mean, low, high), diff, beats in shown:
                md = _ci_digits([(mean, low, high)])     # each interval to its own precision
                row = [e.label] + ([str(n)] if len(counts) > 1 else []) + \
                    [f"{mean:.{md}f} [{low:.{md}f}, {high:.{md}f}]"]
                if diff is None:
                    row += ["base", "-"]
                else:
                    dd = _ci_digits([diff])
                    row += [f"{_signed(diff[0], dd)} [{_signed(diff[1], dd)}, "
                            f"{_signed(diff[2], dd)}]", f"{beats:.2f}"]
                table_rows.append(row)
            header = ["method"] + (["n"] if len(counts) > 1 else []) + \
                [f"{column} [95% CI]", "method - base [95% CI]", BEATS.format("base")]
            what = (f"{column}, {len(order)} paired scenarios" if len(counts) == 1 else column)
            last = sections[0] if sections and sections[0] < len(shown) - 1 else None
            out.append(Table(*where, f"{what}, against {ref.label}", header, table_rows,
                             [] if last is None else [last]))
    if not out:
        raise MissionError("", None, "no paired scenarios: the folders share no (seed, "
                           f"scenario id) of a method and the base {ref.label} at the same "
                           "setting and level (give the same seed and scenarios, or --base)")
    return out
