"""Published rows: the per-scenario rows of an evaluation, shipped as package data with what they
were made with, so that a new method is paired against them without running them again.

A set of published rows is a folder (under ``ata/published/NAME``, or anywhere) of two files:

* ``rows.csv.gz``: the evaluation's results.csv, gzipped, without its time columns (``wall_s``,
  ``milp_solve_s``: the time a row took depends on the machine, not on the method);
* ``manifest.json``: the release the set belongs to (``release``, the ata version that
  published it, shown as ``NAME@RELEASE``, e.g. ``paper@0.2.0``) and the revision of the
  benchmark model (``model_revision``, MODEL.md's), whether its seed is public (``seed_public``)
  and whether its methods ran isolated (``isolated``), the git commit of the checkout that ran
  them (``commit``, ``dirty``) and the package versions (``packages``) where the evaluation
  recorded them, and per method its component versions and the
  digest of each component's code (``code``), and per (setting, level) cell the digests of the
  weights it read (``inputs``: a method may read other weights in each setting), its resolved
  mission, its scenario ids (first, count) and the *model revision* of the cell: the digest of
  the world the scenarios ran in (the world components' code, their settings and the [mission]
  keys that shape the scenarios), with the cell's mean time per scenario
  (``time_per_scenario_s``) and the machine that took it (``machine``, as the evaluation's
  eval.json records it).

`publish` writes one from an `ata eval` folder (`ata publish EVAL_DIR --out DIR`). `check_pairing`
refuses to pair a folder of results against a set when the folder was made by another ata
release than the set's, a cell's scenarios are not among the set's, its model revision differs,
or the code or the cell's weights of a published method differ from those installed now.

``ata.experiment.reproduce.rerun_sample`` reruns a sample of a set's rows and names every row
that is not identical; `ata.published.backend` reads a suite's ``published:METHOD`` from a set.

A manifest written before sets were named by release (no ``release``, ``model_revision`` or
``seed_public``) is read as follows: its release is its ``ata`` (the version that published it),
its model revision is not shown, its seed is public unless a cell's seed is a ``secret:`` label.
The *model revision* of a set (``model_revision``: the revision of the benchmark model, MODEL.md,
`ata.runtime.machine.MODEL_REVISION`) is not a cell's ``model``, the digest of the world its
scenarios ran in.

The reference code and weights are checked against the installed ones from each published
method's resolved mission: a set is valid for the version whose code made it.
"""

from __future__ import annotations

import csv
import gzip
import hashlib
import io
import json
import tempfile
from pathlib import Path
from typing import Any

import numpy as np

from ata import __version__
from ata.core.components import WORLD_KINDS
from ata.core.errors import MissionError
from ata.core.mission import loads_toml
from ata.results.rows import Results, read_results
from ata.results.seeds import seed_groups, split_seed
from ata.runtime.folders import replace_folder, safe_name, shown_path
from ata.runtime.machine import MODEL_REVISION, PROVENANCE
from ata.runtime.inputs import read_json_object
from ata.session import inputs_of, load_session

PUBLISHED = Path(__file__).resolve().parent
"""The sets that ship with ata, one folder each."""
DEFAULT = "paper"
"""The set ``published`` names alone."""
ROWS, MANIFEST = "rows.csv.gz", "manifest.json"
FORMAT = 1
"""The components whose code and settings make the world a method is scored in."""
WORLD_MISSION_KEYS = ("setting", "humans", "robots", "tasks", "horizon_s", "epoch_s",
                      "tick_s", "uncertainty", "fatigue_variance", "event_probability")
RESOLVED_TABLES = ("mission", "components", "references")
"""The tables of a resolved mission that are not a component's settings."""
DROPPED = ("wall_s", "milp_solve_s")
"""results.csv columns left out of published rows: times, which depend on the machine."""
DEFINED_COLUMNS = ("score", "upper_bound", "reallocations")
"""The columns `rerun_sample` always compares (every other numeric column of the rows too)."""


PREFIX = "published:"
"""How a suite's method or a compare argument names published rows: ``published:NAME``."""


def is_published(spec: str | Path) -> bool:
    """Whether a compare argument names published rows (``published``, ``published:NAME`` or
    ``published:PATH``) rather than a result folder."""
    return str(spec) == "published" or str(spec).startswith(PREFIX)


