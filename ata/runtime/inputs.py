"""Files that a component setting names: ``builtin:NAME`` (a checkpoint shipped in ata/weights)
or a path. Trainers and components read checkpoints through ``ata.training``, which takes these
from here; a session hashes them into its plan keys (``Session.inputs``)."""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

WEIGHTS = Path(__file__).resolve().parents[1] / "weights"
"""Where ``builtin:NAME`` checkpoints live (shipped with the package)."""
PINNED = Path(__file__).resolve().parents[1] / "weights" / "digests.json"
"""The sha256 of every shipped checkpoint, file name -> hex digest: a ``builtin:`` file that
differs (bits flipped on disk, a file swapped in) is refused instead of scoring silently
otherwise. `pin_weights` rewrites it after new weights are shipped."""
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
    return _sha256(path)[:16]


def _sha256(path: Path) -> str:
    stat = path.stat()
    key = (str(path.resolve()), stat.st_mtime_ns, stat.st_size)
    if key not in _DIGESTS:
        h = hashlib.sha256()
        with open(path, "rb") as f:
            for block in iter(lambda: f.read(1 << 20), b""):
                h.update(block)
        _DIGESTS[key] = h.hexdigest()
    return _DIGESTS[key]


def pinned() -> dict[str, str]:
    """The pinned digests of the shipped checkpoints (`PINNED`)."""
    return json.loads(PINNED.read_text(encoding="utf-8"))


def shipped_mismatch(path: str | Path) -> str | None:
    """Why the file at `path`, one of the shipped checkpoints' place (`WEIGHTS`), is not the
    file ata shipped; None when it is, or when `path` is not in that folder."""
    path = Path(path)
    if not path.is_file() or path.resolve().parent != WEIGHTS.resolve():
        return None
    want = pinned().get(path.name)
    if want is None:
        return (f"is not one of the checkpoints ata ships (none is pinned under that name in "
                f"{PINNED})")
    have = _sha256(path)
    if have != want:
        return (f"is not the file ata shipped: its sha256 is {have[:16]}..., the pinned one "
                f"{want[:16]}... ({PINNED.name}); the file is corrupted or was replaced: "
                "reinstall ata, or name a checkpoint of your own by its path")
    return None


def pin_weights() -> dict[str, str]:
    """Pin the checkpoints now in `WEIGHTS` (after shipping new ones): rewrite `PINNED`."""
    digests = {p.name: _sha256(p) for p in sorted(WEIGHTS.glob("*.pt"))}
    PINNED.write_text(json.dumps(digests, indent=2) + "\n", encoding="utf-8")
    return digests
