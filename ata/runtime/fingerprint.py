"""What a component in the host's process could change that others read: the module state of
the kernel (``ata.core``) and of the domain library (``ata.model``): their tables, constants,
functions and classes. `check_component` fingerprints it around a component's runs and holds it
against the sources, so that a component that edits a table or patches the kernel or the world's
generator fails its checks.
"""

from __future__ import annotations

import hashlib
import importlib.util
import sys
import types
from pathlib import Path
from typing import Any

import numpy as np

SHARED = ("ata.core", "ata.model")
"""The packages whose module state every component reads."""
ROOT = Path(__file__).resolve().parents[1]


def _modules() -> list[tuple[str, types.ModuleType]]:
    return sorted((name, m) for name, m in list(sys.modules.items())
                  if isinstance(m, types.ModuleType)
                  and any(name == p or name.startswith(p + ".") for p in SHARED))


def _value(value: Any) -> str | None:
    """A digest of a module global that is data (an array, a number, a text, a tuple of them),
    or of the code of a function; None for anything else."""
    if isinstance(value, np.ndarray):
        return hashlib.sha256(value.dtype.str.encode() + str(value.shape).encode()
                              + np.ascontiguousarray(value).tobytes()).hexdigest()
    if isinstance(value, (int, float, str, bytes, bool, tuple, frozenset)) or value is None:
        return hashlib.sha256(repr(value).encode()).hexdigest()
    code = getattr(value, "__code__", None)
    if isinstance(code, types.CodeType):
        return _code(code)
    return None


def _code(code: types.CodeType) -> str:
    """A digest of a code object's instructions, constants and names (its nested functions' by
    their own digests, not by where they happen to lie in memory)."""
    consts = [_code(c) if isinstance(c, types.CodeType) else repr(c) for c in code.co_consts]
    return hashlib.sha256(code.co_code + repr((consts, code.co_names)).encode()).hexdigest()


def state() -> dict[str, str]:
    """'module.name' (and 'module.Class.attribute') -> a digest, for every data global, function
    and class attribute of the shared packages' modules loaded now."""
    return {f"{name}.{k}": v for name, module in _modules() for k, v in _own(name, module).items()}


def changed(before: dict[str, str], after: dict[str, str]) -> list[str]:
    """The names whose value or code differs between two `state`s (or that one lacks)."""
    return sorted(k for k in before.keys() | after.keys() if before.get(k) != after.get(k))


def _fresh(name: str, module: types.ModuleType) -> types.ModuleType | None:
    """The module executed afresh from its source, apart from the loaded one (None where it
    cannot be)."""
    spec = importlib.util.spec_from_file_location(f"_ata_fresh_{name}", module.__file__)
    fresh = importlib.util.module_from_spec(spec)
    try:
        spec.loader.exec_module(fresh)
    except Exception:                    # noqa: BLE001 - a module that cannot be made again
        return None
    return fresh


def _own(name: str, module: types.ModuleType) -> dict[str, str]:
    """`state`'s digests of one module's globals and class attributes."""
    out: dict[str, str] = {}
    for key, value in list(vars(module).items()):
        if key.startswith("__"):
            continue
        if isinstance(value, type) and value.__module__ in (name, module.__name__):
            for attr, member in list(vars(value).items()):
                if attr in ("__module__", "__qualname__", "__doc__"):
                    continue
                digest = _value(getattr(member, "__func__", member))
                if digest is not None:
                    out[f"{key}.{attr}"] = digest
            continue
        digest = _value(value)
        if digest is not None:
            out[key] = digest
    return out


def against_sources() -> list[str]:
    """The tables, constants, functions and class attributes of the shared packages' loaded
    modules that differ from what their sources make (each module executed afresh): edited or
    patched by something else, a component's import-time code say."""
    out = []
    for name, module in _modules():
        if not getattr(module, "__file__", None) or not module.__file__.endswith(".py"):
            continue
        fresh = _fresh(name, module)
        if fresh is None:
            continue
        mine, theirs = _own(name, module), _own(name, fresh)
        out += [f"{name}.{k}" for k in sorted(mine) if k in theirs and mine[k] != theirs[k]]
    return out
