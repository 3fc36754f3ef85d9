"""A training run's folder: its resolved mission, log.csv (and the same scalars as TensorBoard
event files, when the ``tensorboard`` package is installed), and checkpoints written atomically."""

from __future__ import annotations

import csv
import os
from pathlib import Path
from typing import Any, Callable

from ata.core.errors import MissionError
from ata.runtime import extras
from ata.training.checkpoints import of_kind, read_checkpoint


class TrainRun:
    """A training run folder.

    :param fields: the columns of log.csv.
    :param resume: carry on in an existing folder. Its log is kept up to the rows written when
        its checkpoint.pt was saved (each checkpoint records that count as ``log_rows``; none
        without a checkpoint.pt, whose run starts over): the rows of steps that the resumed run
        does again are not left twice in log.csv.
    :param on_row: told of every logged row (the progress bar).
    :param tensorboard: also write every row's numeric columns as TensorBoard scalars (tag: the
        column; step: the step counted across phases, each phase after the one before, as `ata
        report` draws it) to event files in the folder, if the ``tensorboard`` package is
        installed (``tensorboard_missing`` says it was not). A resumed run hides the scalars of
        the rows it cut from log.csv (TensorBoard's ``purge_step``).
    """

    def __init__(self, run_dir: str | Path, mission_toml: str, fields: list[str], *,
                 resume: bool = False, on_row: Callable[[dict], None] | None = None,
                 tensorboard: bool = True):
        self.dir = Path(run_dir)
        self.fields = list(fields)
        self.on_row = on_row
        self.rows = 0
        self.tensorboard = tensorboard
        self.tensorboard_missing = False
        self._writer: Any = None
        self._phase: str | None = None        # the step across phases of the last row logged
        self._offset = 0.0
        self._phase_max = 0.0
        self._last_x: float | None = None
        self._purge: int | None = None        # resumed: hide the event files' later steps
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
            for row in list(csv.DictReader(lines[:1 + self.rows]))[:self.rows]:
                self._x(row)
        self._purge = 0 if self._last_x is None else int(self._last_x) + 1

    def _x(self, row: dict[str, Any]) -> float:
        """The step of a row counted across phases (each phase after the one before)."""
        phase, step = str(row.get("phase") or ""), float(row.get("step") or 0)
        if phase != self._phase:
            if self._phase is not None:
                self._offset += self._phase_max
            self._phase, self._phase_max = phase, 0.0
        self._phase_max = max(self._phase_max, step)
        self._last_x = self._offset + step
        return self._last_x

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
        self._scalars(row)
        self.tell(row)

    def _scalars(self, row: dict[str, Any]) -> None:
        """The row's numeric columns (but ``step``) as TensorBoard scalars; empty ones are left
        out, as in log.csv."""
        x = self._x(row)
        writer = self._tensorboard_writer()
        if writer is None:
            return
        try:
            for key, value in row.items():
                if key in ("phase", "step") or value in ("", None):
                    continue
                try:
                    number = float(value)
                except (TypeError, ValueError):
                    continue                               # a text column, such as setting
                writer.add_scalar(key, number, int(x))
            writer.flush()
        except Exception as exc:        # an optional extra: the training goes on without it
            self._without_tensorboard(exc, "writing its event file")

    def _tensorboard_writer(self) -> Any:
        if not self.tensorboard or self.tensorboard_missing:
            return None
        if self._writer is None:
            def load() -> Any:
                import tensorboard  # noqa: F401  (torch's writer needs the package)
                from torch.utils.tensorboard import SummaryWriter  # the simulator needs no torch
                return SummaryWriter
            writer = extras.optional("tensorboard", load)
            if writer is None:
                self.tensorboard_missing = True
                return None
            try:
                self._writer = writer(str(self.dir), purge_step=self._purge)
            except Exception as exc:
                self._without_tensorboard(exc, "opening its event file")
        return self._writer

    def _without_tensorboard(self, exc: Exception, doing: str) -> None:
        """TensorBoard failed: one warning, and no more scalars (log.csv holds them all)."""
        extras.without("tensorboard", exc, doing)
        self.tensorboard_missing = True
        writer, self._writer = self._writer, None
        if writer is not None:
            try:
                writer.close()
            except Exception:           # already reported; its event file is left as it is
                pass

    def close(self) -> None:
        """Close the TensorBoard event file (if one was written)."""
        if self._writer is not None:
            try:
                self._writer.close()
            except Exception as exc:    # an optional extra: the run is saved without it
                extras.without("tensorboard", exc, "closing its event file")
            self._writer = None

    def tell(self, row: dict[str, Any]) -> None:
        """Tell the progress bar of a row without logging it (progress inside a long step)."""
        if self.on_row is not None:
            self.on_row(row)

    def save(self, data: dict[str, Any], name: str = "checkpoint.pt") -> Path:
        """Write a checkpoint atomically (torch.save to a temporary file, then a rename)."""
        import torch   # on use: the simulator needs no torch
        path = self.dir / name
        tmp = path.with_name(path.name + ".tmp")
        data["log_rows"] = self.rows
        torch.save(data, tmp)
        os.replace(tmp, path)
        return path
