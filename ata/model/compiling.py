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

A cache that cannot be used never stops a command: an entry that cannot be read (an emptied or
truncated file) or written is compiled anew, the entry's index dropped so that the next save
writes a good one; where neither the source's folder nor numba's user cache is writable (a
read-only install with no writable HOME), the cache goes to a folder of this user's under the
system's temporary folder (``NUMBA_CACHE_DIR`` names another), else compiling goes on without
a cache. Each says so in one ``warning:`` line on stderr, once a process.
"""

from __future__ import annotations

import contextlib
import functools
import hashlib
import os
import sys
import tempfile
from pathlib import Path

import numba

_OPTIONS = dict(nogil=True, error_model="numpy")
_MODEL = Path(__file__).resolve().parent
_WARNED: set[str] = set()


def _warn_once(what: str, text: str) -> None:
    if what not in _WARNED:
        _WARNED.add(what)
        sys.stderr.write(f"warning: {text}\n")


def _why(exc: BaseException) -> str:
    lines = str(exc).strip().splitlines()
    return f"{type(exc).__name__}: {lines[0]}" if lines else type(exc).__name__


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

            @contextlib.contextmanager
            def _guard_against_spurious_io_errors(self):
                # around each load and save: an entry that cannot be used is compiled anew
                try:
                    yield
                except Exception as exc:        # whatever a damaged file makes pickle raise
                    index = getattr(self._cache_file, "_index_path", None)
                    with contextlib.suppress(OSError, TypeError):
                        os.unlink(index)
                    _warn_once("entry", f"numba's cache of {self._py_func.__qualname__} "
                               f"could not be used ({_why(exc)}) and is compiled anew "
                               f"(cache folder: {self._cache_path})")

        return Cache
    except (ImportError, AttributeError, TypeError):
        return None


_CACHE = _make_cache()


def _fallback_folder() -> Path | None:
    """This user's numba cache under the system's temporary folder, made private to the user
    (None where it cannot be, or is not the user's own)."""
    folder = Path(tempfile.gettempdir()) / f"ata-numba-{os.getuid()}"
    try:
        folder.mkdir(mode=0o700, exist_ok=True)
        if folder.stat().st_uid != os.getuid() or not os.access(folder, os.W_OK):
            return None
    except OSError:
        return None
    return folder


def _cached(fn, make):
    """`make()`, a compiled `fn` with a cache; where numba finds no writable place for the
    cache, with the cache in `_fallback_folder()`, else with none."""
    try:
        return make()
    except RuntimeError as exc:               # numba: "cannot cache function ...: no locator"
        folder = None if numba.config.CACHE_DIR else _fallback_folder()
        if folder is not None:
            numba.config.CACHE_DIR = str(folder)
            _warn_once("folder", f"numba finds no writable cache folder beside ata or under "
                       f"HOME; compiled code is cached in {folder} (set NUMBA_CACHE_DIR to "
                       "choose another)")
            with contextlib.suppress(RuntimeError):
                return make()
        _warn_once("none", f"numba cannot cache compiled code ({_why(exc)}); compiling "
                   "without a cache (set NUMBA_CACHE_DIR to a writable folder to keep it)")
        return numba.njit(**_OPTIONS)(fn)


def jit(fn):
    """Compile `fn` as the host compiles its loops (see the module's text)."""
    if _CACHE is None or os.environ.get("NUMBA_CACHE_LOCATOR_CLASSES"):
        return _cached(fn, lambda: numba.njit(cache=True, **_OPTIONS)(fn))

    def make():
        dispatcher = numba.njit(**_OPTIONS)(fn)
        dispatcher._cache = _CACHE(fn)
        return dispatcher
    return _cached(fn, make)
