"""Result folders read back as columns, and the statistics every report and comparison uses.

A folder is an `ata eval` output folder (its results.csv has a row per method, setting,
uncertainty level and scenario) or an `ata run` folder (one method: its results.csv has a row per
scenario, and the method, setting, level and seed come from its mission.resolved.toml). Several
folders read together are one evaluation in which a (method, setting, uncertainty) cell of a
later folder replaces the same cell of an earlier one: rerun some cells into a folder of their
own, then read the old folder and the new one together.

Statistics: the mean with its percentile-bootstrap confidence interval (`bootstrap_ci`, a fixed
seed, so a report is the same every time), P(a beats b) (`beat_probability`), and the values of
two selections of rows paired by (seed, scenario id) (`paired`).
"""

from __future__ import annotations

import csv
import json
import math
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ata.core.errors import MissionError
from ata.core.kernel import REFERENCE_COLUMN
from ata.core.mission import UNCERTAINTY_LEVELS, loads_toml

RESAMPLES = 2000
BOOTSTRAP_BLOCK = 1 << 22
"""Resampled values drawn at once (32 MiB of indices)."""
BOOTSTRAP_SEED = 20240601
"""The bootstrap's fixed seed: a report is the same every time it is made."""

REQUIRED = ("method", "setting", "uncertainty", "scenario", "seed", "score", "upper_bound",
            "fraction_of_u", "classified_share")
"""The columns an evaluation's results.csv must have."""
RUN_REQUIRED = ("scenario", "score", "upper_bound", "fraction_of_u")
"""Those of an `ata run` folder's results.csv; the others come from its resolved mission."""
DEFINED = ("score", "upper_bound")
"""Numeric columns that every row defines: blank or NaN there is refused, as is an infinity in
any column. Another column may hold NaN where its value is undefined (``fraction_of_u`` where
U is 0, an ITA-MILP scenario that fell back): a report's means skip those, and `ata compare`
refuses a column it is asked to compute on that holds one."""
TEXT_COLUMNS = ("method", "setting", "uncertainty", "seed")
INT_COLUMNS = ("scenario",)
"""results.csv's columns of text and of integers; every other column holds numbers (blank: NaN).
The seed is kept as text: an integer, or the ``secret:`` hash of a secret one; rows pair on
it."""
Cell = tuple[str, str, str]
"""(method, setting, uncertainty level)."""


