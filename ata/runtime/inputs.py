"""Files that a component setting names: ``builtin:NAME`` (a checkpoint shipped in ata/weights)
or a path. Trainers and components read checkpoints through ``ata.training``, which takes these
from here; a session hashes them into its plan keys (``Session.inputs``)."""

from __future__ import annotations

import hashlib
from pathlib import Path

WEIGHTS = Path(__file__).resolve().parents[1] / "weights"
"""Where ``builtin:NAME`` checkpoints live (shipped with the package)."""
_DIGESTS: dict[tuple, str] = {}


def resolve(spec: str) -> Path:
    """A checkpoint's path: ``builtin:NAME`` is ata/weights/NAME.pt, anything else a path."""
    if spec.startswith("builtin:"):
        return WEIGHTS / f"{spec.split(':', 1)[1]}.pt"
    return Path(spec)


def file_digest(spec: str) -> str | None:
    """The sha256 (first 16 hex digits) of the file a setting names (``builtin:NAME`` or a
    path), or None where it names no file; computed once per process for each version of the
    file. Plan keys include it, so a folder of results is not resumed with other weights."""
    path = resolve(spec)
    if not path.is_file():
        return None
    stat = path.stat()
    key = (str(path.resolve()), stat.st_mtime_ns, stat.st_size)
    if key not in _DIGESTS:
        h = hashlib.sha256()
        with open(path, "rb") as f:
            for block in iter(lambda: f.read(1 << 20), b""):
                h.update(block)
        _DIGESTS[key] = h.hexdigest()[:16]
    return _DIGESTS[key]
