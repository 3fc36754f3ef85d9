"""Running a mission: scenarios in batches (optionally in worker processes), per-scenario
results, summary statistics, and the run folder that makes every number reproducible."""

from __future__ import annotations

import contextlib
import dataclasses
import json
import math
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

import numpy as np
import tomli_w

from ata import __version__
from ata.core import mission as mission_mod
from ata.core.errors import MissionError
from ata.core.kernel import REFERENCE_COLUMN, Simulation
from ata.core.mission import Mission
from ata.core.registry import Register, collect_components, get_plugin_manager, providers
from ata.experiment import runlog
from ata.experiment.execute import Done, Plan
from ata.experiment.folders import stamped_folder
from ata.experiment.isolate import Isolation
from ata.experiment.units import (RUN_CHUNK, chunks_of, fixed_chunks, make_units, run_units,
                                  scenario_ids)
from ata.runtime import memory
from ata.runtime.executors import Executor, ProcessExecutor, SerialExecutor
from ata.runtime.heldout import EVAL_FIRST_SCENARIO
from ata.runtime.inputs import file_digest, shipped_setting

BUILTIN_MISSION = Path(__file__).resolve().parent.parent / "missions" / "default.toml"
"""`ata run`'s default: the full ATA-HRL method with its shipped weights."""
BASELINE_MISSION = BUILTIN_MISSION.with_name("greedy.toml")
"""The greedy reference mission, the base that tests and benchmarks override."""
TRAINING_MISSIONS = sorted(BUILTIN_MISSION.parent.glob("train_*.toml"))
"""The built-in training missions; `ata train --plugins X` takes the one whose components come
from the optional plugins X."""


@dataclass
class Session:
    """A plugin manager, its component registry, and one validated mission."""

    mission: Mission
    registry: Register
    pm: Any

    def versions(self) -> dict[str, str]:
        """'kind name' -> 'distribution version' of every chosen component."""
        return {f"{kind} {name}": self.registry.get(kind, name, "").dist
                for kind, name in self.mission.chosen()}

    def code(self) -> dict[str, str]:
        """'kind name' -> the digest of the code of every chosen component (its plugin's
        source files; for a component named by reference, its file): the plan keys hold them,
        so results made with other code are never resumed as current."""
        from ata.core.references import code_digest
        out = {}
        for kind, name in self.mission.chosen():
            info = self.registry.get(kind, name, "")
            # a method run apart (--isolate) brings the digest of its code, never imported
            out[f"{kind} {name}"] = getattr(info.factory, "code", None) or \
                code_digest(info.factory, info.plugin)
        return out

    def inputs(self) -> dict[str, str]:
        """'component.setting' -> content digest of every file a component setting names (a
        checkpoint, ``builtin:NAME`` or a path): the plan keys hold them, so results made with
        one set of weights are never resumed with another under the same name."""
        return inputs_of({comp: {f.name: getattr(settings, f.name)
                                 for f in dataclasses.fields(settings)}
                          for comp, settings in self.mission.component_settings.items()
                          if settings is not None and dataclasses.is_dataclass(settings)})


def inputs_of(tables: dict[str, dict[str, Any]]) -> dict[str, str]:
    """'component.setting' -> content digest of every file a setting value of `tables`
    (component -> its settings as values) names: `Session.inputs`, or a resolved mission's
    component tables read back."""
    out = {}
    for comp, table in tables.items():
        for name, value in table.items():
            digest = file_digest(value) if isinstance(value, str) and value else None
            if digest is not None:
                out[f"{comp}.{name}"] = digest
    return out


def mission_file(spec: str | Path | None) -> str:
    """The file of a mission argument: ``builtin:NAME`` is ata/missions/NAME.toml (as in
    suites), nothing the built-in default mission, an `ata train` run folder its resolved
    mission (which names its best.pt), anything else a path."""
    if not spec:
        return str(BUILTIN_MISSION)
    spec = str(spec)
    if Path(spec).is_dir():            # an `ata train` run folder: its trained weights
        from ata.training.seeds import trained_mission
        return trained_mission(spec)
    if spec.startswith("builtin:"):
        name = spec.split(":", 1)[1]
        path = BUILTIN_MISSION.parent / f"{name}.toml"
        if not name or "/" in name or not path.is_file():
            known = ", ".join(f"builtin:{p.stem}" for p in sorted(BUILTIN_MISSION.parent.glob(
                "*.toml")))
            raise MissionError("", None, f"no built-in mission {name!r}; there are: {known}",
                               file=spec)
        return str(path)
    return spec


