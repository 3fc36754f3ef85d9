"""What the results page shows of each set of rows it is built from: a published set
(``published``, ``published:NAME``, ``published:PATH``) or a result folder (`ata eval`'s or
`ata run`'s), read with what made it.

Everything here is read from the set's own files: its rows, its manifest (a published set) or
its plugins.toml, resolved missions, eval.json and provenance.json (a folder), and the shipped
checkpoints a learned method's cells read (their training seeds). Nothing is typed in.
"""

from __future__ import annotations

import functools
import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ata.core.errors import MissionError
from ata.core.mission import loads_toml
from ata.published.sets import (RESOLVED_TABLES, cell_name, folder_parts, is_published,
                                mission_inputs, read_published, world_digest)
from ata.results.rows import Results, read_results
from ata.runtime.folders import safe_name
from ata.runtime.machine import PROVENANCE
from ata.training.checkpoints import VALIDATION_SEED_OFFSET, CheckpointError, read_checkpoint
from ata.runtime.inputs import resolve


@dataclass
class Weights:
    """One checkpoint file a learned method's cell read."""

    setting: str          # the component setting that names it ('ctr.checkpoint')
    spec: str             # as the mission names it ('builtin:ata_hrl_a', a path)
    digest: str           # the content digest the set records
    trained: list[str] = field(default_factory=list)
    seeds: list[int] = field(default_factory=list)
    """The root seeds its training drew scenarios from (validation seeds left out); the first
    is the trainer's ``seed``. Empty where the file installed now is not the one recorded."""


@dataclass
class MethodInfo:
    """One method of a set: its code, versions and, per cell ('a/low'), what the cell read."""

    name: str
    code: dict[str, str]
    versions: dict[str, str]
    cells: dict[str, dict[str, Any]]
    """cell -> {mission, model, inputs, time_s, seed, scenarios}"""
    weights: dict[str, list[Weights]] = field(default_factory=dict)
    """cell -> the checkpoints it read (none: not a learned method)."""
    seeds: list[int] | None = None
    """The training seeds the set's manifest names for the method (``training_seeds``), if
    it names them; else they are read from the checkpoints."""

    @property
    def learned(self) -> bool:
        return bool(self.seeds) or any(self.weights.values())

    def training_seeds(self) -> list[int]:
        """The seeds of the training runs behind the method's weights: the manifest's, else
        the trainer seed of every checkpoint it read (one per training run)."""
        if self.seeds:
            return sorted(self.seeds)
        seeds = {w.seeds[0] for ws in self.weights.values() for w in ws if w.seeds}
        return sorted(seeds)


@dataclass
class Source:
    """One set of rows the page is built from, with what made it."""

    name: str             # 'paper', or the folder's name
    spec: str             # what names it on the command line, without a machine's path
    kind: str             # 'published' or 'folder'
    results: Results
    methods: dict[str, MethodInfo]
    release: str | None = None
    ata: str | None = None
    packages: dict[str, str] = field(default_factory=dict)
    machine: dict[str, Any] = field(default_factory=dict)
    commit: str | None = None
    isolated: bool | None = None
    seed_public: bool = True
    digest: str | None = None       # a published set's rows_sha256
    model_revision: str | None = None   # the benchmark model's revision a set names
    command: str = ""               # the command that made the rows
    locator: str = ""               # what reads it here (a published set's spec, a path)

    @property
    def slug(self) -> str:
        return safe_name(self.name, "set")


def load_source(spec: str | Path) -> Source:
    """A published set or a result folder, read with what made it."""
    if is_published(spec):
        return _published(str(spec))
    return _folder(Path(spec))


def _published(spec: str) -> Source:
    results, manifest, folder = read_published(spec)
    methods = {}
    for name, entry in manifest.get("methods", {}).items():
        cells = {}
        for cell, info in entry.get("cells", {}).items():
            cells[cell] = {"mission": info.get("mission", ""), "model": info.get("model"),
                           "inputs": dict(info.get("inputs", {})),
                           "time_s": info.get("time_per_scenario_s"),
                           "seed": str(info.get("seed")), "scenarios": info.get("scenarios")}
        declared = entry.get("training_seeds")
        methods[name] = MethodInfo(name, dict(entry.get("code", {})),
                                   dict(entry.get("versions", {})), cells,
                                   seeds=[int(x) for x in declared]
                                   if isinstance(declared, list) else None)
    machine = manifest.get("machine") or {}
    seeds = {c["seed"] for m in methods.values() for c in m.cells.values()}
    public = manifest.get("seed_public")
    named = spec.split(":", 1)[1] if ":" in spec else folder.name
    source = Source(
        name=folder.name, spec=f"published:{named}" if "/" not in named else
        f"published:{folder.name}", kind="published", results=results, methods=methods,
        # a set published before sets were named by release: the version that published it
        release=_text(manifest.get("release") or manifest.get("ata")),
        ata=_text(manifest.get("ata")),
        packages={k: str(machine[k]) for k in ("numpy", "torch") if k in machine},
        machine=machine, commit=_commit(manifest.get("commit"), manifest.get("dirty")),
        isolated=_flag(manifest.get("isolated", manifest.get("isolate", _UNKNOWN))),
        seed_public=bool(public) if public is not None else
        not any(s.startswith("secret:") for s in seeds),
        digest=manifest.get("rows_sha256"), locator=spec,
        model_revision=_text(manifest.get("model_revision")))
    if isinstance(manifest.get("packages"), dict):
        source.packages.update({str(k): str(v) for k, v in manifest["packages"].items()})
    _read_weights(source)
    return source


