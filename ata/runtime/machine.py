"""What made a run's rows, recorded in its folder: the machine (shown with the time columns),
and the provenance (`provenance.json`: ata's version and the model revision it implements, the
git commit of a checkout and whether its tree was dirty, the versions of the packages that
compute results, the machine)."""

from __future__ import annotations

import json
import os
import platform
import subprocess
from importlib import metadata
from pathlib import Path
from typing import Any

from ata import __version__

MODEL_REVISION = 3
"""The revision of the benchmark model (the world's specification, MODEL.md) this release of
ata implements: a published set and a run folder's provenance record it."""
PACKAGES = ("numpy", "scipy", "numba", "torch", "pluggy")
"""The packages whose versions can move a result."""
PROVENANCE = "provenance.json"


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


def checkout() -> dict[str, Any] | None:
    """The git commit of the checkout ata runs from, and whether its tracked files differ from
    it (``dirty``); None for an installed ata, or where git cannot tell."""
    root = Path(__file__).resolve().parents[2]
    if not (root / ".git").exists():
        return None
    try:
        commit = subprocess.run(["git", "-C", str(root), "rev-parse", "HEAD"],
                                capture_output=True, text=True, timeout=10)
        status = subprocess.run(["git", "-C", str(root), "status", "--porcelain",
                                 "--untracked-files=no"], capture_output=True, text=True,
                                timeout=10)
    except (OSError, subprocess.TimeoutExpired):
        return None
    if commit.returncode != 0 or status.returncode != 0:
        return None
    return {"commit": commit.stdout.strip(), "dirty": bool(status.stdout.strip())}


def provenance() -> dict[str, Any]:
    """What a run folder records of what made it."""
    packages = {}
    for package in PACKAGES:
        try:
            packages[package] = metadata.version(package)
        except metadata.PackageNotFoundError:
            pass
    return {"ata": __version__, "model_revision": MODEL_REVISION, "checkout": checkout(),
            "packages": packages, "machine": machine()}


def write_provenance(folder: str | Path) -> None:
    """provenance.json in a run folder, as of now."""
    (Path(folder) / PROVENANCE).write_text(json.dumps(provenance(), indent=2) + "\n",
                                           encoding="utf-8")


def provenance_text(folder: str | Path) -> str | None:
    """A folder's provenance.json in a line: 'ata V, commit C (dirty), numpy ..., CPU, N cores';
    None where the folder has none."""
    try:
        info = json.loads((Path(folder) / PROVENANCE).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    if not isinstance(info, dict):
        return None
    revision = info.get("model_revision")
    parts = [f"ata {info.get('ata', '?')}"
             + (f" (model revision {revision})" if revision is not None else "")]
    git = info.get("checkout")
    if isinstance(git, dict):
        parts.append(f"commit {str(git.get('commit', '?'))[:12]}"
                     + (" (uncommitted changes)" if git.get("dirty") else ""))
    packages = info.get("packages") if isinstance(info.get("packages"), dict) else {}
    parts += [f"{k} {v}" for k, v in packages.items()]
    mach = info.get("machine") if isinstance(info.get("machine"), dict) else {}
    parts.append(f"{mach.get('cpu', 'unknown')}, {mach.get('cores', '?')} cores")
    return ", ".join(parts)
