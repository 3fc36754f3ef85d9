"""Output folders: where they go by default, how they are named (from names a user chose, made
safe), and their preparation and writing, whose I/O errors become one clear message.

Every command that writes a folder (`ata run`, `eval`, `train`, `report`, `show`) names and
prepares it here, so that a mission name such as ``../../x`` or ``/elsewhere/x`` can never
place a folder outside runs/, a folder another kind of command wrote is refused (not
overwritten), and a full disk or an unwritable path is one message with exit status 2 (a
`MissionError`), not a traceback.
"""

from __future__ import annotations

import contextlib
import json
import os
import re
import shutil
import time
from pathlib import Path
from typing import Iterator

from ata.core.errors import MissionError


def runs_root() -> Path:
    """Where output folders go by default: $ATA_RUNS, else runs/."""
    return Path(os.environ.get("ATA_RUNS", "runs"))


NAME_LIMIT = 80
"""Characters of a user's label kept in a folder name: a file name may hold 255 bytes, and a
folder name is also a line of terminal text."""


def safe_name(text: str, fallback: str = "run") -> str:
    """A form of a user's label that is one plain file name: no separator, no '..', no leading
    dot, no control character, at most `NAME_LIMIT` characters ('w/o.AUX' -> 'w_o.AUX',
    '../../x' -> 'x', '/elsewhere/x' -> 'elsewhere_x')."""
    name = re.sub(r"_+", "_", re.sub(r"[^A-Za-z0-9._-]+|\.\.+", "_", text[:4 * NAME_LIMIT]))
    return name.strip("._-")[:NAME_LIMIT].strip("._-") or fallback


def shown_path(path: str | Path) -> str:
    """A path as output meant for sharing shows it, without the machine's folders: relative to
    the working folder where it is under it, else ``~/...`` under the home folder, else as it
    is (a path the user chose elsewhere)."""
    text = str(path)
    if not Path(text).is_absolute():
        return text
    try:
        resolved = Path(text).resolve()
    except (OSError, RuntimeError):
        return text
    for root, prefix in ((Path.cwd, ""), (Path.home, "~/")):
        try:
            return prefix + str(resolved.relative_to(root().resolve()))
        except (OSError, ValueError, RuntimeError, KeyError):
            continue
    return text


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


KINDS: dict[str, tuple[str, tuple[str, ...], str]] = {
    "seeds": ("training seeds", ("seeds.json",), "resume them with ata train --resume {dir}"),
    "train": ("a training run", ("checkpoint.pt", "best.pt", "log.csv"),
              "resume it with ata train --resume {dir}"),
    "eval": ("an evaluation", ("eval.json",), "go on with it with ata eval --out {dir}"),
    "run": ("a run", ("summary.json",), "go on with it with ata run --out {dir}"),
    "show": ("the pictures of ata show", ("show_map.png", "show_timeline.png",
                                          "show_humans.png", "show_map.gif"),
             "replace them with ata show --out {dir}"),
    "report": ("a report", ("report.md", "curves.md"), "replace it with ata report --out {dir}"),
    "site": ("a results page", ("site.json",), "rebuild it with ata site ... --out {dir}"),
}
"""The kinds of folder the commands write: what each is, the files that mark it (the first
kind whose file is there wins: a report is written into the folder it reads), and the command
that goes on with (or replaces) it."""


def folder_kind(path: str | Path) -> tuple[str, list[str]] | None:
    """The kind of command that wrote `path` (a `KINDS` key) and the files that show it; None
    for a folder that is missing, empty of them, or not a folder. A run or an evaluation that
    has not finished yet is known by its plan.json."""
    path = Path(path)
    if not path.is_dir():
        return None
    for kind, (_, marks, _) in KINDS.items():
        held = [n for n in marks if (path / n).exists()]
        if held:
            return kind, held
    plan = _plan(path)
    if plan is not None:        # an unfinished run or evaluation: its plan says which
        made = plan.get("command") or ("eval" if "paths" in plan else "run")
        return str(made), ["plan.json"]
    return None