def bootstrap_ci(values: Any, resamples: int = RESAMPLES, level: float = 0.95,
                 seed: int = BOOTSTRAP_SEED) -> tuple[float, float, float]:
    """(mean, low, high): the mean and its percentile-bootstrap confidence interval.

    Draws `resamples` resamples of the values with replacement (a matrix, in blocks) and
    takes the (1 - level) / 2 and (1 + level) / 2 quantiles of their means. NaN for no values.
    """
    v = np.asarray(values, dtype=float).ravel()
    if v.size == 0:
        return float("nan"), float("nan"), float("nan")
    mean = float(v.mean())
    if v.size == 1:
        return mean, mean, mean
    gen = np.random.default_rng(seed)
    # in blocks of rows, so that memory stays bounded whatever `resamples` is; the generator
    # draws the same stream in blocks as in one matrix, so the interval does not change
    block = max(1, BOOTSTRAP_BLOCK // v.size)
    means = np.concatenate([v[gen.integers(0, v.size, size=(min(block, resamples - start),
                                                              v.size))].mean(axis=1)
                            for start in range(0, resamples, block)])
    low, high = np.quantile(means, [(1.0 - level) / 2.0, (1.0 + level) / 2.0])
    return mean, float(low), float(high)


def beat_probability(reference: Any, other: Any) -> float:
    """Share of pairs where reference > other; ties count half. NaN for no pairs."""
    r, o = np.asarray(reference, dtype=float), np.asarray(other, dtype=float)
    if r.size == 0:
        return float("nan")
    return float(np.mean((r > o) + 0.5 * (r == o)))


def nanmean(values: Any) -> float:
    """The mean of the finite values; NaN (without numpy's warning) when there are none."""
    v = np.asarray(values, dtype=float)
    v = v[np.isfinite(v)]
    return float(v.mean()) if v.size else float("nan")


def level_key(level: str) -> tuple[int, str]:
    order = list(UNCERTAINTY_LEVELS)
    return (order.index(level) if level in order else len(order), level)


@dataclass
class Results:
    """Result rows as columns, with the methods, settings and levels in report order.

    :param replaced: the cells a later folder replaced, in the order met.
    :param pairs: the (A, B) pairs that the suites of the folders' evaluations name
        (``[suite] pairs``), for the paired table of `ata report --markdown`.
    """

    columns: dict[str, np.ndarray]
    methods: list[str]
    settings: list[str]
    levels: list[str]
    replaced: list[Cell] = field(default_factory=list)
    pairs: list[tuple[str, str]] = field(default_factory=list)
    origin: list[str] = field(default_factory=list)
    """Where each row was read ("FILE line N"), for messages about one value."""
    _index: tuple = field(default=(), repr=False, compare=False)
    """The rows of each (method, setting, level), with the three columns they were read from:
    built at the first `select` and again whenever one of those columns is replaced."""

    def select(self, method: str, setting: str, level: str) -> np.ndarray:
        c = self.columns
        keys = (c["method"], c["setting"], c["uncertainty"])
        if not self._index or any(a is not b for a, b in zip(self._index[0], keys)):
            groups: dict[tuple, list[int]] = {}
            for i, key in enumerate(zip(*(k.tolist() for k in keys))):
                groups.setdefault(key, []).append(i)
            self._index = (keys, {k: np.asarray(v) for k, v in groups.items()})
        mask = np.zeros(len(keys[0]), dtype=bool)
        rows = self._index[1].get((method, setting, level))
        if rows is not None:
            mask[rows] = True
        return mask

    def is_reference(self, method: str) -> bool:
        """Whether the method's rows come from a mission with a reference reconstructor (the
        kernel's ``reference`` column): a yardstick reading the true state, not a method."""
        ref = self.columns.get(REFERENCE_COLUMN)
        return ref is not None and bool(np.any(ref[self.columns["method"] == method] == 1))

    def label(self, method: str) -> str:
        """The method's name in tables: "(reference)" added to a reference's."""
        return f"{method} (reference)" if self.is_reference(method) else method

    def cells(self) -> list[Cell]:
        """Every (method, setting, level) that has rows, methods first, in report order."""
        return [(m, s, lv) for m in self.methods for s in self.settings for lv in self.levels
                if self.select(m, s, lv).any()]


ORIGIN = "\0origin"
"""The key under which a parsed row keeps where it was read (no column can be named so)."""


class _NotFinite(ValueError):
    """A score that is NaN, infinite or blank: no mean or paired difference can use it."""


def _parse(column: str, text: str) -> Any:
    """One cell of results.csv as its column's type; ValueError when it is not one."""
    if column == "seed":
        return text if text.startswith("secret:") else str(int(text))
    if column in TEXT_COLUMNS:
        return text
    if column in INT_COLUMNS:
        return int(text)
    value = float(text) if text != "" else math.nan
    if math.isinf(value) or (column in DEFINED and not math.isfinite(value)):
        raise _NotFinite(text)
    return value


def _run_cell(folder: Path) -> dict[str, Any]:
    """The method, setting, level and seed of an `ata run` folder, from its resolved mission."""
    path = folder / "mission.resolved.toml"
    try:
        mission = loads_toml(path.read_text(encoding="utf-8"))["mission"]
        return {"method": str(mission["name"]), "setting": str(mission["setting"]),
                "uncertainty": str(mission["uncertainty"]), "seed": str(mission["seed"])}
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError, KeyError, TypeError,
            ValueError) as exc:
        raise MissionError("", None, f"cannot read the run's mission (name, setting, "
                           f"uncertainty, seed): {exc}", file=str(path)) from None


