"""The durable record of a chunked run, so that a killed run loses nothing and a rerun does only
what is missing.

An output folder holds ``plan.json`` (what is planned: a key of everything that decides the
results, and the number of work units) and ``units.jsonl`` (one line per finished unit, its
results, appended and fsynced as the unit finishes). A rerun into the folder with the same
plan reads the finished units back, checked line by line against the plan, and runs only the
others; since a unit's numbers depend on its scenarios alone, the final rows are those of an
uninterrupted run. A folder holding results of another plan is refused unless the caller forces
a fresh start (a plan that finished nothing holds none).
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
from ata.runtime.folders import cannot_write

PLAN = "plan.json"
UNITS = "units.jsonl"
LOCK = ".ata-lock"
"""Held (an advisory lock) by the run writing the folder; it names that run."""


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


def rows_digest(encoded_part: Any) -> str:
    """The digest a record line carries of its unit's results (as JSON holds them): a line
    whose results changed after they were written (a hand edit, flipped bits) fails it."""
    text = json.dumps(encoded_part, sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(text.encode("utf-8")).hexdigest()[:16]


FINITE = ("total", "upper_bound")
"""Result columns that are finite in every scenario a unit ran: a NaN or an infinity there is
no result, and would turn the run's summary and report into NaN."""


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


class NotSaved(Exception):
    """The record could not be written (a full disk, a file size limit, a permission): the
    message names the file and the reason; what is saved is what the file held before."""


REQUIRED = ("scenario", "total", "upper_bound", "reallocations", "warnings")
"""What every unit's results hold (`ata.experiment.units.run_batch`)."""
PER_RUN = ("warnings", "wall_s")
"""The entries of a unit's results that are not one value per scenario."""


def _differences(before: Any, describe: dict[str, Any] | None) -> str:
    """What the folder's plan.json (`before`) describes otherwise than this plan, for the
    refusal's message ('' when the descriptions agree: the difference is in what they do not
    show, such as component versions or weights)."""
    if not isinstance(before, dict) or not describe:
        return ""

    def show(value: Any) -> str:
        return ", ".join(map(str, value)) if isinstance(value, list) else str(value)

    now = json.loads(json.dumps(describe, default=str))
    diffs = [f"{k} {show(before[k])} there, {show(now[k])} here" for k in now
             if k in before and before[k] != now[k]]
    return f" ({'; '.join(diffs)})" if diffs else ""