def locate(spec: str | Path) -> Path:
    """The folder of a set: ``published`` the default set, ``published:NAME`` a shipped one,
    ``published:PATH`` (or a PATH) a folder with a manifest.json."""
    text = str(spec)
    name = text.split(":", 1)[1] if ":" in text else DEFAULT if text == "published" else text
    shipped = sorted(p.parent.name for p in PUBLISHED.glob(f"*/{MANIFEST}"))
    for folder in (PUBLISHED / name, Path(name).expanduser()):
        if (folder / MANIFEST).is_file() and (folder / ROWS).is_file():
            return folder
    raise MissionError("", None, f"no published rows {name!r}: shipped sets: "
                       f"{', '.join(shipped) or '(none in this version yet)'}; or give "
                       f"published:PATH, a folder that `ata publish` wrote", file=text)


def release(manifest: dict[str, Any]) -> str:
    """The ata release a set belongs to: its ``release``, else (a set published before sets
    were named by release) the ``ata`` version that published it."""
    return str(manifest.get("release") or manifest.get("ata") or "unknown")


def seed_public(manifest: dict[str, Any]) -> bool:
    """Whether a set's seed is public: its ``seed_public``, else whether no cell's seed is the
    ``secret:`` label of a secret one."""
    if isinstance(manifest.get("seed_public"), bool):
        return manifest["seed_public"]
    return not any(str(info.get("seed", "")).startswith("secret:")
                   for entry in manifest.get("methods", {}).values()
                   for info in entry.get("cells", {}).values())


def shown(folder: str | Path) -> str:
    """How output names a set's folder, without a path of this machine: ``published:NAME`` for
    a shipped set, else the path relative to the working folder (as given where it is not
    under it)."""
    folder = Path(folder)
    try:
        if folder.resolve().parent == PUBLISHED:
            return f"{PREFIX}{folder.name}"
    except OSError:
        pass
    return relative(folder)


def relative(path: str | Path) -> str:
    """A path relative to the working folder where it is under it (`shown_path`)."""
    return shown_path(path)


def set_name(folder: str | Path, manifest: dict[str, Any]) -> str:
    """A set named by its release: ``NAME@RELEASE`` (``paper@0.2.0``), NAME its folder's."""
    return f"{Path(folder).name}@{release(manifest)}"


def describe(folder: str | Path, manifest: dict[str, Any]) -> str:
    """A set in a line: 'paper@0.2.0 (published:paper; model revision 3; public seed)'."""
    revision = manifest.get("model_revision")
    parts = [shown(folder)] + ([f"model revision {revision}"] if revision is not None else []) \
        + ["public seed" if seed_public(manifest) else "secret seed"] \
        + (["isolated"] if manifest.get("isolated") else [])
    return f"{set_name(folder, manifest)} ({'; '.join(parts)})"


def folder_release(folder: str | Path) -> str | None:
    """The ata release that made a result folder's rows: its plugins.toml's ``ata``, else its
    provenance.json's or eval.json's; None where none says."""
    folder = Path(folder)
    try:
        version = _read_toml(folder / "plugins.toml").get("ata")
        if version:
            return str(version)
    except (OSError, ValueError):
        pass
    for name in (PROVENANCE, "eval.json"):
        try:
            data = json.loads((folder / name).read_text(encoding="utf-8"))
        except (OSError, ValueError):
            continue
        if isinstance(data, dict) and data.get("ata"):
            return str(data["ata"])
    return None


def check_release(mine: str | None, folder: str | Path, manifest: dict[str, Any],
                  what: str = "the rows here") -> None:
    """Refuse (MissionError, one line naming both) to pair rows made by ata `mine` with a set of
    another release."""
    theirs = release(manifest)
    if mine is None or mine == theirs:
        return
    raise MissionError("", None, f"{what} were made with ata {mine}, the published set "
                       f"{set_name(folder, manifest)} ({shown(folder)}) with ata {theirs}: rows "
                       f"of two releases are not paired; evaluate with ata {theirs}, or compare "
                       f"with a set published with ata {mine}")


def read_from_sets(folder: str | Path) -> list[str]:
    """The methods of an evaluation read from published sets (a suite's ``published:METHOD``),
    each as 'METHOD: NAME@RELEASE (published:NAME)', from its eval.json; [] for none."""
    out = []
    for job in _json_object(Path(folder) / "eval.json").get("jobs") or []:
        source = str(job.get("mission", "")) if isinstance(job, dict) else ""
        if not source.startswith(PREFIX) or source.count(":") < 2:
            continue
        where, method = source[len(PREFIX):].rsplit(":", 1)
        for candidate in (PUBLISHED / where, Path(where)):
            manifest = _json_object(candidate / MANIFEST)
            if manifest:
                line = f"{method}: {describe(candidate, manifest)}"
                break
        else:
            line = f"{method}: {source} (the set is not here)"
        if line not in out:
            out.append(line)
    return out


