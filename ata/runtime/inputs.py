"""Files that a component setting names: ``builtin:NAME`` (a checkpoint shipped in ata/weights)
or a path. Trainers and components read checkpoints through ``ata.training``, which takes these
from here; a session hashes them into its plan keys (``Session.inputs``).

A *family* of shipped weights is named without its setting: ``builtin:ata_hrl`` stands for
``ata_hrl_a`` (trained on setting (a)) and ``ata_hrl_b_ft`` (fine-tuned on (b)). `weights_for`
resolves a family to the member that suits a mission's team: the member of the mission's own
setting, or for a custom team the member whose setting is nearest in size (`team_distance`).
"""

from __future__ import annotations

import hashlib
import json
import math
from pathlib import Path
from typing import Any

from ata.core.errors import MissionError
from ata.core.mission import TEAM_SETTINGS

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


def read_json_object(path: str | Path, what: str) -> dict[str, Any]:
    """The JSON object in the file at `path` (`what` it is, for the message); a file missing,
    unreadable, not JSON or not an object is one MissionError naming it."""
    try:
        data = json.loads(Path(path).read_text(encoding="utf-8"))
    except OSError as exc:
        raise MissionError("", None, f"cannot read {what}: {exc.strerror or exc}",
                           file=str(path)) from None
    except ValueError as exc:           # not JSON, or not UTF-8
        raise MissionError("", None, f"{what} is not JSON ({exc})", file=str(path)) from None
    if not isinstance(data, dict):
        raise MissionError("", None, f"{what} is not a JSON object but a "
                           f"{type(data).__name__}", file=str(path))
    return data


def pinned() -> dict[str, str]:
    """The pinned digests of the shipped checkpoints (`PINNED`); a missing or broken file is a
    MissionError saying to reinstall."""
    try:
        return read_json_object(PINNED, "the pinned digests of ata's shipped checkpoints")
    except MissionError as exc:
        raise MissionError("", None, f"{exc}: reinstall ata") from None


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


def family(name: str) -> dict[str, str]:
    """The shipped members of a family of weights, setting -> checkpoint name: ``NAME_S.pt``
    (trained on setting S) or ``NAME_S_ft.pt`` (fine-tuned on it; preferred)."""
    members: dict[str, str] = {}
    for path in sorted(WEIGHTS.glob(f"{name}_*.pt")):
        suffix = path.stem[len(name) + 1:]
        for setting in TEAM_SETTINGS:       # sorted: NAME_S before NAME_S_ft, which wins
            if suffix in (setting, f"{setting}_ft"):
                members[setting] = path.stem
    return members


def team_distance(humans: int, robots: int, tasks: int, setting: str) -> float:
    """How far a team is from a team setting's: the sum over humans, robots and POIs of the
    absolute log-ratio of the sizes (a team twice the setting's in every count: 3 log 2)."""
    base = TEAM_SETTINGS[setting]
    return sum(abs(math.log(x / y)) for x, y in ((humans, base.humans), (robots, base.robots),
                                                  (tasks, base.tasks)))


def weights_for(spec: str, team: Any) -> str:
    """The checkpoint a setting value names for a team (`team`: the [mission] settings, with
    ``setting``, ``humans``, ``robots`` and ``tasks``): ``builtin:FAMILY`` (no file of that
    name, but members, see `family`) becomes its member of the team's setting, or for a custom
    team its member nearest in size; any other value is returned as it is."""
    if not spec.startswith("builtin:"):
        return spec
    name = spec.split(":", 1)[1]
    members = family(name)
    if (WEIGHTS / f"{name}.pt").is_file() or not members:
        return spec
    setting = team.setting if team.setting in members else min(
        members, key=lambda s: (team_distance(team.humans, team.robots, team.tasks, s), s))
    return f"builtin:{members[setting]}"


def shipped_setting(spec: str) -> str | None:
    """The team setting a ``builtin:`` checkpoint was trained (or fine-tuned) on, read from its
    name; None for a path or a name of no setting."""
    if not spec.startswith("builtin:"):
        return None
    stem = spec.split(":", 1)[1]
    for setting in TEAM_SETTINGS:
        if stem.endswith(f"_{setting}") or stem.endswith(f"_{setting}_ft"):
            return setting
    return None
