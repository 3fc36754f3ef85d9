"""The machine a run was made on, recorded beside its rows (eval.json) and shown with its time
columns."""

from __future__ import annotations

import os
import platform
from importlib import metadata
from typing import Any


def machine() -> dict[str, Any]:
    """What ran an evaluation, for the time columns of its tables: the CPU's model name, the
    cores the process may use, the system, and the Python, numpy and torch versions."""
    cpu = platform.processor()
    try:
        with open("/proc/cpuinfo", encoding="utf-8") as f:
            cpu = next((line.split(":", 1)[1].strip() for line in f
                        if line.startswith("model name")), cpu)
    except OSError:
        pass
    try:
        cores = len(os.sched_getaffinity(0))
    except AttributeError:                                  # not on Linux
        cores = os.cpu_count() or 0
    out = {"cpu": cpu or "unknown", "cores": cores, "system": platform.platform(),
           "python": platform.python_version()}
    for package in ("numpy", "torch"):
        try:
            out[package] = metadata.version(package)
        except metadata.PackageNotFoundError:
            pass
    return out


def machine_text(info: dict[str, Any]) -> str:
    """`machine`'s record in a line: 'CPU, N cores (system; Python X, torch Y)'."""
    versions = "; ".join(f"{k} {info[k]}" for k in ("python", "numpy", "torch") if k in info)
    return f"{info.get('cpu', 'unknown')}, {info.get('cores', '?')} cores ({versions})"
