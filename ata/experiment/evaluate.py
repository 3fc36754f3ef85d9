"""`ata eval`: many methods, team settings and uncertainty levels on held-out scenarios.

A *suite* file names methods (each a mission file plus ``--set`` overrides) and the settings and
uncertainty levels to run them at; a plain mission file counts as one method at its own setting
and level. Every (method, setting, level) becomes a *job*: a validated mission whose scenarios
are cut into chunks, the work units that an executor (ata.experiment.executors) runs anywhere. A
scenario's numbers depend on (seed, scenario id) alone, so the rows do not depend on the
executor, the worker count or the chunk size.

Held-out scenarios: every evaluation scenario id is at least EVAL_FIRST_SCENARIO = 2**40, and
trainers draw ids below it (``ata.training.TRAINING_ID_LIMIT``). Beyond that, every learned
component reports the (seed, id) ranges its weights were trained on (the ``ata_trained_on``
hook, from its checkpoint), and `check_held_out` refuses a job whose scenarios meet any of them.
"""

from __future__ import annotations

import json
import os
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

import numpy as np
import tomli_w

from ata import __version__
from ata.core import mission as mission_mod
from ata.core.errors import MissionError
from ata.core.kernel import Simulation
from ata.core.mission import UNCERTAINTY_LEVELS, Mission
from ata.experiment import runlog
from ata.experiment.executors import Executor
from ata.experiment.heldout import EVAL_FIRST_SCENARIO
from ata.experiment.runner import Session, build_once, load_session, stamped_folder
from ata.experiment.units import Unit, fixed_chunks, make_units, run_units, scenario_ids

DEFAULT_SCENARIOS = 500
"""Scenarios per (method, setting, level) when neither the suite nor the command says."""
DEFAULT_CHUNK = 50
"""Scenarios per work unit."""

CORE_COLUMNS = ["method", "setting", "uncertainty", "scenario", "seed", "score", "upper_bound",
                "fraction_of_u", "classified_share", "reallocations", "wall_s"]
"""The first columns of results.csv; the components' other per-scenario metrics follow, sorted."""

SUITE_KEYS = {"name": "a label for the evaluation",
              "description": "free text",
              "settings": "team settings to run every method at (a, b, custom)",
              "uncertainty": "uncertainty levels to run every method at",
              "scenarios": "scenarios per (method, setting, level)",
              "seed": "root seed of the evaluation scenarios, or 'env:NAME' to read a secret "
                      "one from the environment"}
METHOD_KEYS = {"name": "the method's label in results and reports",
               "mission": "its mission file, relative to the suite file, or builtin:NAME",
               "set": "--set overrides applied to the mission",
               "plugins": "optional plugins to load",
               "settings": "team settings for this method (instead of the suite's)",
               "uncertainty": "uncertainty levels for this method (instead of the suite's)",
               "setting": "per-setting tables: [method.setting.b] set = [...]"}
FIXED_KEYS = ("setting", "uncertainty", "seed", "scenarios", "first_scenario")
"""[mission] keys the evaluation sets itself; a method may not override them."""
BUILTIN_MISSIONS = Path(__file__).resolve().parent.parent / "missions"


# -- suites -------------------------------------------------------------------------------------
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
    if not target.is_file():
        raise MissionError(where, "mission", f"no such mission file: {target}", file=path)
    return str(target)


def load_suite(path: str | Path) -> Suite:
    """Read a suite file, or a mission file (a table [mission]) as a one-method suite."""
    path = str(path)
    raw = mission_mod.read_toml(path)
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
        suite.methods.append(spec)
    return suite


# -- jobs ---------------------------------------------------------------------------------------
@dataclass
class Job:
    """One (method, setting, uncertainty level): a validated mission on the held-out range."""

    method: str
    setting: str
    level: str
    session: Session
    source: str

    @property
    def mission(self) -> Mission:
        return self.session.mission

    @property
    def label(self) -> str:
        return f"{self.method}__{self.setting}__{self.level}"


def eval_range(mission: Mission) -> tuple[int, int, int]:
    s = mission.settings
    return s.seed, s.first_scenario, s.first_scenario + s.scenarios