def load_session(path: str | None = None, overrides: list[str] | None = None,
                 plugins: list[str] | None = None, extra: tuple = (),
                 isolate: Isolation | None = None) -> Session:
    """Read (or take the built-in) mission, load the plugins it needs, and validate it. With
    `isolate`, no third-party method is imported here: a sandboxed process validates it
    (`ata.experiment.remote`)."""
    source = mission_file(path)
    raw = mission_mod.read_toml(source)
    raw = mission_mod.apply_overrides(raw, overrides or [])   # its errors name --set
    # a component named in [components] loads its plugin (lazy registration); these are the
    # optional plugins asked for by name
    optional = list(dict.fromkeys((plugins or []) + mission_mod.requested_plugins(raw)))
    if plugins:
        raw.setdefault("mission", {})["plugins"] = optional
    if isolate is not None and not extra:
        from ata.experiment.isolate import prober, resolver
        from ata.experiment.remote import isolated_registry
        registry, raw = isolated_registry(raw, optional, source, resolver(isolate),
                                          prober(isolate))
        pm = registry.pm
    else:
        pm = get_plugin_manager(optional=optional, extra=extra)
        registry = collect_components(pm)
    mission = mission_mod.validate(raw, registry, source=source, overrides=overrides or [])
    return Session(mission=mission, registry=registry, pm=pm)


def closure(plugins: list[str]) -> frozenset[str]:
    """A set of optional plugins with those they bring along (ctr and aux bring ita)."""
    from ata.core.registry import OPTIONAL_PLUGINS, requires
    out = set(plugins)
    for name in plugins:
        if name in OPTIONAL_PLUGINS:
            out |= set(requires(name))
    return frozenset(out)


def training_mission_for(plugins: list[str]) -> Path:
    """The built-in training mission whose optional plugins (those it names and those that
    provide its components) are `plugins` (with what they bring along): ctr,aux the full
    ATA-HRL; ctr w/o.AUX; ita the ITA alone; trp TR-POMDP; ita,trp AtRL-TR."""
    wanted = closure(plugins)
    found = {}
    for path in TRAINING_MISSIONS:
        raw = mission_mod.read_toml(path)
        found[closure(mission_mod.requested_plugins(raw)
                      + providers(mission_mod.named_components(raw)))] = path
    if wanted not in found:
        known = "; ".join(",".join(sorted(k)) for k in found)
        raise MissionError("--plugins", None, f"no built-in training mission for "
                           f"{','.join(sorted(wanted)) or '(none)'}; there are: {known} (or "
                           "give a training mission file)")
    return found[wanted]


def build_trainer(session: Session) -> Any:
    """The trainer component the mission names in [components] trainer, built from its table;
    its scenario ranges are checked to stay below the evaluation ids."""
    m = session.mission
    name = m.slots.trainer
    if name == "none":
        raise MissionError("[components]", "trainer", "names no trainer: nothing to train "
                           "(ata_hrl trains ATA-HRL's parts, tr_pomdp the TR-POMDP agents)",
                           file=m.source)
    info = session.registry.get("trainer", name, "[components] key 'trainer'")
    try:
        trainer = info.factory(m.component_settings.get(name), m, session.registry)
    except MissionError as exc:
        raise exc.with_file(m.source) from None
    trainer.component_name = name
    for seed, lo, hi in trainer.scenario_ranges():
        if hi > EVAL_FIRST_SCENARIO:
            raise MissionError(f"[{name}]", None, f"trains on scenario ids up to {hi - 1}, "
                               f"which reach the evaluation ids (from {EVAL_FIRST_SCENARIO})",
                               file=m.source)
    return trainer


def training_saved(run_dir: str | Path) -> str:
    """What an interrupted `ata train` left in its run folder and how to go on, read from the
    folder's files (the trainers save checkpoint.pt as they go)."""
    folder = Path(run_dir)
    checkpoint = folder / "checkpoint.pt"
    if not checkpoint.is_file():
        return (f"interrupted before the first checkpoint: nothing to resume in {folder}; run "
                "the same command again to start over")
    saved = time.strftime("%Y-%m-%d %H:%M:%S", time.localtime(checkpoint.stat().st_mtime))
    return (f"interrupted: the last checkpoint, saved {saved}, is {checkpoint}; run ata train "
            f"--resume {folder} to go on from it (the steps after it run again)")


@dataclass
class RunResult:
    """Per-scenario results of a run, in scenario order."""

    scenario: np.ndarray
    total: np.ndarray
    upper_bound: np.ndarray
    reallocations: np.ndarray
    metrics: dict[str, np.ndarray] = field(default_factory=dict)
    wall_s: float = 0.0
    warnings: list[str] = field(default_factory=list)

    def rows(self) -> list[dict[str, Any]]:
        out = []
        for i in range(self.scenario.size):
            row = {"scenario": int(self.scenario[i]), "score": float(self.total[i]),
                   "upper_bound": float(self.upper_bound[i]),
                   "fraction_of_u": float(self.total[i] / self.upper_bound[i])
                   if self.upper_bound[i] > 0 else float("nan"),
                   "reallocations": int(self.reallocations[i])}
            row.update({k: float(v[i]) for k, v in self.metrics.items()})
            out.append(row)
        return out