def _read_one(path: str | Path) -> tuple[list[dict[str, Any]], list[str], list[tuple[str, str]]]:
    """The rows of one results.csv, each cell parsed as its column's type, its columns, and the
    pairs its eval.json's suites name; one MissionError naming the file and line for a file cut
    short, garbled, or of another row count than its eval.json."""
    given = path = Path(path)
    if path.is_dir():
        path = path / "results.csv"
    if not path.is_file():
        raise MissionError("", None, "no such results file or training log: this reads an "
                           "evaluation folder (results.csv, from `ata eval`) or a run folder "
                           "(`ata run`); `ata report` also a training run folder (log.csv, "
                           "from `ata train`)", file=str(given))
    # utf-8-sig: a spreadsheet saves a byte-order mark before the first column's name (the
    # csv module reads its CRLF line ends as they are)
    with open(path, newline="", encoding="utf-8-sig") as f:
        reader = csv.DictReader(f)
        rows = list(reader)
        header = list(reader.fieldnames or [])
    run = None
    if "method" not in header and (path.parent / "mission.resolved.toml").is_file():
        run = _run_cell(path.parent)                      # a plain `ata run` folder
    missing = [c for c in (RUN_REQUIRED if run else REQUIRED) if c not in header]
    if missing:
        raise MissionError("", None, f"not an evaluation's results: no column {missing[0]!r}",
                           file=str(path))
    if not rows:
        raise MissionError("", None, "has no rows", file=str(path))
    parsed = []
    for line, row in enumerate(rows, start=2):
        if None in row or any(v is None for v in row.values()):
            raise MissionError("", None, f"line {line} has {'more' if None in row else 'fewer'} "
                               f"fields than the header: the file is cut short or garbled",
                               file=str(path))
        typed = dict(run or {})
        for column, text in row.items():
            try:
                typed[column] = _parse(column, text)
            except ValueError as exc:
                what = "a finite number" if isinstance(exc, _NotFinite) else "a number"
                raise MissionError("", None, f"line {line}: {column} is {text!r}, not {what}",
                                   file=str(path)) from None
        share = typed.get("fraction_of_u")
        if isinstance(share, float) and math.isnan(share) and typed.get("upper_bound", 0) > 0:
            raise MissionError("", None, f"line {line}: fraction_of_u is "
                               f"{row['fraction_of_u']!r}, not a finite number (U is "
                               f"{typed['upper_bound']:g})", file=str(path))
        typed[ORIGIN] = f"{path} line {line}"
        parsed.append(typed)
    if run:
        header = [c for c in REQUIRED if c not in header] + header
    return parsed, header, _check_eval_json(path, len(rows))


def _check_eval_json(path: Path, rows: int) -> list[tuple[str, str]]:
    """The pairs eval.json's suites name; an error when it plans another number of rows."""
    meta = path.with_name("eval.json")
    if not meta.is_file():
        return []
    try:
        data = json.loads(meta.read_text(encoding="utf-8"))
        planned = data.get("rows")
    except (json.JSONDecodeError, AttributeError, UnicodeDecodeError):
        return []
    if isinstance(planned, int) and planned != rows:
        raise MissionError("", None, f"holds {rows} rows where eval.json says {planned}: the "
                           "file is incomplete or was changed", file=str(path))
    pairs = []
    for suite in data.get("suites") or []:
        head = (suite.get("content") or {}).get("suite") if isinstance(suite, dict) else None
        for pair in (head or {}).get("pairs") or []:
            if isinstance(pair, list) and len(pair) == 2 and tuple(pair) not in pairs:
                pairs.append((str(pair[0]), str(pair[1])))
    return pairs