def check_held_out(mission: Mission, sim: Simulation) -> None:
    """Raise a MissionError when a (seed, scenario id) pair of the mission's scenarios is one
    that the weights of a component of `sim` (built from the mission) were trained on."""
    seed, lo, hi = eval_range(mission)
    for ranges in sim.pm.hook.ata_trained_on():
        for t_seed, t_lo, t_hi in ranges or []:
            if seed == t_seed and lo < t_hi and t_lo < hi:
                raise MissionError("[mission]", "first_scenario", f"scenarios {lo}..{hi - 1} "
                                   f"of seed {mission.seed_label} overlap the ids {t_lo}..{t_hi - 1} of that "
                                   "seed that a component's weights were trained on; "
                                   "evaluation scenarios must be held out")


def _pick(values: list[str] | None, wanted: list[str] | None) -> list[str | None]:
    if values is None:
        return [None]                  # the mission's own
    return [v for v in values if wanted is None or v in wanted]


def _level_order(level: str) -> int:
    order = list(UNCERTAINTY_LEVELS)
    return order.index(level) if level in order else len(order)


def plan(paths: list[str], *, scenarios: int | None = None, seed: int | None = None,
         methods: list[str] | None = None, settings: list[str] | None = None,
         levels: list[str] | None = None, validate: bool = True) -> tuple[list[Suite], list[Job]]:
    """Read the suites and build every job's mission; with `validate`, build each job's
    components once on one scenario, so that a bad method fails before any work starts."""
    suites = [load_suite(p) for p in paths]
    names: dict[str, str] = {}
    for suite in suites:
        for m in suite.methods:
            if m.name in names:
                raise MissionError(f"method {m.name!r}", None, f"is defined twice (also in "
                                   f"{names[m.name]}); method names must be unique",
                                   file=suite.path)
            names[m.name] = suite.path
    if methods:
        unknown = [m for m in methods if m not in names]
        if unknown:
            raise MissionError("--methods", None, f"unknown method {unknown[0]!r}; the suites "
                               "define: " + ", ".join(names))
    jobs: list[Job] = []
    for suite in suites:
        for spec in suite.methods:
            if methods and spec.name not in methods:
                continue
            own_settings = spec.settings if spec.settings is not None else suite.settings
            own_levels = spec.levels if spec.levels is not None else suite.levels
            for key in spec.per_setting:
                if own_settings is not None and key not in own_settings:
                    raise MissionError(f"[[method]] {spec.name!r}", "setting", f"has a table "
                                       f"for setting {key!r}, which it does not run at "
                                       f"({', '.join(own_settings)})", file=suite.path)
            for st in _pick(own_settings, settings):
                for lv in _pick(own_levels, levels):
                    job = _job(suite, spec, st, lv, scenarios, seed)
                    if (settings and job.setting not in settings) or \
                            (levels and job.level not in levels):
                        continue
                    jobs.append(job)
    seen: dict[tuple[str, str, str], Job] = {}
    for job in jobs:
        key = (job.method, job.setting, job.level)
        if key in seen:
            raise MissionError(f"method {job.method!r}", None, f"runs twice at setting "
                               f"{job.setting}, {job.level} uncertainty", file=job.source)
        seen[key] = job
    if not jobs:
        raise MissionError("", None, "nothing to evaluate: the filters leave no (method, "
                           "setting, uncertainty) of " + ", ".join(paths))
    if validate:
        for job in jobs:
            _validate_job(job)
    return suites, jobs


def _context(exc: MissionError, source: str, method: str, setting: str | None,
             level: str | None) -> MissionError:
    at = ", ".join(x for x in (f"setting {setting}" if setting else "",
                               f"{level} uncertainty" if level else "") if x)
    return MissionError(f"method {method!r}" + (f" ({at})" if at else ""), None, str(exc),
                        file=source)


