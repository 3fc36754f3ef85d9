"""Trust tiers: a published set is *reproduced* when ata's own rerun of a sample of its rows
(every method and cell, `ata.experiment.reproduce.rerun_sample`) on the code the set names (its
methods' code digests) found them identical, and *reported* otherwise.

`verify` reruns the sample and returns its record; the record names the set by its rows' digest
and the code it ran by each method's component digests, so a record is only taken for the set
it checked, rerun on the code the set says made it (`tier`).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from ata import __version__
from ata.core.errors import MissionError
from ata.experiment.reproduce import rerun_sample
from ata.published.sets import current_code
from ata.site.sources import Source

REPRODUCED, REPORTED = "reproduced", "reported"
NOT_RERUN = "not rerun"


def installed_code(source: Source) -> dict[str, dict[str, str]]:
    """Each method's component digests of the code installed now (from its first cell's
    resolved mission)."""
    out = {}
    for name, method in source.methods.items():
        text = next((c["mission"] for c in method.cells.values() if c["mission"]), None)
        out[name] = current_code(text) if text else {}
    return out


def verify(source: Source, per_cell: int) -> dict[str, Any]:
    """Rerun `per_cell` scenarios of every method and cell of a published set here; the record
    of what was rerun and what differed."""
    if source.kind != "published":
        raise MissionError("--verify", None, f"{source.name} is a result folder: --verify "
                           "reruns a sample of a published set (ata publish it first)")
    if per_cell < 1:
        raise MissionError("--verify", None, "reruns at least 1 scenario per cell")
    lines = rerun_sample(source.locator, per_cell)
    skipped = [x for x in lines if x.endswith(NOT_RERUN)]
    differ = [x for x in lines if not x.endswith(NOT_RERUN)]
    cells = sum(len(m.cells) for m in source.methods.values())
    return {"set": source.name, "rows_sha256": source.digest, "per_cell": per_cell,
            "cells": cells, "ata": __version__, "code": installed_code(source),
            "identical": not differ, "differ": differ, "not_rerun": skipped}


def read_records(paths: list[str | Path]) -> list[dict[str, Any]]:
    """The records in `paths` (each a JSON list of records, a site's verified.json)."""
    out = []
    for path in paths:
        try:
            data = json.loads(Path(path).read_text(encoding="utf-8"))
        except (OSError, ValueError) as exc:
            raise MissionError("--verified", None, f"cannot read the records: {exc}",
                               file=str(path)) from None
        if not isinstance(data, list) or not all(isinstance(r, dict) for r in data):
            raise MissionError("--verified", None, "is not a list of verification records",
                               file=str(path))
        out += data
    return out


def tier(source: Source, records: list[dict[str, Any]]) -> tuple[str, dict[str, Any] | None,
                                                                 str]:
    """(the set's tier, the record that makes it reproduced or None, why in a sentence). A
    record counts for the set whose rows it reran (their digest) when the code it ran is the
    code the set names (each method's component digests): the rerun reproduced the set as
    published. It does not depend on the code installed when the page is built."""
    if source.kind != "published":
        return REPORTED, None, "a result folder: its rows are as its folder reports them"
    if not source.seed_public:
        return REPORTED, None, "a secret seed: its rows cannot be rerun by others"
    mine = [r for r in records if r.get("rows_sha256") == source.digest]
    if not mine:
        return REPORTED, None, "no rerun of a sample of its rows is recorded"
    for record in reversed(mine):
        ran = record.get("code") if isinstance(record.get("code"), dict) else {}
        if not all(m.code and all((ran.get(name) or {}).get(k) == v for k, v in m.code.items())
                   for name, m in source.methods.items()):
            continue
        if not record.get("identical") or record.get("cells") != sum(
                len(m.cells) for m in source.methods.values()):
            return REPORTED, record, "a rerun of a sample of its rows found values that differ"
        n = record.get("per_cell")
        return REPRODUCED, record, (f"{n} scenario{'s' if n != 1 else ''} of every method and "
                                    f"cell rerun with ata {record.get('ata')} on the code the "
                                    "set names: identical")
    last = mine[-1]
    n = last.get("per_cell")
    found = "identical rows" if last.get("identical") else "rows that differ"
    return REPORTED, None, (f"a rerun of {n} scenario{'s' if n != 1 else ''} of every method "
                            f"and cell with ata {last.get('ata')} found {found}, but on other "
                            "code than the set names: publish the set again with that code, "
                            "then rerun")
