"""Where `ata eval` runs its work units: in this process, in local worker processes, or on a
Ray cluster. One interface: `run(fn, units)` yields `(index, fn(units[index]))` as units finish,
in any order; the caller puts results back in order, so no executor can change a number."""

from __future__ import annotations

import functools
import multiprocessing
import os
import pickle
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from typing import Any, Callable, Iterator, Sequence

from ata.core.errors import ContractError, MissionError
from ata.runtime import extras

EXECUTORS = ("serial", "process", "ray")


def cpu_count() -> int:
    """The cores this process may use."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:       # not on Linux
        return os.cpu_count() or 1


class Executor:
    """Runs `fn` on each unit; subclasses say where."""

    name = "?"
    parallel = False

    def run(self, fn: Callable[[Any], Any], units: Sequence[Any]) -> Iterator[tuple[int, Any]]:
        raise NotImplementedError

    def describe(self) -> dict[str, Any]:
        return {"executor": self.name}

    def close(self) -> None:
        pass

    def __enter__(self) -> "Executor":
        return self

    def __exit__(self, *exc) -> None:
        self.close()


class SerialExecutor(Executor):
    """Every unit in this process, in order."""

    name = "serial"

    def run(self, fn, units):
        for i, unit in enumerate(units):
            yield i, fn(unit)


class ProcessExecutor(Executor):
    """A local pool of worker processes (spawned, so that nothing the parent imported, such as
    torch's thread pools, is inherited half-initialised)."""

    name = "process"
    parallel = True

    def __init__(self, workers: int | None = None):
        self.workers = workers or cpu_count()

    def describe(self):
        return {"executor": self.name, "workers": self.workers}

    def run(self, fn, units):
        if not units:
            return
        workers = min(self.workers, len(units))
        context = multiprocessing.get_context("spawn")
        pool = ProcessPoolExecutor(max_workers=workers, mp_context=context,
                                   initializer=_die_with_parent, initargs=(os.getpid(),))
        finished = False
        manager = None
        try:
            plain = functools.partial(_plainly, fn)
            pending = {pool.submit(plain, pickle.dumps(unit)): i for i, unit in enumerate(units)}
            # the pool's manager thread (started by the first submit); shutdown forgets it
            manager = getattr(pool, "_executor_manager_thread", None)
            while pending:
                done, _ = wait(pending, return_when=FIRST_COMPLETED)
                # the units that finished first, so that their results are kept (recorded)
                # when another one failed at the same time
                for future in sorted(done, key=lambda f: f.exception() is not None):
                    i = pending.pop(future)
                    try:
                        answer = future.result()
                    except BrokenProcessPool:
                        codes = sorted({p.exitcode for p in getattr(pool, "_processes",
                                                                   {}).values()
                                        if p.exitcode not in (None, 0)})
                        raise WorkerDied(codes) from None
                    yield i, pickle.loads(answer)
            finished = True
        finally:
            if not finished:
                # interrupted (Ctrl-C, an error, the caller stopped): stop the units under way
                # now instead of waiting for them to finish
                for process in list(getattr(pool, "_processes", {}).values()):
                    process.terminate()
            pool.shutdown(wait=finished, cancel_futures=True)
            if not finished and manager is not None:
                # the manager thread closes its wake-up pipe as it winds down; let it finish
                # here, or Python's exit hook may write to that pipe while it is being closed
                # (CPython 3.11: "Exception ignored ... Bad file descriptor" after a Ctrl-C).
                # Taken before shutdown, which drops the pool's reference when it does not wait
                manager.join(timeout=5)


class WorkerError(RuntimeError):
    """An error raised in a worker that cannot cross back as itself (it does not survive
    pickling): its type and message, the worker's traceback chained below it."""


class WorkerDied(WorkerError):
    """A worker process ended without an answer (a component called ``os._exit`` or crashed,
    or the system killed the process, for memory say); the units that finished are kept."""

    def __init__(self, codes: list[int]):
        how = ", ".join(f"signal {-c}" if c < 0 else f"exit code {c}" for c in codes)
        super().__init__(f"a worker process ended without an answer{f' ({how})' if how else ''}: "
                         "a component ended or crashed the process, or the system killed it "
                         "(memory: try fewer --workers); the units that finished are saved, "
                         "and the same command with the same --out resumes the rest")
        self.codes = codes


def _plainly(fn: Callable[[Any], Any], data: bytes) -> bytes:
    """In a worker: `fn` of the unit pickled in `data`, its result pickled. The unit and the
    result cross as bytes, so that an error in reading either is raised where it is handled
    (here, or in the caller) and not in the pool's own threads, where any error breaks the
    whole pool (a unit whose method file changed: a `BrokenProcessPool`). An error crosses
    back as itself when it survives pickling (a MissionError or ContractError: the same
    one-line refusal), else as a `WorkerError` naming it."""
    try:
        return pickle.dumps(fn(pickle.loads(data)))
    except Exception as exc:
        if isinstance(exc, (MissionError, ContractError)) or _crosses(exc):
            raise
        raise WorkerError(f"{type(exc).__name__}: {exc}") from exc


def _crosses(exc: BaseException) -> bool:
    try:
        return type(pickle.loads(pickle.dumps(exc))) is type(exc)
    except Exception:       # any failure to pickle or unpickle: it would not cross
        return False


def _die_with_parent(parent: int) -> None:
    """In a worker: leave Ctrl-C to the parent (which stops the pool), and ask the kernel to end
    this process when its parent dies (Linux), so that a killed `ata eval` leaves no worker
    behind."""
    import signal   # on use: in the worker that dies with its parent

    signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        import ctypes   # on use: Linux's prctl, where there is one

        libc = ctypes.CDLL(None, use_errno=True)
        PR_SET_PDEATHSIG = 1
        libc.prctl(PR_SET_PDEATHSIG, signal.SIGKILL)
        if os.getppid() != parent:    # the parent died before the request took effect
            os._exit(1)
    except (OSError, AttributeError):  # not Linux: the pool's own shutdown has to do
        pass


class RayExecutor(Executor):
    """Ray tasks, one CPU each: on the cluster at `address` (or $RAY_ADDRESS), else on a local
    Ray instance started here (with `workers` CPUs when given). The `ata` package (and any
    third-party plugin a mission names) must be importable on the cluster's nodes."""

    name = "ray"
    parallel = True

    def __init__(self, address: str | None = None, workers: int | None = None):
        def load() -> Any:
            import ray   # the optional extra ata[ray]
            return ray
        ray = extras.required("ray", load, "--executor ray needs ray, which is not installed")
        self.ray = ray
        self.address = address or os.environ.get("RAY_ADDRESS") or None
        self.workers = workers
        self._started = False
        if not ray.is_initialized():
            kwargs: dict[str, Any] = {"address": self.address, "log_to_driver": False}
            if self.address is None and workers:
                kwargs["num_cpus"] = workers
            try:
                ray.init(**kwargs)
            except ConnectionError as exc:
                raise MissionError("--address", None, f"cannot connect to the Ray cluster at "
                                   f"{self.address!r}: {exc}") from None
            self._started = True

    def describe(self):
        return {"executor": self.name, "address": self.address or "local",
                "cpus": self.ray.cluster_resources().get("CPU")}

    def run(self, fn, units):
        if not units:
            return
        remote = self.ray.remote(num_cpus=1, max_retries=0)(_plainly)
        pending = {remote.remote(fn, pickle.dumps(unit)): i for i, unit in enumerate(units)}
        try:
            while pending:
                done, _ = self.ray.wait(list(pending), num_returns=1)
                for ref in done:
                    i = pending.pop(ref)
                    try:
                        value = self.ray.get(ref)
                    except self.ray.exceptions.RayTaskError as exc:
                        cause = getattr(exc, "cause", None)   # a refusal: the same one line
                        if isinstance(cause, (MissionError, ContractError)):
                            raise cause from None
                        raise
                    yield i, pickle.loads(value)
        finally:
            for ref in pending:
                self.ray.cancel(ref, force=True)

    def close(self):
        if self._started:
            self.ray.shutdown()
            self._started = False


def make_executor(name: str, workers: int | None = None,
                  address: str | None = None) -> Executor:
    """The executor called `name`: serial, process or ray."""
    if name == "serial":
        return SerialExecutor()
    if name == "process":
        return ProcessExecutor(workers)
    if name == "ray":
        return RayExecutor(address, workers)
    raise MissionError("--executor", None, f"unknown executor {name!r}; choose one of "
                       + ", ".join(EXECUTORS))
