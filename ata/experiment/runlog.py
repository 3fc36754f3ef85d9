"""The durable record of a chunked run, so that a killed run loses nothing and a rerun does only
what is missing.

An output folder holds ``plan.json`` (what is planned: a key of everything that decides the
results, and the number of work units) and ``units.jsonl`` (one line per finished unit, its
results, appended, flushed and fsynced as the unit finishes). A rerun into the folder with the
same plan reads the finished units back and runs only the others; since a unit's numbers depend
on its scenarios alone, the final rows are those of an uninterrupted run. A folder holding
results of another plan is refused unless the caller forces a fresh start (a plan that finished
nothing holds none).
"""

from __future__ import annotations

import csv
import hashlib
import json
import os
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

from ata.core.errors import MissionError

PLAN = "plan.json"
UNITS = "units.jsonl"
LOCK = ".ata-lock"
"""Held (an advisory lock) by the run writing the folder; it names that run."""
TRAINING_FILES = ("log.csv", "checkpoint.pt", "best.pt")
"""What marks a training run's folder (`ata.training.TrainRun`)."""


def plan_key(parts: Any) -> str:
    """A stable digest of a plan's description (JSON-serialisable)."""
    text = json.dumps(parts, sort_keys=True, default=str)
    return hashlib.sha256(text.encode("utf-8")).hexdigest()[:16]


