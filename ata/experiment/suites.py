"""Suite files of `ata eval`: the methods to evaluate (each a mission file plus ``--set``
overrides) and the team settings and uncertainty levels to run them at, read and checked key by
key (docs/evaluation.md, "Suites"). A plain mission file reads as a one-method suite."""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

from ata.backend import Backend
from ata.core import mission as mission_mod
from ata.core.errors import MissionError
from ata.published import PREFIX as PUBLISHED_PREFIX
from ata.published import published_method
from ata.training.folders import is_seeds_folder, trained_methods, trained_suite

SUITE_KEYS = {"name": "a label for the evaluation",
              "description": "free text",
              "settings": "team settings to run every method at (a, b, custom)",
              "uncertainty": "uncertainty levels to run every method at",
              "scenarios": "scenarios per (method, setting, level)",
              "seed": "root seed of the evaluation scenarios, or 'env:NAME' to read a secret "
                      "one from the environment",
              "pairs": "the paired differences the suite is about, [[A, B], ...]: A - B in "
                       "the paired table of `ata report --markdown`"}
METHOD_KEYS = {"name": "the method's label in results and reports",
               "mission": "its mission file, relative to the suite file, or builtin:NAME, or "
                          "published:METHOD (published rows, not run again)",
               "set": "--set overrides applied to the mission",
               "plugins": "optional plugins to load",
               "settings": "team settings for this method (instead of the suite's)",
               "uncertainty": "uncertainty levels for this method (instead of the suite's)",
               "setting": "per-setting tables: [method.setting.b] set = [...]",
               "seeds": "training seeds: one method per seed S, named 'NAME seed S', with "
                        "{seed} in its set values replaced by S"}
FIXED_KEYS = ("setting", "uncertainty", "seed", "scenarios", "first_scenario")
"""[mission] keys the evaluation sets itself; a method may not override them."""
BUILTIN_MISSIONS = Path(__file__).resolve().parent.parent / "missions"


@dataclass
class MethodSpec:
    """One method of a suite: a mission file and its overrides."""

    name: str
    source: str                       # the suite (or mission) file that defines it
    mission: str                      # the mission file
    overrides: list[str] = field(default_factory=list)
    plugins: list[str] = field(default_factory=list)
    settings: list[str] | None = None   # None: the suite's (or the mission's own)
    levels: list[str] | None = None
    per_setting: dict[str, list[str]] = field(default_factory=dict)
    backend: Backend | None = None      # None: the evaluation's (in-process or isolated)


@dataclass
class Suite:
    """A suite file, or a plain mission file as a one-method suite (`own` is then True)."""

    path: str
    name: str
    methods: list[MethodSpec]
    settings: list[str] | None = None
    levels: list[str] | None = None
    scenarios: int | None = None
    seed: int | str | None = None       # a str: 'env:NAME', a secret seed read at plan time
    own: bool = False
    raw: dict[str, Any] = field(default_factory=dict)


def _strings(value: Any, where: str, key: str, path: str) -> list[str]:
    if isinstance(value, str):
        value = [value]
    if not isinstance(value, list) or not all(isinstance(v, str) for v in value):
        raise MissionError(where, key, "must be a list of strings", file=path)
    return list(value)


def _int(value: Any, where: str, key: str, path: str, low: int) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or value < low:
        raise MissionError(where, key, f"must be an integer >= {low}", file=path)
    return value


def _unknown(table: dict, allowed: dict, where: str, path: str) -> None:
    for key in table:
        if key not in allowed:
            raise MissionError(where, key, "unknown key; allowed: " + ", ".join(allowed),
                               file=path)


def _mission_path(spec: str, base: Path, where: str, path: str) -> str:
    if spec.startswith("builtin:"):
        target = BUILTIN_MISSIONS / f"{spec.split(':', 1)[1]}.toml"
    else:
        target = Path(spec).expanduser()
        if not target.is_absolute():
            target = base / target
    if target.is_dir():                 # an `ata train` folder: expanded by load_suite
        return str(target)
    if not target.is_file():
        raise MissionError(where, "mission", f"no such mission file: {target}", file=path)
    return str(target)


