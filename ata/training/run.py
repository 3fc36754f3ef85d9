"""A training run's folder: its resolved mission, log.csv, and checkpoints written atomically."""

from __future__ import annotations

import csv
import os
from pathlib import Path
from typing import Any, Callable

from ata.core.errors import MissionError
from ata.training.checkpoints import of_kind, read_checkpoint


class TrainRun:
    """A training run folder.

    :param fields: the columns of log.csv.
    :param resume: carry on in an existing folder. Its log is kept up to the rows written when
        its checkpoint.pt was saved (each checkpoint records that count as ``log_rows``; none
        without a checkpoint.pt, whose run starts over): the rows of steps that the resumed run
        does again are not left twice in log.csv.
    :param on_row: told of every logged row (the progress bar).
    """

    def __init__(self, run_dir: str | Path, mission_toml: str, fields: list[str], *,
                 resume: bool = False, on_row: Callable[[dict], None] | None = None):
        self.dir = Path(run_dir)
        self.fields = list(fields)
        self.on_row = on_row
        self.rows = 0
        self._resumed: dict[str, Any] | None = None     # checkpoint.pt, read once on resume
        self.dir.mkdir(parents=True, exist_ok=True)
        if not resume:
            held = [n for n in ("checkpoint.pt", "best.pt", "log.csv") if (self.dir / n).exists()]
            if held:
                raise MissionError("--out", None, f"{self.dir} holds a training run already "
                                   f"({', '.join(held)}): resume it with --resume {self.dir}, "
                                   "or choose another folder")
            (self.dir / "mission.resolved.toml").write_text(mission_toml, encoding="utf-8")
            with open(self.dir / "log.csv", "w", newline="") as f:
                csv.DictWriter(f, fieldnames=self.fields).writeheader()
        else:
            self._rewind()

    def _rewind(self) -> None:
        """Cut log.csv back to the rows its last checkpoint had seen written."""
        log = self.dir / "log.csv"
        lines = log.read_text(encoding="utf-8").splitlines(keepends=True) if log.exists() else []
        keep = 0
        if self.checkpoint_path.exists():
            self._resumed = read_checkpoint(self.checkpoint_path)
            kept = self._resumed.get("log_rows")
            keep = kept if isinstance(kept, int) and 0 <= kept < len(lines) else len(lines) - 1
        self.rows = max(keep, 0)
        if lines:
            tmp = log.with_name(log.name + ".tmp")
            tmp.write_text("".join(lines[:1 + self.rows]), encoding="utf-8")
            os.replace(tmp, log)

    @property
    def resumes(self) -> bool:
        """Whether the run carries on from a checkpoint.pt (one killed before its first
        checkpoint starts over)."""
        return self.checkpoint_path.exists()

    @property
    def checkpoint_path(self) -> Path:
        return self.dir / "checkpoint.pt"

    @property
    def best_path(self) -> Path:
        return self.dir / "best.pt"

    def resume_checkpoint(self, kind: str) -> dict[str, Any]:
        """checkpoint.pt of the run being resumed (read once, when the run folder opened), as
        ``read_checkpoint(self.checkpoint_path, kind)`` gives it."""
        data, self._resumed = self._resumed, None
        if data is None:
            return read_checkpoint(self.checkpoint_path, kind)
        return of_kind(data, self.checkpoint_path, kind)

    def log(self, row: dict[str, Any]) -> None:
        """Append one row to log.csv (unknown keys are an error: they would be lost)."""
        unknown = set(row) - set(self.fields)
        if unknown:
            raise KeyError(f"log row has columns not in log.csv: {sorted(unknown)}")
        row = {k: row.get(k, "") for k in self.fields}
        with open(self.dir / "log.csv", "a", newline="") as f:
            csv.DictWriter(f, fieldnames=self.fields).writerow(row)
        self.rows += 1
        self.tell(row)

    def tell(self, row: dict[str, Any]) -> None:
        """Tell the progress bar of a row without logging it (progress inside a long step)."""
        if self.on_row is not None:
            self.on_row(row)

    def save(self, data: dict[str, Any], name: str = "checkpoint.pt") -> Path:
        """Write a checkpoint atomically (torch.save to a temporary file, then a rename)."""
        import torch
        path = self.dir / name
        tmp = path.with_name(path.name + ".tmp")
        data["log_rows"] = self.rows
        torch.save(data, tmp)
        os.replace(tmp, path)
        return path