def read_results(path: str | Path | list) -> Results:
    """Read result folders (or results.csv files) as one evaluation: methods keep their order of
    first appearance; a (method, setting, uncertainty) cell of a later folder replaces the same
    cell of an earlier one, in its place. A (method, setting, level, scenario) found twice in
    one folder, or a folder named twice, is an error."""
    paths = [Path(p) for p in path] if isinstance(path, (list, tuple)) else [Path(path)]
    named: dict[Path, Path] = {}
    cells: dict[Cell, list[dict[str, Any]]] = {}
    header: list[str] = []
    replaced: list[Cell] = []
    pairs: list[tuple[str, str]] = []
    for p in paths:
        if p.resolve() in named:
            raise MissionError("", None, "is named twice", file=str(p))
        named[p.resolve()] = p
        rows, cols, more = _read_one(p)
        header += [c for c in cols if c not in header]
        pairs += [x for x in more if x not in pairs]
        keys = [(r["method"], r["setting"], r["uncertainty"], r["scenario"]) for r in rows]
        if len(set(keys)) != len(keys):
            raise MissionError("", None, "a (method, setting, uncertainty, scenario) appears "
                               "twice", file=str(p))
        mine: dict[Cell, list[dict[str, Any]]] = {}
        for r in rows:
            mine.setdefault((r["method"], r["setting"], r["uncertainty"]), []).append(r)
        for cell, block in mine.items():
            if cell in cells:
                replaced.append(cell)
            cells[cell] = block          # a dict keeps a replaced key in its first place
    rows = [r for block in cells.values() for r in block]
    cols: dict[str, np.ndarray] = {}
    for name in header:
        # a column that one of the files read together lacks is blank (NaN) in its rows
        raw = [r.get(name, math.nan) for r in rows]
        cols[name] = np.array(raw, dtype=object if name in TEXT_COLUMNS
                              else np.int64 if name in INT_COLUMNS else float)
    methods = list(dict.fromkeys(cols["method"]))
    settings = sorted(set(cols["setting"]))
    levels = sorted(set(cols["uncertainty"]), key=level_key)
    return Results(columns=cols, methods=methods, settings=settings, levels=levels,
                   replaced=list(dict.fromkeys(replaced)), pairs=pairs,
                   origin=[r[ORIGIN] for r in rows])


def paired(a: Results, sel_a: np.ndarray, b: Results, sel_b: np.ndarray,
           column: str = "score") -> tuple[np.ndarray, np.ndarray]:
    """A column of the rows `sel_a` of `a` and `sel_b` of `b` (masks, e.g. of
    `Results.select`), on the scenarios both ran (same seed and id), in pairs, in the order of
    b's rows."""
    ca, cb = a.columns, b.columns
    key_a = {(str(s), int(i)): k for k, s, i in zip(np.nonzero(sel_a)[0], ca["seed"][sel_a],
                                                   ca["scenario"][sel_a])}
    pairs = [(key_a[(str(s), int(i))], k) for k, s, i in
             zip(np.nonzero(sel_b)[0], cb["seed"][sel_b], cb["scenario"][sel_b])
             if (str(s), int(i)) in key_a]
    if not pairs:
        return np.zeros(0), np.zeros(0)
    ia, ib = np.array(pairs).T
    return ca[column][ia], cb[column][ib]


def paired_values(res: Results, ref: np.ndarray, other: np.ndarray,
                  column: str = "score") -> tuple[np.ndarray, np.ndarray]:
    """`paired` within one evaluation: the rows `ref` and `other` select."""
    return paired(res, ref, res, other, column)


def check_column(res: Results, column: str, source: str = "",
                 methods: list[str] | None = None) -> None:
    """A MissionError unless `column` is a numeric column of the results whose every value
    (in the rows of `methods`, if given) is a finite number: a mean or a paired difference
    over a NaN is NaN, and one that skipped it would average other scenarios than it says."""
    if column in TEXT_COLUMNS or column in INT_COLUMNS or column not in res.columns:
        numeric = [c for c in res.columns if c not in TEXT_COLUMNS + INT_COLUMNS]
        raise MissionError("--column", None, f"no numeric column {column!r} in the results"
                           f"{' of ' + source if source else ''}; columns: "
                           + ", ".join(numeric))
    rows = np.ones(len(res.columns[column]), bool) if methods is None else \
        np.isin(res.columns["method"], methods)
    bad = np.nonzero(rows & ~np.isfinite(np.asarray(res.columns[column], dtype=float)))[0]
    if bad.size:
        where = res.origin[bad[0]] if res.origin else f"row {bad[0] + 1}"
        raise MissionError("--column", None, f"{column!r} is not a finite number in "
                           f"{bad.size} row(s) of the results{' of ' + source if source else ''}"
                           f" (the first: {where}, method {res.columns['method'][bad[0]]}): no "
                           "mean or paired difference can use it")
