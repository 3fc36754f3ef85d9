"""How the host compiles its loops (numba), and how their compiled code is cached.

`jit` compiles a function with no Python objects, no fast-math (so the same bits as numpy's),
numpy's floating-point errors (a division by zero gives inf or nan, as in numpy), and caches
what it compiles beside its source (``__pycache__``) or, where that is not writable, in numba's
user cache.

numba checks a cached function against its own source file alone, not against the files of the
functions it calls, which it compiles in: a change to `ata.model.scalar` would leave the POI
step's cached code computing a formula its source no longer says. So a function compiled here
is checked, beside its own file, against every Python file of its folder and of the host's
`ata.model` (where the formulas the loops share live): a change to any of them compiles it
again.
"""

from __future__ import annotations

import functools
import hashlib
import os
from pathlib import Path

import numba

_OPTIONS = dict(nogil=True, error_model="numpy")
_MODEL = Path(__file__).resolve().parent


@functools.lru_cache(maxsize=None)
def _folder_digest(folder: Path) -> str:
    """A digest of the names and contents of the folder's Python files (read once a process)."""
    h = hashlib.sha256()
    for path in sorted(folder.glob("*.py")):
        h.update(path.name.encode())
        h.update(path.read_bytes())
    return h.hexdigest()


def _stamp(py_file: str | None) -> tuple[str, ...]:
    folders = {_MODEL} | ({Path(py_file).resolve().parent} if py_file else set())
    return tuple(_folder_digest(f) for f in sorted(folders))


def _make_cache():
    """numba's function cache whose locators add `_stamp` to the source's own; None where this
    numba's cache classes are not the ones this was written against."""
    try:
        from numba.core import caching   # on use: numba's cache internals, probed

        def stamped(cls):
            class Stamped(cls):
                def get_source_stamp(self):
                    return (super().get_source_stamp(),
                            _stamp(getattr(self, "_py_file", None)))
            Stamped.__name__ = Stamped.__qualname__ = f"Stamped{cls.__name__}"
            return Stamped

        class Impl(caching.CompileResultCacheImpl):
            _locator_classes = [stamped(c)
                                for c in caching.CompileResultCacheImpl._locator_classes]

        class Cache(caching.FunctionCache):
            _impl_class = Impl

        return Cache
    except (ImportError, AttributeError, TypeError):
        return None


_CACHE = _make_cache()


def jit(fn):
    """Compile `fn` as the host compiles its loops (see the module's text)."""
    if _CACHE is None or os.environ.get("NUMBA_CACHE_LOCATOR_CLASSES"):
        return numba.njit(cache=True, **_OPTIONS)(fn)
    dispatcher = numba.njit(**_OPTIONS)(fn)
    dispatcher._cache = _CACHE(fn)
    return dispatcher
