"""Running a mission: scenarios in batches (optionally in worker processes), per-scenario
results, summary statistics, and the run folder that makes every number reproducible."""

from __future__ import annotations

import contextlib
import dataclasses
import json
import math
import os
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

import numpy as np
import tomli_w

from ata import __version__
from ata.core import mission as mission_mod
from ata.core.errors import MissionError
from ata.core.kernel import Simulation
from ata.core.mission import Mission
from ata.core.registry import Register, collect_components, get_plugin_manager
from ata.experiment import runlog
from ata.experiment.executors import Executor, ProcessExecutor, SerialExecutor
from ata.experiment.heldout import EVAL_FIRST_SCENARIO
from ata.experiment.inputs import file_digest
from ata.experiment.units import chunks_of, make_units, run_units

BUILTIN_MISSION = Path(__file__).resolve().parent.parent / "missions" / "default.toml"
"""`ata run`'s default: the full ATA-HRL method with its shipped weights."""
BASELINE_MISSION = BUILTIN_MISSION.with_name("greedy.toml")
"""The greedy reference mission, the base that tests and benchmarks override."""
TRAINING_MISSIONS = sorted(BUILTIN_MISSION.parent.glob("train_*.toml"))
"""The built-in training missions; `ata train --plugins X` takes the one whose plugins are X."""


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

    def inputs(self) -> dict[str, str]:
        """'component.setting' -> content digest of every file a component setting names (a
        checkpoint, ``builtin:NAME`` or a path): the plan keys hold them, so results made with
        one set of weights are never resumed with another under the same name."""
        out = {}
        for comp, settings in self.mission.component_settings.items():
            if settings is None or not dataclasses.is_dataclass(settings):
                continue
            for f in dataclasses.fields(settings):
                value = getattr(settings, f.name)
                if isinstance(value, str) and value:
                    digest = file_digest(value)
                    if digest is not None:
                        out[f"{comp}.{f.name}"] = digest
        return out


def load_session(path: str | None = None, overrides: list[str] | None = None,
                 plugins: list[str] | None = None, extra: tuple = ()) -> Session:
    """Read (or take the built-in) mission, load the plugins it needs, and validate it."""
    source = str(path) if path else str(BUILTIN_MISSION)
    raw = mission_mod.read_toml(source)
    try:
        raw = mission_mod.apply_overrides(raw, overrides or [])
    except MissionError as exc:
        raise exc.with_file(source) from None
    optional = list(dict.fromkeys((plugins or []) + mission_mod.requested_plugins(raw)))
    if plugins:
        raw.setdefault("mission", {})["plugins"] = optional
    pm = get_plugin_manager(optional=optional, extra=extra)
    registry = collect_components(pm)
    mission = mission_mod.validate(raw, registry, source=source)
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
    """The built-in training mission whose optional plugins are `plugins` (with what they bring
    along): ctr,aux the full ATA-HRL; ctr w/o.AUX; ita the ITA alone; trp TR-POMDP; ita,trp
    AtRL-TR."""
    wanted = closure(plugins)
    found = {}
    for path in TRAINING_MISSIONS:
        raw = mission_mod.read_toml(path)
        found[closure(mission_mod.requested_plugins(raw))] = path
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


def build_once(mission: Mission, registry: Register) -> Simulation:
    """Build the mission's components once, on its first scenario (as `ata check` does): a
    component that cannot fill its slot, or a checkpoint that cannot be read, fails here,
    before any work starts."""
    return Simulation(mission.replace(scenarios=1), registry, [mission.settings.first_scenario])


def plan_key(session: Session, chunks: list[np.ndarray]) -> str:
    """What decides a run's rows: the resolved mission, the components' versions, the chunks."""
    return runlog.plan_key({"ata": __version__, "mission": session.mission.to_toml(),
                            "versions": session.versions(), "inputs": session.inputs(),
                            "chunks": [[int(c[0]), int(c.size)] for c in chunks]})


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
    run's cache folder (`ata.experiment.cache`; None: none).
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
    merged = {k: np.concatenate([p[k] for p in parts]) for k in parts[0]
              if k not in ("warnings", "wall_s")}
    return RunResult(scenario=merged["scenario"], total=merged["total"],
                     upper_bound=merged["upper_bound"], reallocations=merged["reallocations"],
                     metrics={k[2:]: v for k, v in merged.items() if k.startswith("m:")},
                     wall_s=wall, warnings=[w for p in parts for w in p["warnings"]])


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


def write_run(out_dir: str | Path, session: Session, result: RunResult) -> Path:
    """Write results.csv, summary.json, the resolved mission and the plugin versions."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    rows = result.rows()
    runlog.write_csv(out / "results.csv", list(rows[0]), rows)
    (out / "summary.json").write_text(json.dumps(summarize(result), indent=2) + "\n")
    (out / "mission.resolved.toml").write_text(session.mission.to_toml(), encoding="utf-8")
    versions = {"ata": __version__, "components": session.versions(),
                "inputs": session.inputs()}
    (out / "plugins.toml").write_text(tomli_w.dumps(versions), encoding="utf-8")
    return out


def default_out_dir(mission: Mission, prefix: str = "") -> Path:
    """A new folder runs/[PREFIX]NAME-TIME for a run of the mission."""
    return stamped_folder(f"{prefix}{mission.settings.name}")


def runs_root() -> Path:
    """Where output folders go by default: $ATA_RUNS, else runs/."""
    return Path(os.environ.get("ATA_RUNS", "runs"))


def stamped_folder(label: str) -> Path:
    """A new folder runs/LABEL-TIME, created now: two runs started in the same second get
    LABEL-TIME and LABEL-TIME-2."""
    return new_folder(runs_root() / f"{label}-{time.strftime('%Y%m%d-%H%M%S')}")


def new_folder(path: Path) -> Path:
    """Create path, or path-2, path-3 ... if it exists (atomically: mkdir fails on a taken name)."""
    prepare_out_dir(path.parent)
    for n in range(1, 10_000):
        candidate = path if n == 1 else path.with_name(f"{path.name}-{n}")
        try:
            candidate.mkdir()
            return candidate
        except FileExistsError:
            continue
    raise MissionError("--out", None, f"no free folder name like {path}")


def prepare_out_dir(path: Path) -> Path:
    """Create the output folder and check that it can be written, before any work is done; a
    path under a file or a folder without write permission is one clear error."""
    path = Path(path)
    try:
        path.mkdir(parents=True, exist_ok=True)
        probe = path / f".ata-write-check-{os.getpid()}"
        probe.write_bytes(b"")
        probe.unlink()
    except OSError as exc:
        raise MissionError("--out", None, f"cannot write to {path}: "
                           f"{exc.strerror or exc}") from None
    return path
