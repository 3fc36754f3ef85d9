"""`ata eval`: many methods, team settings and uncertainty levels on held-out scenarios.

A *suite* file (`ata.experiment.suites`) names methods (each a mission file plus ``--set``
overrides) and the settings and uncertainty levels to run them at; a plain mission file counts
as one method at its own setting and level. Every (method, setting, level) becomes a *job*: a
validated mission whose scenarios are cut into chunks, the work units that an executor
(ata.runtime.executors) runs anywhere, where the job's backend (``ata.backend``) says. A
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
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable

import numpy as np
import tomli_w

from ata import __version__
from ata.backend import IN_PROCESS, Backend
from ata.core.errors import MissionError
from ata.core.kernel import Simulation
from ata.core.mission import TEAM_SETTINGS, UNCERTAINTY_LEVELS, Mission
from ata.experiment import runlog
from ata.experiment.execute import Done, Plan, ProgressFactory, run_plan
from ata.experiment.suites import MethodSpec, Suite, load_suite
from ata.experiment.units import Unit, fixed_chunks, make_units, run_units, scenario_ids
from ata.published import check_models
from ata.runtime.executors import EXECUTORS, Executor
from ata.runtime.folders import safe_name, stamped_folder
from ata.runtime.heldout import EVAL_FIRST_SCENARIO
from ata.runtime.machine import machine, write_provenance
from ata.session import Session, load_session

DEFAULT_SCENARIOS = 500
"""Scenarios per (method, setting, level) when neither the suite nor the command says."""
DEFAULT_CHUNK = 250
"""Scenarios per work unit: two units a cell of the paper's suite. A unit pays a fixed time
beside its scenarios' own (the learned methods' decoder steps, about 6 s in (a)), so bigger
units run faster; a unit is saved when it ends, so smaller ones lose less to an interruption
(docs/evaluation.md)."""

CORE_COLUMNS = ["method", "setting", "uncertainty", "scenario", "seed", "score", "upper_bound",
                "fraction_of_u", "classified_share", "reallocations", "wall_s"]
"""The first columns of results.csv; the components' other per-scenario metrics follow, sorted."""


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
                                   f"of seed {mission.seed_label} overlap the ids "
                                   f"{t_lo}..{t_hi - 1} of that seed that a component's "
                                   "weights were trained on; evaluation scenarios must be held "
                                   "out")


def _pick(values: list[str] | None, wanted: list[str] | None) -> list[str | None]:
    if values is None:
        return [None]                  # the mission's own
    return [v for v in values if wanted is None or v in wanted]


def _level_order(level: str) -> int:
    order = list(UNCERTAINTY_LEVELS)
    return order.index(level) if level in order else len(order)


def _rejoin(parts: list[str], names: dict[str, str]) -> list[str]:
    """`--methods` split at its commas, with the parts of a method name that holds commas
    (``ATA-HRL, full recipe, seed 12345``) joined again; other parts as they were."""
    out, i = [], 0
    while i < len(parts):
        # the longest run of parts from i that joins into a name, else part i alone
        i, name = next(((j, joined) for j in range(len(parts), i + 1, -1)
                        for joined in (", ".join(parts[i:j]), ",".join(parts[i:j]))
                        if joined in names), (i + 1, parts[i]))
        out.append(name)
    return out


def plan(paths: list[str], *, scenarios: int | None = None, seed: int | None = None,
         methods: list[str] | None = None, settings: list[str] | None = None,
         levels: list[str] | None = None, validate: bool = True,
         backend: Backend = IN_PROCESS) -> tuple[list[Suite], list[Job]]:
    """Read the suites and build every job's mission, its decisions run by `backend` (a
    method of published rows by its own); with `validate`, build each job's components once on
    one scenario where its backend builds them, so that a bad method fails before any work
    starts."""
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
        methods = _rejoin(methods, names)
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
                    job = _job(suite, spec, st, lv, scenarios, seed, backend)
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
    check_models(jobs)
    return suites, jobs


def _context(exc: MissionError, source: str, method: str, setting: str | None,
             level: str | None) -> MissionError:
    at = ", ".join(x for x in (f"setting {setting}" if setting else "",
                               f"{level} uncertainty" if level else "") if x)
    return MissionError(f"method {method!r}" + (f" ({at})" if at else ""), None, str(exc),
                        file=source)


