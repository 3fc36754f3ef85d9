"""The one chunked runner under `ata run` and `ata eval`: a plan's scenarios cut into work units,
run on an `Executor` (serial, process, Ray), each unit recorded as it finishes.

A unit is a chunk of one mission's scenario ids. A scenario's numbers depend on (seed, scenario
id) alone, so the rows do not depend on the executor, the worker count or the chunking. `ata
run` is a plan of one mission; `ata eval` one of many (method, setting, level) jobs.
"""

from __future__ import annotations

import contextlib
import copy
import dataclasses
import sys
import time
from dataclasses import dataclass
from typing import Any, Callable, Iterator

import numpy as np

from ata.core.kernel import Simulation
from ata.core.mission import Mission
from ata.core.references import restore
from ata.core.registry import Register, collect_components, get_plugin_manager
from ata.experiment import runlog
from ata.experiment.interrupts import Interrupts
from ata.experiment.isolate import Isolation, prober
from ata.experiment.remote import worker_registry
from ata.runtime.cache import run_cache
from ata.runtime.executors import Executor

RUN_CHUNK = 100
"""`ata run`'s batches hold at most this many scenarios, so that a long run is saved as it goes
(each batch is recorded as it ends); bigger batches step faster (docs/evaluation.md)."""


def run_batch(mission: Mission, registry: Register, scenario_ids: np.ndarray,
              on_epoch: Callable[[int], None] | None = None,
              isolate: Isolation | None = None) -> dict[str, Any]:
    """Simulate one batch and return its per-scenario arrays; with `isolate`, its decision
    components run in a sandboxed process of their own (`ata.experiment.isolate`)."""
    if isolate is None:
        record = Simulation(mission, registry, scenario_ids).run(on_epoch=on_epoch)
    else:
        from ata.experiment.proxies import isolated_simulation
        with isolated_simulation(mission, registry, scenario_ids, isolate) as sim:
            record = sim.run(on_epoch=on_epoch)
    out = {"scenario": np.asarray(scenario_ids), "total": record.total,
           "upper_bound": record.upper_bound.copy(),
           "reallocations": record.reallocated.sum(axis=1)}
    out.update({f"m:{k}": np.asarray(v, dtype=float) for k, v in record.metrics.items()})
    out["warnings"] = list(record.warnings)
    return out


def one_worker(mission: Mission) -> Mission:
    """A copy whose components run no process pools of their own (the executor already uses
    every core): each component setting called `workers` is set to 1. Results are unchanged."""
    out = None
    for name, st in mission.component_settings.items():
        if st is not None and getattr(st, "workers", 1) > 1:
            out = out or copy.deepcopy(mission)
            out.component_settings[name] = dataclasses.replace(st, workers=1)
    return out or mission


@contextlib.contextmanager
def torch_one_thread() -> Iterator[None]:
    """One torch thread while a unit runs (when torch is loaded), on every executor alike, so
    that no reduction order depends on where a unit ran."""
    torch = sys.modules.get("torch")
    if torch is None:
        yield
        return
    previous = torch.get_num_threads()
    torch.set_num_threads(1)
    try:
        yield
    finally:
        torch.set_num_threads(previous)


def scenario_ids(mission: Mission) -> np.ndarray:
    s = mission.settings
    return s.first_scenario + np.arange(s.scenarios, dtype=np.int64)


