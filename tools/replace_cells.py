"""One evaluation's rows with some of its cells taken from another evaluation: for a suite
in which only some methods changed (new weights), rerun those methods' cells with `ata eval
... --methods M --settings S` into NEW, then combine with the unchanged rows of BASE.

Usage: python tools/replace_cells.py BASE NEW OUT

OUT/results.csv holds BASE's rows, in BASE's order, except that every (method, setting,
uncertainty) cell present in NEW is replaced by NEW's rows of that cell (with NEW's number of
scenarios, which must equal BASE's); OUT/eval.json names both folders and the replaced cells.
`ata report OUT` and `python tools/results_tables.py OUT` read it as any evaluation.
"""

from __future__ import annotations

import csv
import json
import sys
from pathlib import Path

from ata.experiment import runlog


def read(folder: Path) -> tuple[list[dict], list[str]]:
    with open(folder / "results.csv", newline="", encoding="utf-8") as f:
        reader = csv.DictReader(f)
        return list(reader), list(reader.fieldnames or [])


def main(base: str, new: str, out: str) -> None:
    base_rows, header = read(Path(base))
    new_rows, new_header = read(Path(new))
    cell = lambda r: (r["method"], r["setting"], r["uncertainty"])    # noqa: E731
    replaced = {}
    for r in new_rows:
        replaced.setdefault(cell(r), []).append(r)
    counts = {}
    for r in base_rows:
        counts[cell(r)] = counts.get(cell(r), 0) + 1
    for c, rows in replaced.items():
        if c not in counts:
            sys.exit(f"{new}: cell {c} is not in {base}")
        if len(rows) != counts[c]:
            sys.exit(f"{new}: cell {c} has {len(rows)} rows, {base} has {counts[c]}")
    header += [h for h in new_header if h not in header]
    rows, done = [], set()
    for r in base_rows:
        c = cell(r)
        if c not in replaced:
            rows.append(r)
        elif c not in done:
            rows += replaced[c]
            done.add(c)
    o = Path(out)
    o.mkdir(parents=True, exist_ok=True)
    runlog.write_csv(o / "results.csv", header, rows)     # a column a row lacks: blank
    (o / "eval.json").write_text(json.dumps(
        {"rows": len(rows), "base": str(base), "replaced_from": str(new),
         "replaced_cells": [list(c) for c in replaced]}, indent=2) + "\n", encoding="utf-8")
    print(f"{out}: {len(rows)} rows, {len(replaced)} cells from {new}")


if __name__ == "__main__":
    if len(sys.argv) != 4:
        sys.exit(__doc__)
    main(*sys.argv[1:])
