"""Published rows reproduced: a sample of a set's rows run again on the code installed now."""

from __future__ import annotations

import tempfile
from pathlib import Path

import numpy as np

from ata.experiment.runner import run_mission
from ata.published import read_published
from ata.session import load_session


def rerun_sample(spec: str | Path, per_cell: int = 2, methods: list[str] | None = None,
                 columns: tuple[str, ...] = (), cells: dict[str, list[str]] | None = None
                 ) -> list[str]:
    """Rerun `per_cell` scenarios of every (method, cell) of a set (the first and the last of
    each cell's rows, then evenly between) and return one line per value that is not identical
    to the published one (empty: every rerun row is identical). `cells`: method -> the cells
    ("SETTING/LEVEL") to rerun of it (default: all). Rows of a secret seed are not rerun, nor
    a row whose MILP solve reached a limit (``milp_status`` 1: where a time limit stops it
    depends on the machine's speed); a line says so."""
    results, manifest, _ = read_published(spec)
    cols = results.columns
    numeric = [c for c in results.columns if c not in ("method", "setting", "uncertainty",
                                                       "scenario", "seed")]
    wanted = list(columns) or numeric
    out: list[str] = []
    for method, entry in manifest["methods"].items():
        if methods is not None and method not in methods:
            continue
        for cell, info in entry["cells"].items():
            if cells is not None and cell not in cells.get(method, ()):
                continue
            setting, level = cell.split("/")
            sel = np.nonzero(results.select(method, setting, level))[0]
            if str(info["seed"]).startswith("secret:"):
                out.append(f"{method} ({cell}): a secret seed; not rerun")
                continue
            picks = sorted({int(sel[round(k * (sel.size - 1) / max(per_cell - 1, 1))])
                            for k in range(min(per_cell, sel.size))})
            with tempfile.TemporaryDirectory() as tmp:
                path = Path(tmp) / "mission.toml"
                path.write_text(info["mission"], encoding="utf-8")
                for row in picks:
                    sid = int(cols["scenario"][row])
                    if "milp_status" in cols and cols["milp_status"][row] == 1:
                        out.append(f"{method} ({cell}) scenario {sid}: a MILP solve reached "
                                   "a limit; not rerun")
                        continue
                    session = load_session(str(path), [f"mission.first_scenario={sid}",
                                                       "mission.scenarios=1"])
                    again = run_mission(session, workers=1).rows()[0]
                    for c in wanted:
                        if c not in again:
                            continue
                        a, b = float(cols[c][row]), float(again[c])
                        if not (a == b or (np.isnan(a) and np.isnan(b))):
                            out.append(f"{method} ({cell}) scenario {sid}: {c} {a!r} "
                                       f"published, {b!r} rerun")
    return out