def build_once(mission: Mission, registry: Register,
               isolate: Isolation | None = None) -> Simulation | None:
    """Build the mission's components once, on its first scenario (as `ata check` does): a
    component that cannot fill its slot, or a checkpoint that cannot be read, fails here,
    before any work starts. With `isolate`, the decision components are built in a sandboxed
    process (`ata.experiment.isolate`), never here, and nothing is returned."""
    one, ids = mission.replace(scenarios=1), [mission.settings.first_scenario]
    if isolate is None:
        sim = Simulation(one, registry, ids)
        memory.remember(mission, sim.pm)      # the memory estimate asks them (ata_peak_bytes)
        return sim
    from ata.experiment.proxies import isolated_simulation
    with isolated_simulation(one, registry, ids, isolate) as sim:
        sim.pm.hook.ata_trained_on()           # waits for the process to build them
    return None


def plan_key(session: Session, chunks: list[np.ndarray]) -> str:
    """What decides a run's rows: the resolved mission, the components' versions, the chunks."""
    return runlog.plan_key({"ata": __version__, "mission": session.mission.to_toml(),
                            "versions": session.versions(), "inputs": session.inputs(),
                            "code": session.code(),
                            "chunks": [[int(c[0]), int(c.size)] for c in chunks]})


def mission_plan(session: Session, workers: int | None = None,
                 chunk_size: int = RUN_CHUNK) -> Plan:
    """`ata run`'s plan: one job, the mission's scenarios in batches (`units.chunks_of`), cut
    smaller when `workers` of them at once would not fit in memory (`ata.runtime.memory`)."""
    m = session.mission
    workers = workers or m.settings.workers
    chunks = chunks_of(m, workers, chunk_size)
    notes = []
    # a batch too big for memory is cut smaller (the rows do not depend on the batches)
    size, limit = max(int(c.size) for c in chunks), memory.memory_limit()
    fits = memory.largest_batch(m, size, workers, limit)
    if fits == 0:
        raise memory.too_large(m, workers, limit)
    if fits < size:
        chunks = fixed_chunks(scenario_ids(m), fits)
        notes.append(f"batches of {fits} scenarios, not {size}: a bigger batch would need more "
                     f"than {memory.limit_text(limit)}")
    return Plan(missions=[m], registries=[session.registry], chunks=[chunks],
                key=plan_key(session, chunks), unit_name="batches",
                describe={"mission": m.settings.name, "scenarios": m.settings.scenarios,
                          "code": session.code()},
                title=f"{m.settings.name}: {m.settings.scenarios} scenarios",
                default_out=lambda: default_out_dir(m), notes=notes)


def write_done(session: Session, done: Done) -> RunResult:
    """The run's result from its finished plan (`execute.run_plan`), written to its folder."""
    result = run_result(done.parts, done.wall_s)
    write_run(done.out_dir, session, result)
    return result


def run_result(parts: list[dict[str, Any]], wall_s: float) -> RunResult:
    """One RunResult of the units' results, in unit order."""
    merged = {k: np.concatenate([p[k] for p in parts]) for k in parts[0]
              if k not in ("warnings", "wall_s")}
    return RunResult(scenario=merged["scenario"], total=merged["total"],
                     upper_bound=merged["upper_bound"], reallocations=merged["reallocations"],
                     metrics={k[2:]: v for k, v in merged.items() if k.startswith("m:")},
                     wall_s=wall_s, warnings=[w for p in parts for w in p["warnings"]])


def run_mission(session: Session, progress: Callable[[float], None] | None = None,
                workers: int | None = None, log: runlog.RunLog | None = None,
                chunks: list[np.ndarray] | None = None,
                executor: Executor | None = None, cache: str | Path | None = None) -> RunResult:
    """Run every scenario of the mission: a plan of one job on the chunked runner of `ata eval`
    (`ata.experiment.units`); `progress(n)` is told of n more scenarios done.

    Results depend on (seed, scenario index) alone: any batch size, worker count or executor
    gives the same per-scenario numbers. Without `executor`, one worker runs the chunks here,
    several run them on a process executor. With `log` (`ata run`'s output folder), chunks it
    holds are not run again and each chunk is recorded there as it finishes. `cache` is the
    run's cache folder (`ata.runtime.cache`; None: none).
    """
    mission = session.mission
    workers = workers or mission.settings.workers
    chunks = chunks if chunks is not None else chunks_of(mission, workers)
    with contextlib.ExitStack() as stack:
        if executor is None:
            executor = stack.enter_context(SerialExecutor() if workers <= 1
                                           else ProcessExecutor(workers))
        found = make_units([mission], [chunks], cache=cache, executor=executor,
                           registries=[session.registry])
        parts, wall = run_units(found, executor, log=log, progress=progress)
    return run_result(parts, wall)