def _encode(value: Any) -> Any:
    if isinstance(value, np.ndarray):
        return {"__array__": value.tolist(), "dtype": str(value.dtype)}
    if isinstance(value, (np.integer, np.floating)):
        return value.item()
    if isinstance(value, dict):
        return {k: _encode(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_encode(v) for v in value]
    return value


def _decode(value: Any) -> Any:
    if isinstance(value, dict):
        if "__array__" in value:
            return np.asarray(value["__array__"], dtype=value["dtype"])
        return {k: _decode(v) for k, v in value.items()}
    if isinstance(value, list):
        return [_decode(v) for v in value]
    return value


def write_csv(path: Path, columns: list[str], rows: list[dict[str, Any]]) -> None:
    """Write rows to a CSV file atomically (a temporary file, then a rename): a kill leaves the
    old file or the new one, never half of one."""
    tmp = path.with_name(path.name + ".tmp")
    with open(tmp, "w", newline="", encoding="utf-8") as f:
        writer = csv.DictWriter(f, fieldnames=columns)
        writer.writeheader()
        writer.writerows(rows)
    os.replace(tmp, path)


def _write_atomic(path: Path, text: str) -> None:
    tmp = path.with_name(path.name + ".tmp")
    with open(tmp, "w", encoding="utf-8") as f:
        f.write(text)
        f.flush()
        os.fsync(f.fileno())
    os.replace(tmp, path)


class RunLog:
    """Opens (or resumes) the record of a plan in `out_dir`.

    :param key: the plan's key (`plan_key`); a folder recorded under another key is refused.
    :param units: the number of work units of the plan.
    :param force: start afresh in a folder of another plan (its record is dropped).
    :param describe: what the plan is, written to plan.json for people.
    """

    def __init__(self, out_dir: str | Path, key: str, units: int, *, force: bool = False,
                 describe: dict[str, Any] | None = None):
        self.dir = Path(out_dir)
        self.key = key
        self.units = units
        self.done: dict[int, dict[str, Any]] = {}
        plan, log = self.dir / PLAN, self.dir / UNITS
        same = False
        if plan.exists():
            try:
                same = json.loads(plan.read_text(encoding="utf-8")).get("key") == key
            except (json.JSONDecodeError, AttributeError):
                same = False
        holds = (self.dir / "results.csv").exists() or (log.exists() and log.stat().st_size > 0)
        if not same and not force and holds:
            raise MissionError("--out", None, f"{self.dir} holds the results of another plan; "
                               "choose another folder, or --force to start it over there")
        if same:
            self.done = self._read(log)
        else:
            for stale in (log, self.dir / "results.csv"):
                stale.unlink(missing_ok=True)
            _write_atomic(plan, json.dumps({"key": key, "units": units, **(describe or {})},
                                           indent=2, default=str) + "\n")
        self.resumed = len(self.done)
        self._file = open(log, "a", encoding="utf-8")

    def _read(self, log: Path) -> dict[int, dict[str, Any]]:
        """The finished units; a line cut short by a kill is dropped (and cut off the file)."""
        if not log.exists():
            return {}
        done: dict[int, dict[str, Any]] = {}
        good = 0
        with open(log, "rb") as f:
            data = f.read()
        for line in data.splitlines(keepends=True):
            if not line.endswith(b"\n"):
                break
            try:
                entry = json.loads(line)
                index = int(entry["unit"])
                part = _decode(entry["part"])
            except (ValueError, KeyError, TypeError):
                break
            if 0 <= index < self.units:
                done[index] = part
            good += len(line)
        if good < len(data):
            with open(log, "r+b") as f:
                f.truncate(good)
        return done

    def add(self, index: int, part: dict[str, Any]) -> None:
        """Record a finished unit durably (flushed and fsynced before this returns)."""
        self._file.write(json.dumps({"unit": index, "part": _encode(part)}) + "\n")
        self._file.flush()
        os.fsync(self._file.fileno())
        self.done[index] = part

    def saved(self) -> int:
        """How many finished units the file holds, read back from disk (what a rerun finds,
        even when an interrupt came in the middle of `add`)."""
        self._file.flush()
        return len(self._read(self.dir / UNITS))

    def missing(self) -> list[int]:
        return [i for i in range(self.units) if i not in self.done]

    def close(self) -> None:
        self._file.close()


def parts_and_todo(log: RunLog | None, units: int) -> tuple[list[Any], list[int]]:
    """The results of `units` work units so far (None where not done) and the indices still to
    run: all of them without a log, else those the log does not hold."""
    parts: list[Any] = [None] * units
    if log is None:
        return parts, list(range(units))
    for i, part in log.done.items():
        parts[i] = part
    return parts, log.missing()


class FolderLock:
    """The right to write an output folder, held by one run at a time: two runs on one --out at
    once would mix their files. An advisory lock (flock) on ``.ata-lock`` in the folder, which
    the kernel drops when the process ends, however it ends; the file names the holder for the
    refusal and is removed when the run lets go. Where flock is missing (not POSIX), no lock.
    """

    def __init__(self, out_dir: str | Path):
        self.path = Path(out_dir) / LOCK
        self._fd: int | None = None

    def acquire(self) -> "FolderLock":
        try:
            import fcntl
        except ImportError:          # not POSIX
            return self
        while True:
            fd = os.open(self.path, os.O_RDWR | os.O_CREAT, 0o644)
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except OSError:
                os.close(fd)
                raise MissionError("--out", None, f"{self.path.parent} is in use by another "
                                   f"run ({self._holder()}); wait for it to end, or choose "
                                   "another folder") from None
            # the holder before us may have removed the file as we opened it: lock the file
            # that is there now, or a third run could hold another one at the same time
            try:
                same = os.fstat(fd).st_ino == os.stat(self.path).st_ino
            except FileNotFoundError:
                same = False
            if same:
                break
            os.close(fd)
        os.ftruncate(fd, 0)
        os.write(fd, json.dumps({"pid": os.getpid(), "command": " ".join(sys.argv),
                                 "started": time.strftime("%Y-%m-%d %H:%M:%S")}).encode())
        self._fd = fd
        return self

    def _holder(self) -> str:
        try:
            info = json.loads(self.path.read_text(encoding="utf-8"))
            return f"pid {info['pid']}, started {info['started']}: {info['command']}"
        except (OSError, ValueError, KeyError, TypeError):
            return "its details are not written yet"

    def release(self) -> None:
        if self._fd is None:
            return
        self.path.unlink(missing_ok=True)        # before the unlock: no one locks a stale file
        os.close(self._fd)
        self._fd = None

    def __enter__(self) -> "FolderLock":
        return self.acquire()

    def __exit__(self, *exc) -> None:
        self.release()


def refuse_training_folder(out_dir: str | Path) -> None:
    """A MissionError when `out_dir` is a training run's folder: a run or an evaluation there
    would overwrite its resolved mission, and `ata train --resume` would then fail."""
    path = Path(out_dir)
    held = [n for n in TRAINING_FILES if (path / n).exists()]
    if held:
        raise MissionError("--out", None, f"{path} is the folder of a training run "
                           f"({', '.join(held)}); choose another folder")