class RunLog:
    """Opens (or resumes) the record of a plan in `out_dir`.

    On resume every line of units.jsonl is checked against the plan: a line that does not
    parse, fails the digest of its rows (`rows_digest`: edited or corrupted after it was
    written), names no unit of the plan, repeats one, lacks a result, holds a non-finite total,
    or holds other scenarios or other columns than its unit's is dropped (and its unit run
    again); `dropped` says which and why, and the file is rewritten without them.

    :param key: the plan's key (`plan_key`); a folder recorded under another key is refused.
    :param units: the number of work units of the plan.
    :param force: start afresh in a folder of another plan (its record is dropped).
    :param describe: what the plan is, written to plan.json for people.
    :param expected: each unit's scenario ids, in unit order (None: not checked).
    :raises NotSaved: when the folder's record cannot be read or written.
    """

    def __init__(self, out_dir: str | Path, key: str, units: int, *, force: bool = False,
                 describe: dict[str, Any] | None = None,
                 expected: list[np.ndarray] | None = None):
        self.dir = Path(out_dir)
        self.key = key
        self.units = units
        self.expected = expected
        self.done: dict[int, dict[str, Any]] = {}
        self.dropped: list[str] = []
        plan, log = self.dir / PLAN, self.dir / UNITS
        self.path = log
        try:
            same, before = False, {}
            if plan.exists():
                try:
                    before = json.loads(plan.read_text(encoding="utf-8"))
                    same = before.get("key") == key
                except (json.JSONDecodeError, AttributeError, UnicodeDecodeError):
                    same, before = False, {}
            holds = ((self.dir / "results.csv").exists()
                     or (log.exists() and log.stat().st_size > 0))
            if not same and not force and holds:
                raise MissionError("--out", None, f"{self.dir} holds the results of another "
                                   f"plan{_differences(before, describe)}; choose another "
                                   "folder, or --force to start it over there")
            if same:
                self.done = self._read(log, repair=True)
            else:
                for stale in (log, self.dir / "results.csv"):
                    stale.unlink(missing_ok=True)
                _write_atomic(plan, json.dumps({"key": key, "units": units, **(describe or {})},
                                               indent=2, default=str) + "\n")
            self._fd = os.open(log, os.O_WRONLY | os.O_APPEND | os.O_CREAT, 0o644)
        except OSError as exc:
            raise NotSaved(cannot_write(exc, log)) from None
        self.resumed = len(self.done)

    def _problem(self, index: int, part: Any, columns: set[str] | None) -> str | None:
        """Why a unit's record does not fit the plan (None when it does)."""
        if not 0 <= index < self.units:
            return f"unit {index} is not one of the plan's (0 to {self.units - 1})"
        if not isinstance(part, dict):
            return f"unit {index} holds no results"
        missing = [k for k in REQUIRED if k not in part]
        if missing:
            return f"unit {index} lacks {', '.join(missing)}"
        if columns is not None and set(part) != columns:
            return f"unit {index} holds other columns than the other units"
        if self.expected is None:
            return None
        want = np.asarray(self.expected[index])
        ids = np.asarray(part["scenario"])
        if ids.shape != want.shape or not np.array_equal(ids, want):
            return (f"unit {index} holds other scenarios than the plan's "
                    f"({int(want[0])} to {int(want[-1])})")
        for name, value in part.items():
            if name not in PER_RUN and np.shape(value) != want.shape:
                return f"unit {index}'s {name} does not hold one value per scenario"
        for name in FINITE:
            try:
                finite = bool(np.isfinite(np.asarray(part[name], dtype=float)).all())
            except (TypeError, ValueError):
                finite = False
            if not finite:
                return f"unit {index}'s {name} holds a value that is not a finite number"
        return None

    def _read(self, log: Path, repair: bool = False) -> dict[int, dict[str, Any]]:
        """The finished units that fit the plan. A last line cut short by a kill is dropped
        silently, a line that does not fit with a note in `dropped`; with `repair`, the file
        is rewritten without them."""
        if not log.exists():
            return {}
        with open(log, "rb") as f:
            data = f.read()
        entries: list[tuple[int, int, Any, bytes]] = []      # (line number, unit, part, line)
        dropped: list[tuple[int, str]] = []
        lines = data.splitlines(keepends=True)
        for number, line in enumerate(lines, 1):
            if not line.endswith(b"\n"):
                continue                                     # the last one, cut short
            try:
                entry = json.loads(line)
                index, raw = int(entry["unit"]), entry["part"]
            except (ValueError, KeyError, TypeError, AttributeError, RecursionError):
                dropped.append((number, "not a unit's record"))
                continue
            if entry.get("digest") != rows_digest(raw):
                dropped.append((number, f"unit {index}'s results do not match the digest "
                                        "written with them (changed after they were written)"
                                if "digest" in entry else
                                f"unit {index}'s results carry no digest (an older record)"))
                continue
            entries.append((number, index, _decode(raw), line))
        # the columns most units hold (metrics differ between missions, not between units)
        sets = [frozenset(p) for _, _, p, _ in entries if isinstance(p, dict)]
        columns = set(max(sets, key=sets.count)) if sets else None
        done: dict[int, dict[str, Any]] = {}
        kept: list[bytes] = []
        for number, index, part, line in entries:
            problem = self._problem(index, part, columns)
            if problem is None and index in done:
                problem = f"unit {index} again"
            if problem is not None:
                dropped.append((number, problem))
                continue
            done[index] = part
            kept.append(line)
        if repair:
            self.dropped = [f"line {n}: {why}" for n, why in sorted(dropped)]
            if len(kept) < len(lines):
                _write_atomic_bytes(log, b"".join(kept))
        return done

    def add(self, index: int, part: dict[str, Any]) -> None:
        """Record a finished unit durably (written and fsynced before this returns); when it
        cannot be written whole, the file is cut back to the units before it (`NotSaved`)."""
        encoded = _encode(part)
        data = memoryview((json.dumps({"unit": index, "part": encoded,
                                       "digest": rows_digest(encoded)}) + "\n").encode())
        size = os.fstat(self._fd).st_size
        try:
            while data:
                data = data[os.write(self._fd, data):]
            os.fsync(self._fd)
        except OSError as exc:
            try:
                os.ftruncate(self._fd, size)                 # no half line left behind
            except OSError:
                pass
            raise NotSaved(cannot_write(exc, self.path)) from None
        self.done[index] = part

    def saved(self) -> int:
        """How many finished units the file holds, read back from disk (what a rerun finds,
        even when an interrupt came in the middle of `add`)."""
        try:
            return len(self._read(self.path))
        except OSError:
            return len(self.done)

    def missing(self) -> list[int]:
        return [i for i in range(self.units) if i not in self.done]

    def close(self) -> None:
        if self._fd is not None:
            os.close(self._fd)
            self._fd = None


def _write_atomic_bytes(path: Path, data: bytes) -> None:
    tmp = path.with_name(path.name + ".tmp")
    with open(tmp, "wb") as f:
        f.write(data)
        f.flush()
        os.fsync(f.fileno())
    os.replace(tmp, path)


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
            import fcntl                 # imported on use: POSIX only
        except ImportError:              # not POSIX
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
        try:                          # the holder's details; a full disk leaves them out
            os.ftruncate(fd, 0)
            os.write(fd, json.dumps({"pid": os.getpid(), "command": " ".join(sys.argv),
                                     "started": time.strftime("%Y-%m-%d %H:%M:%S")}).encode())
        except OSError:
            pass
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