def _job(suite: Suite, spec: MethodSpec, setting: str | None, level: str | None,
         scenarios: int | None, seed: int | None, backend: Backend = IN_PROCESS) -> Job:
    overrides = list(spec.overrides)
    # the cell's team setting and level, and what they fix: a setting's team sizes and a
    # level's fatigue variance and event probability (a resolved mission, such as a training
    # folder's, names them all, for the setting and level it was trained at)
    if setting is not None:
        overrides += spec.per_setting.get(setting, [])
        overrides.append(f"mission.setting='{setting}'")
        team = TEAM_SETTINGS.get(setting)
        overrides += [f"mission.{k}={getattr(team, k)}" for k in ("humans", "robots", "tasks")
                      if team is not None]
    if level is not None:
        overrides.append(f"mission.uncertainty='{level}'")
        overrides += [f"mission.{k}={v}" for k, v in
                      zip(("fatigue_variance", "event_probability"),
                          UNCERTAINTY_LEVELS.get(level, ()))]
    n = scenarios or suite.scenarios
    if n is None and not suite.own:
        n = DEFAULT_SCENARIOS
    if n is not None:
        overrides.append(f"mission.scenarios={int(n)}")
    root = seed if seed is not None else (suite.seed if suite.seed is not None else 0)
    root = f"'{root}'" if isinstance(root, str) else int(root)    # 'env:NAME': secret
    overrides += [f"mission.seed={root}", f"mission.first_scenario={EVAL_FIRST_SCENARIO}"]
    try:
        if spec.backend is not None:                    # its own: published rows, read
            session = spec.backend.load(overrides)
        else:
            session = load_session(spec.mission, overrides, spec.plugins or None,
                                   backend=backend)
    except MissionError as exc:
        raise _context(exc, suite.path, spec.name, setting, level) from None
    m = session.mission
    return Job(method=spec.name, setting=m.settings.setting, level=m.settings.uncertainty,
               session=session, source=suite.path)


def _validate_job(job: Job) -> None:
    """Build the job's components once, on one scenario, where its backend builds them (as
    `ata check` does), and check that its scenarios are held out."""
    m = job.mission
    try:
        job.session.backend.check(m, job.session.registry, lambda sim: check_held_out(m, sim))
    except MissionError as exc:
        raise _context(exc, job.source, job.method, job.setting, job.level) from None


# -- the command -------------------------------------------------------------------------------
def evaluate_suites(paths: list[str], out: str | Path | None = None, *,
                    executor: str = "process", workers: int | None = None,
                    address: str | None = None, chunk_size: int | None = None,
                    scenarios: int | None = None, seed: int | None = None,
                    methods: list[str] | None = None, settings: list[str] | None = None,
                    levels: list[str] | None = None, cache: str | Path | None = None,
                    no_cache: bool = False, force: bool = False,
                    backend: Backend = IN_PROCESS, notify: Callable[[str], None] | None = None,
                    progress: ProgressFactory | None = None) -> tuple[Path, EvalResult]:
    """`ata eval`: plan the suites' jobs (every job built and validated before any scenario
    runs or anything is written), run them into `out` (`execute.run_plan`) and write the
    folder; its path and the result. `cache`: the cache folder (default `default_cache_dir`,
    none with `no_cache`)."""
    if executor not in EXECUTORS:
        raise MissionError("--executor", None, f"unknown executor {executor!r}; choose one of "
                           + ", ".join(EXECUTORS))
    chunk_size = chunk_size or DEFAULT_CHUNK
    suites, jobs = plan(list(paths), scenarios=scenarios, seed=seed, methods=methods,
                        settings=settings, levels=levels, backend=backend)
    cache_dir = None if no_cache else (cache or default_cache_dir())
    the_plan = eval_plan(suites, jobs, chunk_size, describe={
        "paths": list(paths), "jobs": len(jobs), "chunk_size": chunk_size})
    arguments = {"paths": list(paths), "chunk_size": chunk_size, "scenarios": scenarios,
                 "seed": seed, "methods": ",".join(methods) if methods else None,
                 "settings": ",".join(settings) if settings else None,
                 "levels": ",".join(levels) if levels else None,
                 "cache": str(cache_dir) if cache_dir else None,
                 "first_scenario": EVAL_FIRST_SCENARIO, "isolate": backend.key() or None}
    return run_plan(the_plan, lambda done: (done.out_dir, write_done(suites, jobs, chunk_size,
                                                                     arguments, done)),
                    out, executor=executor, workers=workers, address=address, cache=cache_dir,
                    force=force, notify=notify, progress=progress)


# -- work units ---------------------------------------------------------------------------------
def job_units(jobs: list[Job], chunk_size: int, cache: str | Path | None = None,
              executor: Executor | None = None) -> list[Unit]:
    """The plan's work units: each job's scenarios in chunks of `chunk_size`."""
    return make_units([j.mission for j in jobs],
                      [fixed_chunks(scenario_ids(j.mission), chunk_size) for j in jobs],
                      cache=cache, executor=executor,
                      registries=[j.session.registry for j in jobs],
                      backends=[j.session.backend for j in jobs])


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
                                      j.session.versions(), j.session.inputs(),
                                      j.session.code(), j.session.backend.key()]
                                     for j in jobs]})


def plan_code(jobs: list[Job]) -> dict[str, str]:
    """'kind name' -> the digest of its code, for every component of every job."""
    out: dict[str, str] = {}
    for job in jobs:
        out.update(job.session.code())
    return dict(sorted(out.items()))