def world_digest(resolved: dict[str, Any], code: dict[str, str]) -> str:
    """The model revision of a resolved mission run with components of this `code`: the
    digest of the world components' code and settings and the [mission] keys that shape the
    scenarios (never the decision components)."""
    slots = resolved.get("components", {})
    kinds = {"task_model": "task_model", "human_model": "human_model",
             "robot_model": "robot_model", "perturbations": "perturbation",
             "injectors": "injector"}
    world = []
    for slot, kind in kinds.items():
        value = slots.get(slot, [])
        for name in value if isinstance(value, list) else [value]:
            world.append([kind, name, code.get(f"{kind} {name}", "?"), resolved.get(name, {})])
    mission = {k: resolved.get("mission", {}).get(k) for k in WORLD_MISSION_KEYS}
    text = json.dumps({"mission": mission, "world": world}, sort_keys=True, default=str)
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def cell_name(setting: str, level: str) -> str:
    return f"{setting}/{level}"


def _read_toml(path: Path) -> dict[str, Any]:
    return loads_toml(path.read_text(encoding="utf-8"))


def _eval_parts(folder: Path) -> tuple[dict[str, Any], dict[tuple[str, str, str], str]]:
    """An eval folder's plugins.toml and its resolved missions' texts by cell."""
    plugins = _read_toml(folder / "plugins.toml") if (folder / "plugins.toml").is_file() else {}
    missions = {}
    for path in sorted((folder / "missions").glob("*.resolved.toml")):
        method, setting, level = path.name[:-len(".resolved.toml")].rsplit("__", 2)
        missions[(method, setting, level)] = path.read_text(encoding="utf-8")
    # the files are named by a safe form of the method's label ('w/o.AUX' -> 'w_o.AUX'):
    # eval.json's jobs give the labels
    try:
        jobs = json.loads((folder / "eval.json").read_text(encoding="utf-8")).get("jobs", [])
    except (OSError, ValueError):
        jobs = []
    for job in jobs:
        key = (safe_name(job["method"], "method"), job["setting"], job["uncertainty"])
        if key in missions:
            missions[(job["method"], job["setting"], job["uncertainty"])] = missions[key]
    return plugins, missions


def _run_parts(folder: Path, method: str) -> tuple[dict[str, Any], dict[tuple, str]]:
    """An `ata run` folder's, as one method's."""
    plugins = _read_toml(folder / "plugins.toml")
    text = (folder / "mission.resolved.toml").read_text(encoding="utf-8")
    m = loads_toml(text)["mission"]
    return ({"code": {method: plugins.get("code", {})},
             "inputs": {method: plugins.get("inputs", {})},
             "methods": {method: plugins.get("components", {})}},
            {(method, m["setting"], m["uncertainty"]): text})


def folder_parts(folder: Path, results: Results) -> tuple[dict[str, Any], dict[tuple, str]]:
    """plugins.toml (per method) and the resolved missions by (method, setting, level) of an
    `ata eval` or `ata run` folder."""
    folder = Path(folder)
    if (folder / "eval.json").is_file() or (folder / "missions").is_dir():
        return _eval_parts(folder)
    if (folder / "mission.resolved.toml").is_file():
        return _run_parts(folder, results.methods[0])
    raise MissionError("", None, "holds no resolved missions (missions/ of `ata eval`, "
                       "mission.resolved.toml of `ata run`): cannot tell what its rows were "
                       "made with", file=str(folder))


