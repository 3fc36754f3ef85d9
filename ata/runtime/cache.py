"""The run-scoped cache folder, for results that depend on the scenario alone.

`ata eval` sets it around each unit of work (`--cache DIR`, `$ATA_CACHE` or ``~/.cache/ata``;
none with ``--no-cache``). A component that can reuse such results, such as the ITA-MILP
baseline's solved allocations, asks ``cache_dir()`` and keeps its files in a subfolder named
after itself; ``None`` means no caching. The core knows nothing of what is cached.
"""

from __future__ import annotations

import contextlib
from contextvars import ContextVar
from pathlib import Path
from typing import Iterator

_CACHE: ContextVar[Path | None] = ContextVar("ata_cache_dir", default=None)


def cache_dir() -> Path | None:
    """The folder of the run's cache, or None when caching is off."""
    return _CACHE.get()


@contextlib.contextmanager
def run_cache(path: str | Path | None) -> Iterator[Path | None]:
    """Make `path` the cache folder inside the block (None: no cache)."""
    token = _CACHE.set(Path(path).expanduser() if path is not None else None)
    try:
        yield _CACHE.get()
    finally:
        _CACHE.reset(token)