def load_suite(path: str | Path) -> Suite:
    """Read a suite file, or a mission file (a table [mission]) as a one-method suite; an `ata
    train` folder is the suite of its seeds against greedy, or its run's trained weights
    against greedy at the training mission's setting and level."""
    run_folder = Path(path).is_dir() and not is_seeds_folder(Path(path))
    if Path(path).is_dir():             # an `ata train` folder: its suite, or its mission
        path = trained_suite(path)
    path = str(path)
    raw = mission_mod.read_toml(path)
    if run_folder:
        raw = _against_greedy(raw, path)
    if "suite" not in raw and "method" not in raw:
        if "mission" not in raw:
            raise MissionError("", None, "neither a suite (a table [suite] and [[method]] "
                               "tables) nor a mission file (a table [mission])", file=path)
        name = raw["mission"].get("name", "mission") if isinstance(raw["mission"], dict) \
            else "mission"
        method = MethodSpec(name=str(name), source=path, mission=path)
        return Suite(path=path, name=str(name), methods=[method], own=True, raw=raw)
    _unknown(raw, {"suite": 1, "method": 1}, "", path)
    head = raw.get("suite", {})
    if not isinstance(head, dict):
        raise MissionError("[suite]", None, "must be a table", file=path)
    _unknown(head, SUITE_KEYS, "[suite]", path)
    suite = Suite(path=path, name=str(head.get("name", Path(path).stem)), methods=[], raw=raw)
    if "settings" in head:
        suite.settings = _strings(head["settings"], "[suite]", "settings", path)
    if "uncertainty" in head:
        suite.levels = _strings(head["uncertainty"], "[suite]", "uncertainty", path)
    if "scenarios" in head:
        suite.scenarios = _int(head["scenarios"], "[suite]", "scenarios", path, 1)
    if "seed" in head:
        seed = head["seed"]
        suite.seed = seed if isinstance(seed, str) and seed.startswith("env:") \
            else _int(seed, "[suite]", "seed", path, 0)
    pairs = head.get("pairs", [])
    if not isinstance(pairs, list) or not all(
            isinstance(p, list) and len(p) == 2 and all(isinstance(x, str) for x in p)
            for p in pairs):
        raise MissionError("[suite]", "pairs", "must be a list of [A, B] pairs of method names",
                           file=path)
    methods = raw.get("method", [])
    if not isinstance(methods, list) or not methods or \
            not all(isinstance(m, dict) for m in methods):
        raise MissionError("[[method]]", None, "a suite needs one or more [[method]] tables",
                           file=path)
    base = Path(path).resolve().parent
    for i, table in enumerate(methods):
        label = table.get("name")
        where = f"[[method]] {label!r}" if isinstance(label, str) else f"[[method]] #{i + 1}"
        _unknown(table, METHOD_KEYS, where, path)
        if not isinstance(label, str) or not label.strip():
            raise MissionError(where, "name", "is required (a string)", file=path)
        if "mission" not in table or not isinstance(table["mission"], str):
            raise MissionError(where, "mission", "is required (a mission file)", file=path)
        if table["mission"].startswith(PUBLISHED_PREFIX):   # rows read, not run
            rows = published_method(table["mission"], base, where, path)
            if "set" in table or "plugins" in table:
                raise MissionError(where, "set" if "set" in table else "plugins",
                                   "a published method takes no set or plugins", file=path)
            spec = MethodSpec(name=label, source=path, mission=rows.source, backend=rows)
        else:
            spec = MethodSpec(name=label, source=path,
                              mission=_mission_path(table["mission"], base, where, path))
        spec.overrides = _strings(table.get("set", []), where, "set", path)
        spec.plugins = _strings(table.get("plugins", []), where, "plugins", path)
        if "settings" in table:
            spec.settings = _strings(table["settings"], where, "settings", path)
        if "uncertainty" in table:
            spec.levels = _strings(table["uncertainty"], where, "uncertainty", path)
        per = table.get("setting", {})
        if not isinstance(per, dict):
            raise MissionError(where, "setting", "must be a table of settings, e.g. "
                               "[method.setting.b]", file=path)
        for setting, sub in per.items():
            if not isinstance(sub, dict):
                raise MissionError(f"{where} setting {setting!r}", None, "must be a table",
                                   file=path)
            _unknown(sub, {"set": "--set overrides for this setting"},
                     f"{where} setting {setting!r}", path)
            spec.per_setting[setting] = _strings(sub.get("set", []),
                                                 f"{where} setting {setting!r}", "set", path)
        for text in spec.overrides + [t for v in spec.per_setting.values() for t in v]:
            keys, _ = mission_mod.parse_override(text)
            if keys[0] == "mission" and keys[1] in FIXED_KEYS:
                raise MissionError(where, "set", f"{text!r}: the evaluation sets mission."
                                   f"{keys[1]} itself (use the suite's settings, uncertainty, "
                                   "scenarios and seed)", file=path)
        if "seeds" in table:
            suite.methods += _per_seed(spec, table["seeds"], where, path)
            continue
        if spec.backend is None and Path(spec.mission).is_dir():
            # an `ata train` folder: its trained weights; each seed's, a method each
            suite.methods += [replace(spec, name=n, mission=m)
                              for n, m in trained_methods(spec.mission, spec.name)]
            continue
        suite.methods.append(spec)
    return suite