def publish(eval_dir: str | Path, out: str | Path) -> Path:
    """Write the published rows of an `ata eval` folder to `out` (rows.csv.gz, manifest.json),
    whole or not at all (`replace_folder`)."""
    folder, out = Path(eval_dir), Path(out)
    results = read_results(folder)
    plugins, missions = _eval_parts(folder)
    if not plugins.get("code"):
        raise MissionError("", None, "its plugins.toml records no code digests: evaluate "
                           "again with this version of ata, then publish", file=str(folder))
    with open(folder / "results.csv", newline="", encoding="utf-8-sig") as f:
        reader = csv.DictReader(f)
        header = [c for c in reader.fieldnames or [] if c not in DROPPED]
        rows = [{c: r[c] for c in header} for r in reader]
    cols = results.columns
    methods: dict[str, Any] = {}
    for method in results.methods:
        code = plugins["code"].get(method, {})
        cells = {}
        for s in results.settings:
            for lv in results.levels:
                sel = results.select(method, s, lv)
                if not sel.any():
                    continue
                text = missions.get((method, s, lv))
                if text is None:
                    raise MissionError("", None, f"no resolved mission for {method} ({s}, {lv})",
                                       file=str(folder))
                ids = sorted(int(i) for i in cols["scenario"][sel])
                wall = cols["wall_s"][sel] if "wall_s" in cols else np.array([np.nan])
                cells[cell_name(s, lv)] = {"seed": str(cols["seed"][sel][0]),
                                       "scenarios": [ids[0], len(ids)],
                                       "model": world_digest(loads_toml(text), code),
                                       "time_per_scenario_s": round(float(np.mean(wall)), 4),
                                       "inputs": mission_inputs(text),
                                       "mission": text}
        # plugins.toml keeps one digest a setting per method (a method may read other weights
        # in each setting): each must be one of its cells' files as installed now
        recorded = plugins.get("inputs", {}).get(method, {})
        stale = [k for k, v in recorded.items()
                 if all(c["inputs"].get(k) != v for c in cells.values())]
        if stale:
            raise MissionError("", None, f"the weights {method} read ({', '.join(stale)}) "
                               "changed since the evaluation: evaluate again, then publish",
                               file=str(folder))
        methods[method] = {"code": code,
                           "versions": plugins.get("methods", {}).get(method, {}),
                           "cells": cells}
    buffer = io.StringIO()
    writer = csv.DictWriter(buffer, fieldnames=header, lineterminator="\n")
    writer.writeheader()
    writer.writerows(rows)
    data = gzip.compress(buffer.getvalue().encode(), mtime=0)
    meta = _json_object(folder / "eval.json")
    made = _json_object(folder / PROVENANCE)
    git = made.get("checkout") if isinstance(made.get("checkout"), dict) else {}
    arguments = meta.get("arguments") if isinstance(meta.get("arguments"), dict) else {}
    _check_made_here(folder, plugins.get("ata"), methods)
    manifest = {"format": FORMAT, "release": __version__, "model_revision": MODEL_REVISION,
                "ata": __version__, "made_with": plugins.get("ata"),
                "seed_public": not any(c["seed"].startswith("secret:")
                                       for m in methods.values() for c in m["cells"].values()),
                "isolated": bool(arguments.get("isolate")),
                "commit": git.get("commit"), "dirty": git.get("dirty"),
                "packages": made.get("packages"),
                "rows": len(rows), "rows_sha256": hashlib.sha256(data).hexdigest(),
                "machine": meta.get("machine"),
                # each method of several training seeds ('NAME seed S' rows): its seeds
                "seeds": {label: [split_seed(m)[1] for m in ms]
                          for label, ms in seed_groups(list(methods)).items()
                          if split_seed(ms[0])[1] is not None},
                "methods": methods}
    # whole or not at all: a full disk never leaves half a set, nor spoils the set it replaces
    return replace_folder(out, {ROWS: data,
                                MANIFEST: (json.dumps(manifest, indent=1) + "\n").encode()})


def _json_object(path: Path) -> dict[str, Any]:
    """A JSON file's object; {} where it is missing, unreadable or not an object."""
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return {}
    return data if isinstance(data, dict) else {}


def _check_made_here(folder: Path, made_with: str | None, methods: dict[str, Any]) -> None:
    """A set belongs to the release that publishes it: an evaluation made with another ata
    version is published only where every method's code is the code installed now."""
    if made_with in (None, __version__):
        return
    for name, entry in methods.items():
        text = next(iter(entry["cells"].values()), {}).get("mission")
        now = current_code(text) if text else {}
        changed = [k for k, v in entry["code"].items() if now.get(k) not in (None, v)]
        if changed:
            raise MissionError("", None, f"was evaluated with ata {made_with} and this is ata "
                               f"{__version__}, whose code of {name} differs "
                               f"({', '.join(changed)}): a set belongs to one release; "
                               f"evaluate again with ata {__version__}, then publish",
                               file=str(folder))


def read_published(spec: str | Path) -> tuple[Results, dict[str, Any], Path]:
    """(the rows, the manifest, the folder) of a set of published rows."""
    folder = locate(spec)
    manifest = read_json_object(folder / MANIFEST, "the manifest of published rows")
    data = (folder / ROWS).read_bytes()
    if manifest.get("rows_sha256") not in (None, hashlib.sha256(data).hexdigest()):
        raise MissionError("", None, f"{ROWS} is not the file its manifest describes (another "
                           "sha256): the set was changed; publish it again (ata publish "
                           "EVAL_DIR -o DIR) or restore its files", file=shown(folder))
    with tempfile.TemporaryDirectory() as tmp:
        (Path(tmp) / "results.csv").write_bytes(gzip.decompress(data))
        results = read_results(Path(tmp))
    where, named = str(Path(tmp) / "results.csv"), f"{shown(folder)}/{ROWS}"
    results.origin = [o.replace(where, named) for o in results.origin]
    return results, manifest, folder