def _job(suite: Suite, spec: MethodSpec, setting: str | None, level: str | None,
         scenarios: int | None, seed: int | None) -> Job:
    overrides = list(spec.overrides)
    if setting is not None:
        overrides += spec.per_setting.get(setting, [])
        overrides.append(f"mission.setting='{setting}'")
    if level is not None:
        overrides.append(f"mission.uncertainty='{level}'")
    n = scenarios or suite.scenarios
    if n is None and not suite.own:
        n = DEFAULT_SCENARIOS
    if n is not None:
        overrides.append(f"mission.scenarios={int(n)}")
    root = seed if seed is not None else (suite.seed if suite.seed is not None else 0)
    root = f"'{root}'" if isinstance(root, str) else int(root)    # 'env:NAME': secret
    overrides += [f"mission.seed={root}", f"mission.first_scenario={EVAL_FIRST_SCENARIO}"]
    try:
        session = load_session(spec.mission, overrides, spec.plugins or None)
    except MissionError as exc:
        raise _context(exc, suite.path, spec.name, setting, level) from None
    m = session.mission
    return Job(method=spec.name, setting=m.settings.setting, level=m.settings.uncertainty,
               session=session, source=suite.path)


def _validate_job(job: Job) -> None:
    """Build the job's components once, on one scenario (as `ata check` does), and check that
    its scenarios are held out."""
    m = job.mission
    try:
        check_held_out(m, build_once(m, job.session.registry))
    except MissionError as exc:
        raise _context(exc, job.source, job.method, job.setting, job.level) from None


# -- work units ---------------------------------------------------------------------------------
def job_units(jobs: list[Job], chunk_size: int, cache: str | Path | None = None,
              executor: Executor | None = None) -> list[Unit]:
    """The plan's work units: each job's scenarios in chunks of `chunk_size`."""
    return make_units([j.mission for j in jobs],
                      [fixed_chunks(scenario_ids(j.mission), chunk_size) for j in jobs],
                      cache=cache, executor=executor,
                      registries=[j.session.registry for j in jobs])


# -- running ------------------------------------------------------------------------------------
@dataclass
class EvalResult:
    rows: list[dict[str, Any]]
    columns: list[str]
    wall_s: float
    method_wall_s: dict[str, float]
    warnings: list[str]


def plan_key(jobs: list[Job], chunk_size: int) -> str:
    """The key of a plan: everything that decides its rows (each job's resolved mission and
    component versions, the chunking); not where or how fast it runs."""
    return runlog.plan_key({"ata": __version__, "chunk_size": chunk_size,
                            "jobs": [[j.method, j.setting, j.level, j.mission.to_toml(),
                                      j.session.versions(), j.session.inputs()]
                                     for j in jobs]})


def unit_count(jobs: list[Job], chunk_size: int) -> int:
    return len(job_units(jobs, chunk_size))


def evaluate(jobs: list[Job], executor: Executor, *, chunk_size: int = DEFAULT_CHUNK,
             cache: str | Path | None = None,
             progress: Callable[[float], None] | None = None,
             log: runlog.RunLog | None = None) -> EvalResult:
    """Run every job's scenarios on `executor` (`ata.experiment.units`, the runner of `ata run`
    too); `progress(n)` hears of n more scenarios done.

    :param log: the output folder's record: units it holds are not run again, and each unit
        is recorded there durably as it finishes.
    """
    units = job_units(jobs, chunk_size, cache, executor)
    parts, wall = run_units(units, executor, log=log, progress=progress)
    method_wall: dict[str, float] = {}
    warnings: list[str] = []
    rows: list[dict[str, Any]] = []
    for unit, part in zip(units, parts):
        job = jobs[unit.job]
        method_wall[job.method] = method_wall.get(job.method, 0.0) + part["wall_s"]
        warnings += [f"{job.method} ({job.setting}, {job.level}): {w}" for w in part["warnings"]]
        rows += _rows(job, part)
    order = {name: i for i, name in enumerate(dict.fromkeys(j.method for j in jobs))}
    rows.sort(key=lambda r: (order[r["method"]], r["setting"], _level_order(r["uncertainty"]),
                             r["uncertainty"], r["scenario"]))
    extras = sorted({k for r in rows for k in r} - set(CORE_COLUMNS))
    columns = CORE_COLUMNS + extras
    rows = [{c: r.get(c, "") for c in columns} for r in rows]
    return EvalResult(rows=rows, columns=columns, wall_s=wall, method_wall_s=method_wall,
                      warnings=list(dict.fromkeys(warnings)))