def _per_seed(spec: MethodSpec, seeds: Any, where: str, path: str) -> list[MethodSpec]:
    """A method of several training seeds: one method a seed, ``NAME seed S``, each with
    ``{seed}`` in its set values (and its settings' set values) replaced by S."""
    if not isinstance(seeds, list) or not seeds or len(set(map(str, seeds))) != len(seeds) \
            or not all(isinstance(x, int) and not isinstance(x, bool) and x >= 0 for x in seeds):
        raise MissionError(where, "seeds", "must be a list of distinct integers >= 0",
                           file=path)
    texts = spec.overrides + [t for v in spec.per_setting.values() for t in v]
    if spec.backend is not None or Path(spec.mission).is_dir() \
            or not any("{seed}" in t for t in texts):
        raise MissionError(where, "seeds", "needs {seed} in a set value (the weights of each "
                           "seed), else every seed would be the same method; a folder of "
                           "seeds is expanded without it", file=path)

    def put(values: list[str], seed: int) -> list[str]:
        return [t.replace("{seed}", str(seed)) for t in values]
    return [replace(spec, name=f"{spec.name} seed {s}", overrides=put(spec.overrides, s),
                    per_setting={k: put(v, s) for k, v in spec.per_setting.items()})
            for s in seeds]


def _against_greedy(mission: dict[str, Any], path: str) -> dict[str, Any]:
    """The suite of a training run folder: its trained weights (its resolved mission, `path`)
    and greedy, paired, at the training mission's setting and level."""
    head = mission.get("mission", {}) if isinstance(mission.get("mission"), dict) else {}
    label = str(head.get("name", "trained"))
    label = "trained" if label == "greedy" else label
    suite: dict[str, Any] = {"name": label, "pairs": [[label, "greedy"]]}
    for key, name in (("setting", "settings"), ("uncertainty", "uncertainty")):
        if isinstance(head.get(key), str):
            suite[name] = [head[key]]
    # the mission by its name: a method's mission is read from the suite file's folder
    return {"suite": suite, "method": [{"name": label, "mission": Path(path).name},
                                       {"name": "greedy", "mission": "builtin:greedy"}]}
