"""Running a mission: its plan (one job, its scenarios in batches), the per-scenario results,
summary statistics, and the run folder that makes every number reproducible."""

from __future__ import annotations

import contextlib
import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

import numpy as np
import tomli_w

from ata import __version__
from ata.backend import IN_PROCESS, Backend
from ata.core.kernel import REFERENCE_COLUMN
from ata.core.mission import Mission
from ata.experiment import runlog
from ata.experiment.execute import Done, Plan, ProgressFactory, run_plan
from ata.experiment.units import (RUN_CHUNK, chunks_of, fixed_chunks, make_units, run_units,
                                  scenario_ids)
from ata.runtime import memory
from ata.runtime.executors import Executor, ProcessExecutor, SerialExecutor
from ata.runtime.folders import shown_path, stamped_folder
from ata.runtime.inputs import shipped_setting
from ata.runtime.machine import write_provenance
from ata.session import Session, load_session


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


def run(mission: str | None = None, overrides: list[str] | None = None,
        plugins: list[str] | None = None, out: str | Path | None = None, *,
        workers: int | None = None, executor: str | None = None, address: str | None = None,
        chunk_size: int | None = None, cache: str | Path | None = None, force: bool = False,
        backend: Backend = IN_PROCESS, notify: Callable[[str], None] | None = None,
        progress: ProgressFactory | None = None) -> tuple[Session, Path, RunResult]:
    """`ata run`: load the mission, build its components once (before any folder is made or
    scenario runs), run its plan into `out` (`execute.run_plan`) and write the folder; the
    session, the folder and the result."""
    session = load_session(mission, overrides, plugins, backend=backend)
    workers = workers or session.mission.settings.workers
    build_once(session)
    plan = mission_plan(session, workers, chunk_size or RUN_CHUNK)
    out_dir, result = run_plan(
        plan, lambda done: (done.out_dir, write_done(session, done)), out,
        executor=executor or ("serial" if workers <= 1 else "process"), workers=workers,
        address=address, cache=cache, force=force, notify=notify, progress=progress)
    return session, out_dir, result


def build_once(session: Session) -> None:
    """Build the session's components once, on its first scenario (as `ata check` does), where
    its backend builds them: a component that cannot fill its slot, or a checkpoint that cannot
    be read, fails here, before any work starts."""
    session.backend.check(session.mission, session.registry,
                          lambda sim: sim.pm.hook.ata_trained_on())


def plan_key(session: Session, chunks: list[np.ndarray]) -> str:
    """What decides a run's rows: the resolved mission, the components' versions, the chunks,
    and where the decisions run (a timeout can change rows)."""
    backend = session.backend.key()
    return runlog.plan_key({"ata": __version__, "mission": session.mission.to_toml(),
                            "versions": session.versions(), "inputs": session.inputs(),
                            "code": session.code(),
                            "chunks": [[int(c[0]), int(c.size)] for c in chunks],
                            **({"backend": backend} if backend else {})})


def mission_plan(session: Session, workers: int | None = None,
                 chunk_size: int = RUN_CHUNK) -> Plan:
    """`ata run`'s plan: one job, the mission's scenarios in batches (`units.chunks_of`), cut
    smaller when `workers` of them at once would not fit in memory (`ata.runtime.memory`)."""
    m = session.mission
    workers = workers or m.settings.workers
    chunks = chunks_of(m, workers, chunk_size)
    notes = list(session.backend.notes(m))
    # a batch too big for memory is cut smaller (the rows do not depend on the batches)
    size, limit = max(int(c.size) for c in chunks), memory.memory_limit()
    fits = memory.largest_batch(m, size, workers, limit)
    if fits == 0:
        raise memory.too_large(m, workers, limit)
    if fits < size:
        chunks = fixed_chunks(scenario_ids(m), fits)
        notes.append(f"batches of {fits} scenarios, not {size}: a bigger batch would need more "
                     f"than {memory.limit_text(limit)}")
    return Plan(missions=[m], registries=[session.registry], backends=[session.backend],
                chunks=[chunks],
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
                           registries=[session.registry], backends=[session.backend])
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
            *([("decisions", f"{session.backend.label} (--isolate)")]
              if session.backend.key() else []),
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
        shown = shown_path(value) if isinstance(value, str) else value   # no machine path
        rows.append(("weights", f"{shown} (read by {', '.join(comps)}{made})"))
    return rows


def write_run(out_dir: str | Path, session: Session, result: RunResult) -> Path:
    """Write results.csv, summary.json, the resolved mission, the plugin versions and the
    provenance (`ata.runtime.machine.provenance`)."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    rows = result.rows()
    runlog.write_csv(out / "results.csv", list(rows[0]), rows)
    (out / "summary.json").write_text(json.dumps(summarize(result), indent=2) + "\n")
    (out / "mission.resolved.toml").write_text(session.mission.to_toml(), encoding="utf-8")
    versions = {"ata": __version__, "components": session.versions(),
                "inputs": session.inputs(), "code": session.code()}
    (out / "plugins.toml").write_text(tomli_w.dumps(versions), encoding="utf-8")
    write_provenance(out)
    return out


def default_out_dir(mission: Mission, prefix: str = "") -> Path:
    """A new folder runs/[PREFIX]NAME-TIME for a run of the mission."""
    return stamped_folder(f"{prefix}{mission.settings.name}")