def mean_ci(values: np.ndarray, z: float = 1.959964) -> tuple[float, float]:
    """Mean and the half-width of its normal-approximation 95% confidence interval."""
    v = np.asarray(values, dtype=float)
    if v.size < 2:
        return float(v.mean()) if v.size else float("nan"), float("nan")
    return float(v.mean()), float(z * v.std(ddof=1) / math.sqrt(v.size))


def summarize(result: RunResult) -> dict[str, Any]:
    """The headline numbers of a run."""
    mean, half = mean_ci(result.total)
    frac = result.total / np.where(result.upper_bound > 0, result.upper_bound, np.nan)
    out = {"scenarios": int(result.scenario.size), "score_mean": mean, "score_ci95": half,
           "upper_bound_mean": float(result.upper_bound.mean()),
           "fraction_of_u": float(np.nanmean(frac)),
           "reallocations_mean": float(result.reallocations.mean()),
           "wall_s": result.wall_s}
    for k, v in result.metrics.items():
        out[f"{k}_mean"] = float(np.mean(v))
    out["warnings"] = result.warnings
    return out


def summary_rows(session: Session, result: RunResult) -> list[tuple[str, str]]:
    """`ata run`'s summary of a run: (what, value) lines."""
    m, s = session.mission, summarize(result)
    first = m.settings.first_scenario
    ci = (f" ± {s['score_ci95']:.1f} (mean ± 95% CI half-width)" if math.isfinite(
        s["score_ci95"]) else " (one scenario: no confidence interval)")
    reference = " (reference)" if REFERENCE_COLUMN in result.metrics else ""
    return [("method", m.method_label() + reference),
            ("team", f"setting {m.settings.setting}: {m.sizes.humans} humans, "
                     f"{m.sizes.robots} robots, {m.sizes.tasks} POIs"),
            ("uncertainty", f"{m.settings.uncertainty} (fatigue variance {m.fatigue_variance}, "
                            f"event probability {m.event_probability})"),
            ("scenarios", f"{s['scenarios']} (ids {first}..{first + s['scenarios'] - 1}, root "
                          f"seed {m.seed_label})"),
            *weights_rows(session),
            ("team performance", f"{s['score_mean']:.1f}{ci}"),
            ("fraction of U", f"{s['fraction_of_u']:.3f} (U: the capacity-free bound)"),
            ("POIs classified", f"{100 * s.get('classified_share_mean', float('nan')):.1f}%"),
            ("reallocations", f"{s['reallocations_mean']:.2f} per scenario"),
            ("wall time", f"{s['wall_s']:.1f} s")]


def weights_rows(session: Session) -> list[tuple[str, str]]:
    """A summary line naming the files of weights the components read (their settings that
    name a file: ``builtin:NAME`` or a path), each with the components that read it and, for a
    shipped one, the team setting it was trained for."""
    m, readers = session.mission, {}
    for key in session.inputs():
        comp, field_name = key.split(".", 1)
        value = getattr(m.component_settings[comp], field_name)
        readers.setdefault(value, []).append(comp)
    rows = []
    for value, comps in readers.items():
        setting = shipped_setting(value)
        made = "" if setting is None else f"; shipped for setting {setting}" + (
            ", the nearest to this team's size" if m.settings.setting == "custom" else "")
        rows.append(("weights", f"{value} (read by {', '.join(comps)}{made})"))
    return rows


def write_run(out_dir: str | Path, session: Session, result: RunResult) -> Path:
    """Write results.csv, summary.json, the resolved mission and the plugin versions."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    rows = result.rows()
    runlog.write_csv(out / "results.csv", list(rows[0]), rows)
    (out / "summary.json").write_text(json.dumps(summarize(result), indent=2) + "\n")
    (out / "mission.resolved.toml").write_text(session.mission.to_toml(), encoding="utf-8")
    versions = {"ata": __version__, "components": session.versions(),
                "inputs": session.inputs(), "code": session.code()}
    (out / "plugins.toml").write_text(tomli_w.dumps(versions), encoding="utf-8")
    return out


def default_out_dir(mission: Mission, prefix: str = "") -> Path:
    """A new folder runs/[PREFIX]NAME-TIME for a run of the mission."""
    return stamped_folder(f"{prefix}{mission.settings.name}")
