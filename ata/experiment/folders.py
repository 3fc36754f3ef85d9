"""Output folders: where they go by default, how they are named (from names a user chose, made
safe), and their preparation and writing, whose I/O errors become one clear message.

Every command that writes a folder (`ata run`, `eval`, `train`, `report`, `show`) names and
prepares it here, so that a mission name such as ``../../x`` or ``/elsewhere/x`` can never
place a folder outside runs/, and a full disk or an unwritable path is one message with exit
status 2 (a `MissionError`), not a traceback.
"""

from __future__ import annotations

import contextlib
import os
import re
import time
from pathlib import Path
from typing import Iterator

from ata.core.errors import MissionError


def runs_root() -> Path:
    """Where output folders go by default: $ATA_RUNS, else runs/."""
    return Path(os.environ.get("ATA_RUNS", "runs"))


def safe_name(text: str, fallback: str = "run") -> str:
    """A form of a user's label that is one plain file name: no separator, no '..', no leading
    dot ('w/o.AUX' -> 'w_o.AUX', '../../x' -> 'x', '/elsewhere/x' -> 'elsewhere_x')."""
    name = re.sub(r"_+", "_", re.sub(r"[^A-Za-z0-9._-]+|\.\.+", "_", text))
    return name.strip("._-") or fallback


def stamped_folder(label: str) -> Path:
    """A new folder runs/LABEL-TIME, created now (LABEL made safe, `safe_name`): two runs
    started in the same second get LABEL-TIME and LABEL-TIME-2."""
    return new_folder(runs_root() / f"{safe_name(label)}-{time.strftime('%Y%m%d-%H%M%S')}")


def named_folder(label: str) -> Path:
    """runs/LABEL (LABEL made safe), not created: a folder a command reuses by name."""
    return runs_root() / safe_name(label)


def new_folder(path: Path) -> Path:
    """Create path, or path-2, path-3 ... if it exists (atomically: mkdir fails on a taken name)."""
    prepare_out_dir(path.parent)
    for n in range(1, 10_000):
        candidate = path if n == 1 else path.with_name(f"{path.name}-{n}")
        try:
            candidate.mkdir()
            return candidate
        except FileExistsError:
            continue
        except OSError as exc:
            raise MissionError("--out", None, f"cannot create {candidate}: "
                               f"{exc.strerror or exc}") from None
    raise MissionError("--out", None, f"no free folder name like {path}")


def prepare_out_dir(path: str | Path) -> Path:
    """Create the output folder and check that it can be written, before any work is done; a
    path under a file, a file, or a folder without write permission is one clear error."""
    path = Path(path)
    try:
        path.mkdir(parents=True, exist_ok=True)
        probe = path / f".ata-write-check-{os.getpid()}"
        probe.write_bytes(b"")
        probe.unlink()
    except OSError as exc:
        reason = "it is a file" if path.is_file() else exc.strerror or str(exc)
        raise MissionError("--out", None, f"cannot write to {path}: {reason}") from None
    return path


def cannot_write(exc: OSError, where: Path | str | None = None) -> str:
    """'cannot write FILE: REASON' for an I/O error (the file it names, else `where`)."""
    target = exc.filename if exc.filename is not None else where
    reason = exc.strerror or str(exc) or type(exc).__name__
    return f"cannot write {target}: {reason}" if target is not None else f"cannot write: {reason}"


@contextlib.contextmanager
def writing(out_dir: str | Path) -> Iterator[None]:
    """Writes into `out_dir` whose I/O errors (a full disk, a file size limit, a permission)
    become one MissionError naming the file and the reason."""
    try:
        yield
    except OSError as exc:
        raise MissionError("", None, cannot_write(exc, out_dir)) from None