def _rows(job: Job, part: dict[str, Any]) -> list[dict[str, Any]]:
    ids = np.asarray(part["scenario"])
    per_row = part["wall_s"] / max(ids.size, 1)
    metrics = {k[2:]: v for k, v in part.items() if k.startswith("m:")}
    out = []
    for i in range(ids.size):
        score, ub = float(part["total"][i]), float(part["upper_bound"][i])
        row = {"method": job.method, "setting": job.setting, "uncertainty": job.level,
               "scenario": int(ids[i]), "seed": job.mission.seed_label,
               "score": score, "upper_bound": ub,
               "fraction_of_u": score / ub if ub > 0 else float("nan"),
               "classified_share": float("nan"),
               "reallocations": int(part["reallocations"][i]), "wall_s": per_row}
        row.update({k: float(v[i]) for k, v in metrics.items()})
        out.append(row)
    return out


# -- the run folder -----------------------------------------------------------------------------
def safe_name(text: str) -> str:
    """A file-name-safe form of a label ('w/o.AUX' -> 'w_o.AUX')."""
    return re.sub(r"[^A-Za-z0-9._-]+", "_", text).strip("_") or "method"


def write_eval(out_dir: str | Path, suites: list[Suite], jobs: list[Job], result: EvalResult,
               arguments: dict[str, Any]) -> Path:
    """results.csv, missions/*.resolved.toml, plugins.toml and eval.json."""
    out = Path(out_dir)
    (out / "missions").mkdir(parents=True, exist_ok=True)
    for stale in (out / "missions").glob("*.resolved.toml"):   # of an earlier plan
        stale.unlink()
    runlog.write_csv(out / "results.csv", result.columns, result.rows)
    for job in jobs:
        name = f"{safe_name(job.method)}__{job.setting}__{job.level}.resolved.toml"
        (out / "missions" / name).write_text(job.mission.to_toml(), encoding="utf-8")
    components: dict[str, str] = {}
    per_method: dict[str, dict[str, str]] = {}
    inputs: dict[str, dict[str, str]] = {}
    for job in jobs:
        versions = job.session.versions()
        components.update(versions)
        per_method.setdefault(job.method, {}).update(versions)
        inputs.setdefault(job.method, {}).update(job.session.inputs())
    (out / "plugins.toml").write_text(tomli_w.dumps({"ata": __version__,
                                                     "components": components,
                                                     "methods": per_method,
                                                     "inputs": inputs}), encoding="utf-8")
    meta = {"ata": __version__, "arguments": arguments,
            "suites": [{"path": s.path, "name": s.name, "content": s.raw} for s in suites],
            "jobs": [{"method": j.method, "setting": j.setting, "uncertainty": j.level,
                      "scenarios": j.mission.settings.scenarios, "seed": j.mission.seed_label,
                      "first_scenario": j.mission.settings.first_scenario,
                      "mission": j.mission.source} for j in jobs],
            "rows": len(result.rows), "wall_s": result.wall_s,
            "method_wall_s": result.method_wall_s, "warnings": result.warnings}
    (out / "eval.json").write_text(json.dumps(meta, indent=2, default=_json_default) + "\n",
                                   encoding="utf-8")
    return out


def _json_default(value: Any) -> Any:
    if isinstance(value, (np.integer, np.floating)):
        return value.item()
    if isinstance(value, Path):
        return str(value)
    return str(value)


def default_out_dir(suites: list[Suite]) -> Path:
    names = [s.name for s in suites]
    label = "+".join(names) if len(names) <= 3 else "suite"
    return stamped_folder(f"eval-{safe_name(label)}")


def default_cache_dir() -> Path:
    """$ATA_CACHE, else ~/.cache/ata."""
    env = os.environ.get("ATA_CACHE")
    return Path(env).expanduser() if env else Path("~/.cache/ata").expanduser()


def total_scenarios(jobs: list[Job]) -> int:
    return sum(j.mission.settings.scenarios for j in jobs)