def _folder(folder: Path) -> Source:
    if not folder.is_dir():
        raise MissionError("", None, "no such folder: give a result folder (`ata eval`, "
                           "`ata run`) or published[:NAME]", file=str(folder))
    results = read_results(folder)
    plugins, missions = folder_parts(folder, results)
    cols = results.columns
    methods = {}
    for name in results.methods:
        code = dict(plugins.get("code", {}).get(name, {}))
        cells = {}
        for _, setting, level in [c for c in results.cells() if c[0] == name]:
            sel = results.select(name, setting, level)
            text = missions.get((name, setting, level), "")
            wall = cols["wall_s"][sel] if "wall_s" in cols else np.array([])
            ids = sorted(int(i) for i in cols["scenario"][sel])
            cells[cell_name(setting, level)] = {
                "mission": text, "model": world_digest(loads_toml(text), code) if text else None,
                "inputs": mission_inputs(text) if text else {},
                "time_s": round(float(np.mean(wall)), 4) if wall.size else None,
                "seed": str(cols["seed"][sel][0]), "scenarios": [ids[0], len(ids)]}
        methods[name] = MethodInfo(name, code, dict(plugins.get("methods", {}).get(name, {})),
                                   cells)
    meta = _json(folder / "eval.json")
    prov = _json(folder / PROVENANCE)
    args = meta.get("arguments") if isinstance(meta.get("arguments"), dict) else {}
    git = prov.get("checkout") if isinstance(prov.get("checkout"), dict) else {}
    summary = _json(folder / "summary.json")
    seeds = {c["seed"] for m in methods.values() for c in m.cells.values()}
    isolated = args.get("isolate") if meta else summary.get("isolate", _UNKNOWN)
    source = Source(
        name=folder.resolve().name, spec=folder.resolve().name, kind="folder", results=results,
        methods=methods, ata=_text(prov.get("ata") or plugins.get("ata")),
        packages={str(k): str(v) for k, v in (prov.get("packages") or {}).items()},
        machine=dict(prov.get("machine") or meta.get("machine") or {}),
        commit=_commit(git.get("commit"), git.get("dirty")),
        isolated=_flag(isolated),
        seed_public=not any(s.startswith("secret:") for s in seeds), locator=str(folder))
    paths = args.get("paths") if isinstance(args.get("paths"), list) else None
    source.command = (f"ata eval {' '.join(Path(p).name for p in paths)} -o {source.name}"
                      if paths else f"ata run {source.name}/mission.resolved.toml -o RERUN")
    _read_weights(source)
    return source


def _read_weights(source: Source) -> None:
    """Each learned method's checkpoints, per cell, and the seeds their training drew from
    (read from the file installed now, where it is the one the set records)."""
    for method in source.methods.values():
        for cell, info in method.cells.items():
            if not info["mission"]:
                continue
            tables = loads_toml(info["mission"])
            found = []
            for comp, table in tables.items():
                if comp in RESOLVED_TABLES or not isinstance(table, dict):
                    continue
                spec = table.get("checkpoint")
                key = f"{comp}.checkpoint"
                if isinstance(spec, str) and key in info["inputs"]:
                    found.append(_weights(key, spec, info["inputs"][key]))
            method.weights[cell] = found


def _weights(key: str, spec: str, digest: str) -> Weights:
    seeds, trained = _trained(spec, digest)
    return Weights(key, spec, digest, list(trained), list(seeds))


@functools.lru_cache(maxsize=None)
def _trained(spec: str, digest: str) -> tuple[tuple[int, ...], tuple[str, ...]]:
    """(the training seeds, the trained parts) of the checkpoint `spec` names, read once per
    file; nothing where the file installed now is not the one of `digest`."""
    if mission_inputs(f'[c]\ncheckpoint = "{spec}"\n').get("c.checkpoint") != digest:
        return (), ()
    try:
        data = read_checkpoint(resolve(spec))
    except CheckpointError:
        return (), ()
    roots = list(dict.fromkeys(int(r[0]) for r in data.get("scenario_ranges", [])))
    return (tuple(s for s in roots if s - VALIDATION_SEED_OFFSET not in roots),
            tuple(str(p) for p in data.get("trained", [])))


def _json(path: Path) -> dict[str, Any]:
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return {}
    return data if isinstance(data, dict) else {}


def _commit(commit: Any, dirty: Any) -> str | None:
    if not commit:
        return None
    return str(commit)[:12] + (" (with uncommitted changes)" if dirty else "")


def _text(value: Any) -> str | None:
    return None if value is None else str(value)


_UNKNOWN = object()
"""A field the set's files do not hold."""


def _flag(value: Any) -> bool | None:
    """Whether the decisions ran isolated: None where the files do not say (a set published
    before the field was recorded); an eval.json's ``isolate`` is None when they did not."""
    return None if value is _UNKNOWN else bool(value)