def _plan(path: Path) -> dict | None:
    try:
        plan = json.loads((path / "plan.json").read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    return plan if isinstance(plan, dict) else None


def refuse_other_kind(path: str | Path, kind: str, reads: tuple[Path, ...] = ()) -> None:
    """A MissionError when `path` holds what another kind of command wrote (`KINDS`): writing
    there would overwrite its files (a resolved mission, results.csv, report.md) and leave a
    folder that neither command can go on with. A report may also go into a folder it reads."""
    found = folder_kind(path)
    if found is None or found[0] == kind:
        return
    if kind == "report" and any(_same(path, r) for r in reads):
        return
    what, _, goes_on = KINDS.get(found[0], (f"another command's output ({found[0]})", (), ""))
    hint = f", or {goes_on.format(dir=path)}" if goes_on else ""
    raise MissionError("--out", None, f"{path} is the folder of {what} "
                       f"({', '.join(found[1])}); choose another folder{hint}")


def _same(a: str | Path, b: str | Path) -> bool:
    try:
        return Path(a).resolve() == Path(b).resolve()
    except OSError:
        return False


def prepare_out_dir(path: str | Path, kind: str | None = None,
                    reads: tuple[Path, ...] = ()) -> Path:
    """Create the output folder and check that it can be written, before any work is done; a
    path under a file, a file, or a folder without write permission is one clear error. With
    `kind` (the `KINDS` key of the calling command), a folder another kind of command wrote is
    refused (`refuse_other_kind`)."""
    path = Path(path)
    too_long = next((part for part in path.parts if len(os.fsencode(part)) > 255), None)
    if too_long is not None:        # the system's limit on one name; its error says no more
        raise MissionError("--out", None, f"cannot write to {path}: a folder name of "
                           f"{len(os.fsencode(too_long)):,} bytes, more than the 255 a "
                           "file name may hold")
    if kind is not None:
        try:
            refuse_other_kind(path, kind, reads)
        except OSError as exc:
            raise MissionError("--out", None, f"cannot write to {path}: "
                               f"{exc.strerror or exc}") from None
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


def replace_folder(out: str | Path, files: dict[str, bytes]) -> Path:
    """Write `files` (name: bytes) as the folder `out`, whole or not at all: they are written
    and synced in a temporary folder beside it, which then takes `out`'s name. A folder already
    at `out` (one holding only these names: an earlier version of the same set) is left as it
    was until the new one is whole, so a full disk or a killed process never leaves it half
    written. A file at `out`, or a folder holding other files, is refused."""
    out = Path(out)
    target = Path(os.path.abspath(out))
    if target.exists() and not target.is_dir():
        raise MissionError("--out", None, f"cannot write to {out}: it is a file")
    if target.is_dir():
        try:
            other = sorted(p.name for p in target.iterdir() if p.name not in files)
        except OSError as exc:
            raise MissionError("--out", None, f"cannot read {out}: "
                               f"{exc.strerror or exc}") from None
        if other:
            raise MissionError("--out", None, f"{out} holds other files than "
                               f"{', '.join(files)} ({', '.join(other[:3])}"
                               f"{', ...' if len(other) > 3 else ''}); choose another folder")
    prepare_out_dir(target.parent)
    tmp = target.with_name(f".{target.name}.{os.getpid()}.new")   # mkdir: the umask's mode
    old = tmp.with_suffix(".old")
    name = ""
    try:
        shutil.rmtree(tmp, ignore_errors=True)          # one left by a killed process
        tmp.mkdir()
        for name, data in files.items():
            with open(tmp / name, "wb") as f:
                f.write(data)
                f.flush()
                os.fsync(f.fileno())
        name = ""
        had = target.is_dir()
        if had:
            os.rename(target, old)
        try:
            os.rename(tmp, target)
        except OSError:
            if had:
                os.rename(old, target)
            raise
    except OSError as exc:
        where = out / name if name else out
        kept = "; it is left as it was" if target.is_dir() else ""
        raise MissionError("--out", None, f"cannot write {where}: "
                           f"{exc.strerror or exc}{kept}") from None
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
        shutil.rmtree(old, ignore_errors=True)
    return out
