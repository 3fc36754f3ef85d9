"""`ata report` of a training folder: one run's curves (`curves`), or a folder of seeds' curves
across its seeds (`seed_curves`)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from ata.results import curves, seed_curves
from ata.training.folders import is_seeds_folder


def is_training_folder(path: str | Path) -> bool:
    """A folder with a log.csv (from `ata train`) and no results.csv (from `ata eval`), or a
    folder of seeds (`ata train --seeds`)."""
    path = Path(path)
    return ((path / curves.LOG_FILE).is_file() and not (path / "results.csv").exists()) \
        or is_seeds_folder(path)


def write_curves(folder: str | Path, out_dir: str | Path | None = None,
                 with_figures: bool = True) -> tuple[Any, list[Path]]:
    """A training folder's curves and curves.md, written into `out_dir` (by default the
    folder): one run's (`curves.write_curves`) or across a folder's seeds
    (`seed_curves.write_seed_report`); what was read, and the files written."""
    if is_seeds_folder(folder):
        return seed_curves.write_seed_report(folder, out_dir, with_figures)
    return curves.write_curves(folder, out_dir, with_figures)


def curves_rows(log: Any) -> tuple[list[str], list[list[str]]]:
    """The table of what `write_curves` read: a row per phase of one run, or per seed (its
    best held-out validation) of a folder of seeds."""
    if isinstance(log, curves.TrainingLog):
        return curves.curves_rows(log)
    return seed_curves.best_rows(log)


def seed_tables(log: Any) -> list[Any]:
    """A folder of seeds' across-seed tables of its evaluation (`seed_curves.eval_tables`);
    none for one run."""
    return [] if isinstance(log, curves.TrainingLog) else seed_curves.eval_tables(log)
