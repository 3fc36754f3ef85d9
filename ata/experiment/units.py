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
from threadpoolctl import threadpool_limits

from ata.backend import IN_PROCESS, Backend
from ata.core.mission import Mission
from ata.core.registry import Register
from ata.experiment import runlog
from ata.experiment.interrupts import Interrupts
from ata.runtime.cache import run_cache
from ata.runtime.executors import Executor

RUN_CHUNK = 100
"""`ata run`'s batches hold at most this many scenarios, so that a long run is saved as it goes
(each batch is recorded as it ends); bigger batches step faster (docs/evaluation.md)."""


def run_batch(mission: Mission, registry: Register | None, scenario_ids: np.ndarray,
              on_epoch: Callable[[int], None] | None = None,
              backend: Backend = IN_PROCESS) -> dict[str, Any]:
    """Simulate one batch where `backend` runs its decisions and return its per-scenario
    arrays (`ata.backend.Part`)."""
    return backend.run_batch(mission, registry, np.asarray(scenario_ids), on_epoch)


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
def one_thread() -> Iterator[None]:
    """One thread for torch (when it is loaded) and for numpy's BLAS while a unit runs, on every
    executor alike: no reduction order depends on where a unit ran, and a unit's matrix
    products do not spin threads beside the other workers."""
    torch = sys.modules.get("torch")
    previous = torch.get_num_threads() if torch is not None else None
    if torch is not None:
        torch.set_num_threads(1)
    try:
        with threadpool_limits(1, user_api="blas"):
            yield
    finally:
        if torch is not None:
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
    sent to a worker builds the registry its backend gives there. ``backend``: where its
    decisions run (`ata.backend`).
    """

    job: int
    mission: Mission
    ids: np.ndarray
    cache: str | None = None
    parallel: bool = False
    registry: Register | None = None
    backend: Backend = IN_PROCESS


def make_units(missions: list[Mission], chunks: list[list[np.ndarray]], *,
               cache: Any = None, executor: Executor | None = None,
               registries: list[Register] | None = None,
               backends: list[Backend] | None = None) -> list[Unit]:
    """The units of a plan: job j's mission over each of its chunks, in order, where job j's
    backend runs them."""
    parallel = bool(executor is not None and executor.parallel)
    units = []
    for j, (mission, parts) in enumerate(zip(missions, chunks)):
        registry = None if parallel or registries is None else registries[j]
        backend = backends[j] if backends is not None else IN_PROCESS
        for ids in parts:
            units.append(Unit(j, mission, ids, str(cache) if cache is not None else None,
                              parallel, registry, backend))
    return units


def run_unit(unit: Unit, on_epoch: Callable[[int], None] | None = None) -> dict[str, Any]:
    """Run one unit (with the registry its backend gives a worker, unless it carries one); the
    result carries the unit's wall time."""
    t0 = time.perf_counter()
    mission = one_worker(unit.mission) if unit.parallel else unit.mission
    registry = unit.registry if unit.registry is not None else \
        unit.backend.worker_registry(mission)
    with one_thread(), run_cache(unit.cache):
        out = run_batch(mission, registry, unit.ids, on_epoch=on_epoch, backend=unit.backend)
    out.setdefault("wall_s", time.perf_counter() - t0)
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