def eval_plan(suites: list[Suite], jobs: list[Job], chunk_size: int = DEFAULT_CHUNK,
              describe: dict[str, Any] | None = None) -> Plan:
    """`ata eval`'s plan: each job's scenarios in chunks of `chunk_size`, a work unit each."""
    return Plan(missions=[j.mission for j in jobs], registries=[j.session.registry for j in jobs],
                backends=[j.session.backend for j in jobs],
                chunks=[fixed_chunks(scenario_ids(j.mission), chunk_size) for j in jobs],
                key=plan_key(jobs, chunk_size),
                describe={**(describe or {}), "code": plan_code(jobs)},
                unit_name="work units", title=f"eval: {len(jobs)} (method, setting, level)",
                notes=list(dict.fromkeys(n for j in jobs for n in j.session.backend.notes(
                    j.mission))),
                default_out=lambda: default_out_dir(suites), command="eval")


def write_done(suites: list[Suite], jobs: list[Job], chunk_size: int,
               arguments: dict[str, Any], done: Done) -> EvalResult:
    """The evaluation's rows from its finished plan (`execute.run_plan`), written to its folder
    with the command's `arguments` (where it ran and the units resumed added)."""
    result = eval_result(jobs, [u.job for u in job_units(jobs, chunk_size)], done.parts,
                         done.wall_s)
    arguments = {**arguments, "executor": done.executor, "resumed_units": done.resumed}
    write_eval(done.out_dir, suites, jobs, result, arguments)
    return result


def evaluate(jobs: list[Job], executor: Executor, *, chunk_size: int = DEFAULT_CHUNK,
             cache: str | Path | None = None,
             progress: Callable[[float], None] | None = None,
             log: runlog.RunLog | None = None) -> EvalResult:
    """Run every job's scenarios on `executor` (`ata.experiment.units`, the runner of `ata run`
    too), in memory; `progress(n)` hears of n more scenarios done.

    :param log: the output folder's record: units it holds are not run again, and each unit
        is recorded there durably as it finishes.
    """
    units = job_units(jobs, chunk_size, cache, executor)
    parts, wall = run_units(units, executor, log=log, progress=progress)
    return eval_result(jobs, [u.job for u in units], parts, wall)


def eval_result(jobs: list[Job], unit_jobs: list[int], parts: list[dict[str, Any]],
                wall: float) -> EvalResult:
    """The rows of every unit's results (`parts`, unit i of job `unit_jobs[i]`), in report
    order, with the wall times and the warnings."""
    method_wall: dict[str, float] = {}
    warnings: list[str] = []
    rows: list[dict[str, Any]] = []
    for j, part in zip(unit_jobs, parts):
        job = jobs[j]
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
def write_eval(out_dir: str | Path, suites: list[Suite], jobs: list[Job], result: EvalResult,
               arguments: dict[str, Any]) -> Path:
    """results.csv, missions/*.resolved.toml, plugins.toml, provenance.json and eval.json."""
    out = Path(out_dir)
    (out / "missions").mkdir(parents=True, exist_ok=True)
    for stale in (out / "missions").glob("*.resolved.toml"):   # of an earlier plan
        stale.unlink()
    runlog.write_csv(out / "results.csv", result.columns, result.rows)
    for job in jobs:
        name = f"{safe_name(job.method, 'method')}__{job.setting}__{job.level}.resolved.toml"
        (out / "missions" / name).write_text(job.mission.to_toml(), encoding="utf-8")
    components: dict[str, str] = {}
    per_method: dict[str, dict[str, str]] = {}
    inputs: dict[str, dict[str, str]] = {}
    code: dict[str, dict[str, str]] = {}
    for job in jobs:
        versions = job.session.versions()
        components.update(versions)
        per_method.setdefault(job.method, {}).update(versions)
        inputs.setdefault(job.method, {}).update(job.session.inputs())
        code.setdefault(job.method, {}).update(job.session.code())
    (out / "plugins.toml").write_text(tomli_w.dumps({"ata": __version__,
                                                     "components": components,
                                                     "methods": per_method,
                                                     "inputs": inputs, "code": code}),
                                      encoding="utf-8")
    meta = {"ata": __version__, "arguments": arguments,
            "suites": [{"path": s.path, "name": s.name, "content": s.raw} for s in suites],
            "jobs": [{"method": j.method, "setting": j.setting, "uncertainty": j.level,
                      "scenarios": j.mission.settings.scenarios, "seed": j.mission.seed_label,
                      "first_scenario": j.mission.settings.first_scenario,
                      "mission": j.mission.source} for j in jobs],
            "rows": len(result.rows), "wall_s": result.wall_s, "machine": machine(),
            "method_wall_s": result.method_wall_s, "warnings": result.warnings}
    write_provenance(out)
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
    return stamped_folder(f"eval-{label}")


def default_cache_dir() -> Path:
    """$ATA_CACHE, else ~/.cache/ata."""
    env = os.environ.get("ATA_CACHE")
    return Path(env).expanduser() if env else Path("~/.cache/ata").expanduser()

