"""What a trainer component needs from ata, for built-in and third-party trainers alike.

A *trainer* is a component of kind ``trainer``, registered by name like any other and chosen in
a training mission's ``[components] trainer``; its settings are the table named after it. `ata
train MISSION` builds it as ``factory(settings, mission, registry)`` and calls ``run``:

    class MyTrainer:
        log_fields = ["phase", "step", ...]                         # the columns of log.csv

        @dataclass
        class Settings: ...

        def __init__(self, settings, mission, registry): ...
        def scenario_ranges(self) -> list[tuple[int, int, int]]: ...   # (seed, first, end)
        def total_steps(self) -> int: ...
        def done_steps(self) -> int: ...                            # for the progress bar
        def run(self, run: TrainRun, resume: bool = False) -> dict: ...

``scenario_ranges`` lists every (root seed, scenario id range) the training may draw; the trainer
records it in each checkpoint, the components it trains report it through the
``ata_trained_on`` hook, and `ata eval` refuses to evaluate a method on any scenario in it.
Training ids must stay below ``TRAINING_ID_LIMIT`` (evaluation ids start at 2**40).

``TrainRun`` is the run folder: the resolved mission, ``log.csv`` (one row per step), and
checkpoints written atomically (a temporary file, then a rename), so a killed run resumes from
its last checkpoint with ``ata train --resume DIR``.
"""

from __future__ import annotations

import csv
import os
from pathlib import Path
from typing import Any, Callable

from ata.core.errors import MissionError
from ata.runtime.heldout import EVAL_FIRST_SCENARIO
from ata.runtime.inputs import WEIGHTS, file_digest, resolve

__all__ = ["TRAINING_ID_LIMIT", "VALIDATION_SEED_OFFSET", "WEIGHTS", "CheckpointError", "TrainRun",
           "file_digest", "load_cached", "read_checkpoint", "resolve", "trained_on"]

TRAINING_ID_LIMIT = EVAL_FIRST_SCENARIO
"""Training scenario ids lie below this; evaluation ids start there."""
VALIDATION_SEED_OFFSET = 1_000_003
"""A trainer's held-out validation scenarios have root seed ``seed + VALIDATION_SEED_OFFSET``
(the built-in trainers' convention; they list that range in ``scenario_ranges``)."""
_CACHE: dict[tuple, Any] = {}


class CheckpointError(MissionError):
    """A checkpoint that is missing, corrupted, or does not match what reads it."""

    def __init__(self, path: str | Path, message: str):
        super().__init__("checkpoint", None, message, file=str(path))


def read_checkpoint(path: str | Path, kind: str | None = None) -> dict[str, Any]:
    """Load a checkpoint dict with ``torch.load(..., weights_only=True)``; a missing, empty,
    truncated or foreign file is a CheckpointError naming it.

    :param kind: the method the checkpoint must be of (its ``kind`` entry), if any: a
        TR-POMDP checkpoint given where ATA-HRL's is expected is refused.
    """
    import torch
    p = Path(path)
    if not p.exists():
        raise CheckpointError(p, "no such checkpoint (train one with `ata train`)")
    if p.is_dir():
        raise CheckpointError(p, "is a directory, not a checkpoint")
    try:
        data = torch.load(p, map_location="cpu", weights_only=True)
    except Exception as exc:   # empty, truncated, corrupted, or not a torch file at all
        first = (str(exc).splitlines() or [""])[0][:200]
        raise CheckpointError(p, f"cannot be read as a checkpoint ({type(exc).__name__}: "
                                 f"{first})") from None
    if not isinstance(data, dict) or "kind" not in data:
        raise CheckpointError(p, "is not an ata checkpoint (it names no method)")
    return _of_kind(data, p, kind)


def _of_kind(data: dict[str, Any], path: Path, kind: str | None) -> dict[str, Any]:
    if kind is not None and data.get("kind") != kind:
        raise CheckpointError(path, f"is a checkpoint of {data.get('kind')!r}, not of "
                                    f"{kind!r}: name a checkpoint that `ata train` wrote for "
                                    f"{kind}")
    return data


def load_cached(spec: str, build: Callable[[dict[str, Any], Path], Any], kind: str) -> Any:
    """What `build(checkpoint data, path)` makes of a checkpoint of `kind` (in evaluation mode),
    built once per process for each (kind, file)."""
    path = resolve(spec)
    key = (kind, str(path.resolve()) if path.exists() else str(path))
    if key not in _CACHE:
        module = build(read_checkpoint(path, kind), path)
        module.eval()
        _CACHE[key] = module
    return _CACHE[key]


def trained_on(spec: str, kind: str) -> list[tuple[int, int, int]]:
    """The (root seed, first id, end id) ranges a checkpoint's training drew scenarios from,
    as its trainer recorded them (read once per process for each version of the file)."""
    path = resolve(spec)
    stat = path.stat() if path.is_file() else None
    key = ("ranges", kind, str(path.resolve()), stat and (stat.st_mtime_ns, stat.st_size))
    if stat is None or key not in _CACHE:
        data = read_checkpoint(path, kind)
        _CACHE[key] = [tuple(int(x) for x in r) for r in data.get("scenario_ranges", [])]
    return list(_CACHE[key])


class TrainRun:
    """A training run folder.

    :param fields: the columns of log.csv.
    :param resume: carry on in an existing folder. Its log is kept up to the rows written when
        its checkpoint.pt was saved (each checkpoint records that count as ``log_rows``): the
        rows of steps that the resumed run does again are not left twice in log.csv.
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
        keep = len(lines) - 1
        if self.checkpoint_path.exists():
            self._resumed = read_checkpoint(self.checkpoint_path)
            kept = self._resumed.get("log_rows")
            if isinstance(kept, int) and 0 <= kept < keep:
                keep = kept
        self.rows = max(keep, 0)
        if lines:
            tmp = log.with_name(log.name + ".tmp")
            tmp.write_text("".join(lines[:1 + self.rows]), encoding="utf-8")
            os.replace(tmp, log)

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
        return _of_kind(data, self.checkpoint_path, kind)

    def log(self, row: dict[str, Any]) -> None:
        """Append one row to log.csv (unknown keys are an error: they would be lost)."""
        unknown = set(row) - set(self.fields)
        if unknown:
            raise KeyError(f"log row has columns not in log.csv: {sorted(unknown)}")
        row = {k: row.get(k, "") for k in self.fields}
        with open(self.dir / "log.csv", "a", newline="") as f:
            csv.DictWriter(f, fieldnames=self.fields).writerow(row)
        self.rows += 1
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

