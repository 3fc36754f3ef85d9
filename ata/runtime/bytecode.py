"""ata's own code as its sources say, for a run that keeps untrusted methods apart (`--isolate`).

Python runs a module from its cached bytecode (``__pycache__/*.pyc``) when the file's header
matches the source's modification time and size, without reading the source; anything that
could write there before (a method once run in-process, say) could have planted bytecode that
does something else. `guard` makes the rest of the process compile ata's modules from their
sources, never from a cache, and checks every cached file of ata's package against its source
(a worker process loads them from the cache).
"""

from __future__ import annotations

import importlib.machinery
import importlib.util
import marshal
import sys
from pathlib import Path
from typing import Any

PACKAGE = "ata"


class _SourceLoader(importlib.machinery.SourceFileLoader):
    """A loader that compiles its module from the source file, whatever the cache holds."""

    def get_code(self, fullname: str) -> Any:
        path = self.get_filename(fullname)
        return self.source_to_code(self.get_data(path), path)


class _SourceFinder:
    """Finds ata's modules as the path finder does, with `_SourceLoader` as their loader."""

    @staticmethod
    def find_spec(name: str, path: Any = None, target: Any = None) -> Any:
        if name != PACKAGE and not name.startswith(PACKAGE + "."):
            return None
        spec = importlib.machinery.PathFinder.find_spec(name, path, target)
        if spec is not None and type(spec.loader) is importlib.machinery.SourceFileLoader:
            spec.loader = _SourceLoader(spec.loader.name, spec.loader.path)
        return spec


def mismatch(source: str) -> str | None:
    """The bytecode file of a source file of ata where it is a cache Python would run (a
    timestamp cache that matches the file, or a hash-based one) but not what the source
    compiles to; None where there is none, or it is the source's."""
    cached = importlib.util.cache_from_source(source)
    try:
        with open(cached, "rb") as f:
            data = f.read()
        with open(source, "rb") as f:
            text = f.read()
    except OSError:
        return None                      # no cache: the source is compiled
    loader = importlib.machinery.SourceFileLoader("_", source)
    try:
        flags = int.from_bytes(data[4:8], "little")
        stats = loader.path_stats(source)
        if flags == 0 and (int.from_bytes(data[8:12], "little")
                           != int(stats["mtime"]) & 0xFFFFFFFF
                           or int.from_bytes(data[12:16], "little")
                           != stats["size"] & 0xFFFFFFFF):
            return None                  # stale: Python compiles the source instead
        code = marshal.loads(data[16:])
    except (ValueError, EOFError, TypeError, OSError):
        return cached
    return None if code == loader.source_to_code(text, source) else cached


def guard() -> None:
    """From now on, compile ata's modules from their sources in this process; and refuse (a
    MissionError) where a bytecode file of ata's package is not what its source compiles to
    (a worker process, which loads them from the cache, would run it)."""
    from ata.core.errors import MissionError     # on use: this module imports no ata module
    if _SourceFinder not in sys.meta_path:
        sys.meta_path.insert(0, _SourceFinder)
    root = Path(__file__).resolve().parents[1]
    planted = [p for p in (mismatch(str(f)) for f in sorted(root.rglob("*.py"))) if p]
    if planted:
        raise MissionError("--isolate", None, f"{len(planted)} bytecode file(s) of ata are not "
                           f"what their sources compile to ({planted[0]}): something changed "
                           "them; delete ata's __pycache__ folders (python -c 'import ata' "
                           "makes them again) and run again")