def current_code(mission_text: str) -> dict[str, str]:
    """The digests of the code installed now of the components a resolved mission names."""
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "mission.toml"
        path.write_text(mission_text, encoding="utf-8")
        session = load_session(str(path))
        return session.code()


def mission_inputs(mission_text: str) -> dict[str, str]:
    """The digests of the files (weights) installed now that a resolved mission's component
    settings name (``ata.session.inputs_of`` of its component tables)."""
    return inputs_of({name: table for name, table in loads_toml(mission_text).items()
                      if isinstance(table, dict) and name not in RESOLVED_TABLES})


def _seed_option(seed: str) -> str:
    """What --seed gives a set's seed: the seed, or for a secret one the variable naming it."""
    return "env:NAME (NAME holding the set's secret seed)" if seed.startswith("secret:") \
        else seed


def check_pairing(mine: Results, folder: str | Path, manifest: dict[str, Any],
                  methods: list[str], set_folder: str | Path | None = None) -> None:
    """Refuse (MissionError) to pair `mine` (read from `folder`) with the published `methods`
    (of the set in `set_folder`) when `folder` was made by another ata release than the set, a
    cell's scenarios are not among the published ones, its model revision differs, or a
    published method's code differs from the code installed now."""
    check_release(folder_release(folder), set_folder or Path("published"), manifest,
                  what=f"the rows of {folder}")
    plugins, missions = folder_parts(Path(folder), mine)
    published = manifest.get("methods", {})
    cols = mine.columns
    for method, setting, level in mine.cells():
        cell = cell_name(setting, level)
        theirs = [(name, published[name]["cells"][cell]) for name in methods
                  if cell in published.get(name, {}).get("cells", {})]
        if not theirs:
            continue
        text = missions.get((method, setting, level))
        if text is None:
            raise MissionError("", None, f"no resolved mission for {method} ({setting}, "
                               f"{level}): cannot check its model revision", file=str(folder))
        model = world_digest(loads_toml(text), plugins.get("code", {}).get(method, {}))
        sel = mine.select(method, setting, level)
        seeds = set(map(str, cols["seed"][sel]))
        ids = [int(i) for i in cols["scenario"][sel]]
        for name, info in theirs:
            if info["model"] != model:
                raise MissionError("", None, f"{method} ({setting}, {level}) ran in another "
                                   f"model than the published {name}: model revision {model} "
                                   f"here, {info['model']} there (the world components' code "
                                   "or settings, or the team, clock or uncertainty, differ); "
                                   "the rows cannot be paired: run it in the published world "
                                   "(the set's missions, in its manifest.json) or evaluate "
                                   f"{name} beside it (ata eval)", file=str(folder))
            first, count = info["scenarios"]
            outside = [i for i in ids if not first <= i < first + count]
            if seeds != {info["seed"]} or outside:
                raise MissionError("", None, f"{method} ({setting}, {level}) ran other "
                                   f"scenarios than the published {name}: seed "
                                   f"{', '.join(sorted(seeds))}, ids {min(ids)}..{max(ids)} "
                                   f"here; seed {info['seed']}, ids {first}..{first + count - 1}"
                                   " there: evaluate it on the published scenarios (ata eval "
                                   f"MISSION_OR_SUITE --seed {_seed_option(info['seed'])} -o DIR "
                                   "runs the held-out ids) and compare that folder",
                                   file=str(folder))
            weights = mission_inputs(info["mission"])
            other = [k for k, v in info.get("inputs", {}).items() if weights.get(k) != v]
            if other:
                raise MissionError("", None, f"the published rows of {name} ({setting}, "
                                   f"{level}) were made with other weights than are installed "
                                   f"now ({', '.join(other)}: "
                                   + "; ".join(f"{info['inputs'][k]} there, {weights.get(k)} "
                                               "here" for k in other)
                                   + "): evaluate it again (ata eval) and compare with that "
                                   "folder")
    for name in methods:
        entry = published.get(name, {})
        text = next(iter(entry.get("cells", {}).values()), {}).get("mission")
        if text is None:
            continue
        now = current_code(text)
        changed = [k for k, v in entry.get("code", {}).items() if now.get(k) not in (None, v)]
        if changed:
            raise MissionError("", None, f"the published rows of {name} were made with other "
                               f"code than is installed now, of {', '.join(changed)} ("
                               + "; ".join(f"{k} {entry['code'][k]} there, {now[k]} here"
                                           for k in changed)
                               + "): they are not this version's; evaluate it again (ata eval) "
                               "and compare with that folder")