def chunks_of(mission: Mission, workers: int, chunk_size: int | None = None) -> list[np.ndarray]:
    """`ata run`'s chunking: the scenario ids in batches of at most batch_size (and at most
    `chunk_size`, when given); with several workers, small enough that each worker gets one."""
    ids = scenario_ids(mission)
    size = mission.settings.batch_size
    if chunk_size is not None:
        size = min(size, chunk_size)
    if workers > 1:
        size = max(1, min(size, -(-ids.size // workers)))
    return fixed_chunks(ids, size)


def fixed_chunks(ids: np.ndarray, size: int) -> list[np.ndarray]:
    """`ids` in chunks of `size` (the last one shorter)."""
    return [ids[i:i + size] for i in range(0, ids.size, size)]


@dataclass
class Unit:
    """A chunk of one job's scenario ids: what a worker runs.

    ``registry`` is set only for units run in this process (a serial executor): the session's
    own, which may hold components no fresh plugin manager finds (a test's inline ones). A unit
    sent to a worker builds a fresh plugin manager there. ``isolate``: its decision components
    run in a sandboxed process apart (`--isolate`; one per method and host process at a time,
    kept between its units).
    """

    job: int
    mission: Mission
    ids: np.ndarray
    cache: str | None = None
    parallel: bool = False
    registry: Register | None = None
    isolate: Isolation | None = None


def make_units(missions: list[Mission], chunks: list[list[np.ndarray]], *,
               cache: Any = None, executor: Executor | None = None,
               registries: list[Register] | None = None,
               isolate: Isolation | None = None) -> list[Unit]:
    """The units of a plan: job j's mission over each of its chunks, in order."""
    parallel = bool(executor is not None and executor.parallel)
    units = []
    for j, (mission, parts) in enumerate(zip(missions, chunks)):
        registry = None if parallel or registries is None else registries[j]
        for ids in parts:
            units.append(Unit(j, mission, ids, str(cache) if cache is not None else None,
                              parallel, registry, isolate))
    return units


def run_unit(unit: Unit, on_epoch: Callable[[int], None] | None = None) -> dict[str, Any]:
    """Run one unit (in a fresh plugin manager unless it carries its registry); the result
    carries the unit's wall time."""
    t0 = time.perf_counter()
    if unit.mission.source.startswith("published:"):   # a suite's published method: read
        from ata.experiment.published import unit_part
        part = unit_part(unit.mission, unit.ids)
        for epoch in range(unit.mission.clock.n_epochs if on_epoch is not None else 0):
            on_epoch(epoch)                            # the progress bar counts it done
        return {**part, "wall_s": 0.0}
    mission = one_worker(unit.mission) if unit.parallel else unit.mission
    registry = unit.registry
    if registry is None and unit.isolate is not None:
        # a method the host never imports (--isolate) stays out of its workers too
        registry = worker_registry(mission, prober(unit.isolate))
    elif registry is None:
        registry = collect_components(get_plugin_manager(optional=mission.settings.plugins))
        restore(mission.references, registry)    # the components it names by reference
    with torch_one_thread(), run_cache(unit.cache):
        out = run_batch(mission, registry, unit.ids, on_epoch=on_epoch, isolate=unit.isolate)
    out["wall_s"] = time.perf_counter() - t0
    return out


def run_units(units: list[Unit], executor: Executor, *, log: runlog.RunLog | None = None,
              progress: Callable[[float], None] | None = None) -> tuple[list[dict], float]:
    """Run the units `log` does not hold yet; return every unit's result, in unit order, and
    the wall time.

    :param log: the output folder's record: each unit is recorded there durably as it ends.
    :param progress: told of n more scenarios done (a float: run in this process, a unit
        reports each epoch as a share of its scenarios).
    """
    parts, todo = runlog.parts_and_todo(log, len(units))
    t0 = time.perf_counter()
    with Interrupts() as interrupts:
        def with_epochs(unit: Unit) -> dict:
            share = unit.ids.size / unit.mission.clock.n_epochs

            def on_epoch(_epoch: int) -> None:
                interrupts.check()
                if progress is not None:
                    progress(share)
            return run_unit(unit, on_epoch=on_epoch)

        fn = run_unit if executor.parallel else with_epochs
        for k, out in executor.run(fn, [units[i] for i in todo]):
            i = todo[k]
            parts[i] = out
            if log is not None:
                log.add(i, out)
            if progress is not None and executor.parallel:
                progress(float(np.asarray(out["scenario"]).size))
            interrupts.check()
    return parts, time.perf_counter() - t0
