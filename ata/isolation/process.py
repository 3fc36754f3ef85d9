"""`--isolate`: a mission's decision components run apart, in a sandboxed process of their own.

The host's kernel holds proxies in their slots (`ata.isolation.proxies`).

The host keeps the mission, the root seed and the world (the `Simulation` with its world
components). Each batch has a decision process (`ata.runtime.decider`, in the sandbox of
`ata.runtime.sandbox`; started for it, or kept from the same method's batch before), which
builds the decision components from the public mission. The
proxies put in the decision slots (the kernel's ``overrides``) forward each decision phase to it
in one round trip per batch: what a `DecisionContext` holds goes out (pickled), reconstructions,
conditions and allocations come back as safe frames (`ata.runtime.frames`: JSON and numeric
arrays, never unpickled), checked here and by the kernel again.

Each call has a time limit (`Isolation.decision_timeout_s`). Past it, the process is killed: an
initial allocation (or a reconstruction before it) that times out fails the batch; a later one
leaves the allocation in force for the rest of the batch's episode, and every scenario of the
batch counts it in the results column ``decision_timeouts``.
"""

from __future__ import annotations

import atexit
import dataclasses
import os
import pickle
import signal
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from typing import Any

import numpy as np

from ata.core.components import DECISION_SLOTS
from ata.core.errors import ContractError, MissionError
from ata.core.kernel import is_reference
from ata.core.mission import SLOT_KINDS, Mission
from ata.core.registry import Register
from ata.isolation.remote import RemoteComponent, code_locations
from ata.runtime import memory, sandbox
from ata.runtime.frames import (HEADER_ONLY, MAX_FRAME, FrameError, HostPipe, PeerGone,
                                PeerTimeout)
from ata.runtime.inputs import resolve
from ata.runtime.messages import Op

DEFAULT_DECISION_TIMEOUT = 60.0
"""Seconds a decision call (one phase of one batch) may take by default."""
TIMEOUT_COLUMN = "decision_timeouts"


@dataclass(frozen=True)
class Isolation:
    """How a run isolates its decision components: the time limit of one decision call, and of
    the process's start (its imports, its components' construction, their checkpoints)."""

    decision_timeout_s: float = DEFAULT_DECISION_TIMEOUT
    startup_timeout_s: float = 300.0

    def key(self) -> dict[str, Any]:
        """What a plan key holds of it: a timeout can change rows, isolation never should."""
        return {"isolate": True, "decision_timeout_s": self.decision_timeout_s}


class ChildFailed(ContractError):
    """The decision process failed: an exception in a component (its traceback as text), a
    broken frame, or an exit."""


class DecisionTimeout(ChildFailed):
    """A decision call took longer than its time limit."""


# -- what the decision process needs of the method's code ----------------------------------------
def _under(path: str, roots: list[str]) -> bool:
    return any(path == r or path.startswith(r.rstrip("/") + "/") for r in roots)


def method_code(mission: Mission, registry: Register
                ) -> tuple[list[str], list[Any], list[str], bool]:
    """(plugin modules to load, paths to show read-only, folders to add to sys.path, whether
    those modules are all it needs) for the decision process: the method's own package (or
    module file) and the files its settings name; the Python installation and `ata` are shown
    anyway."""
    shown = [*sandbox.python_dirs(), sandbox.ata_dir()]
    modules, binds, paths, only = [], [], [], True
    for slot in DECISION_SLOTS:
        value = getattr(mission.slots, slot)
        for name in value if isinstance(value, list) else [value]:
            info = registry.get(SLOT_KINDS[slot], name, "[components]")
            if isinstance(info.factory, RemoteComponent):
                # a method the host never imported: the process loads every plugin, and sees
                # every third-party package's code (found without running it)
                more_binds, more_paths = code_locations()
                more_binds += list(info.factory.remote.binds)      # a file named by reference
                more_paths += list(info.factory.remote.paths)
                binds += [b for b in more_binds if not _under(b, shown)]
                shown += more_binds
                paths += more_paths
                only = False
                continue
            if slot == "reconstructors" and is_reference(info.factory):
                raise MissionError("--isolate", None, f"reconstructor {name!r} is a reference "
                                   "that reads the true state, not a method: run it without "
                                   "--isolate")
            if info.plugin in sys.modules:
                modules.append(info.plugin)
            else:                       # an entry point's name: the process loads them all
                only = False
            for mod_name in (info.plugin, getattr(info.factory, "__module__", "")):
                top = sys.modules.get(mod_name.split(".")[0])
                if top is None:
                    continue
                for where in getattr(top, "__path__", None) or [getattr(top, "__file__", "")]:
                    where = os.path.realpath(where) if where else ""
                    if where and not _under(where, shown):
                        binds.append(where)
                        shown.append(where)
                        if os.path.isfile(where):
                            paths.append(os.path.dirname(where))
            settings = mission.component_settings.get(name)
            if settings is not None and dataclasses.is_dataclass(settings):
                for f in dataclasses.fields(settings):
                    value_ = getattr(settings, f.name)
                    if isinstance(value_, str) and value_ and resolve(value_).is_file():
                        # shown where the setting names it (relative to the working folder,
                        # which the process shares), whatever link leads there
                        where = os.path.abspath(resolve(value_))
                        if not _under(os.path.realpath(where), shown):
                            binds.append((os.path.realpath(where), where))
    return (list(dict.fromkeys(modules)), list(dict.fromkeys(binds)),
            list(dict.fromkeys(paths)), only)


RESOLVE = "resolving the method"


def _ask_once(isolation: Isolation, req: dict[str, Any], what: str,
              files: list[str] = (), folders: list[str] = ()) -> dict[str, Any]:
    """One request to a sandboxed process started for it (shown every third-party package and
    `files`) and ended after: the host's questions about code it does not import."""
    binds, paths = code_locations()
    process = DecisionProcess(_spare_key(isolation) + (req["op"],), None, ([], [], True),
                              binds + list(files), isolation)
    try:
        header, _ = process.call({**req, "paths": paths + list(folders)},
                                 isolation.startup_timeout_s, what, HEADER_ONLY)
    finally:
        process.close()
    return header


def resolver(isolation: Isolation):
    """The `resolve` of `ata.isolation.remote.isolated_registry`: a sandboxed process loads
    every plugin, validates the mission and answers the resolved settings of the components the
    host did not load."""
    def resolve(raw: dict[str, Any], source: str, wanted: list[tuple[str, str]],
                files: list[str] = (), folders: list[str] = ()) -> Any:
        return _ask_once(isolation, {"op": Op.RESOLVE, "mission": raw, "source": source,
                                     "components": wanted}, RESOLVE, files, folders)
    return resolve


def prober(isolation: Isolation):
    """The `probe` of `ata.isolation.remote`: what one ``ata``-group entry point registers,
    as a sandboxed process that imported it alone says (cached per process and entry point:
    the installed packages do not change during a run)."""
    def probe(entry_point: str) -> Any:
        if entry_point not in _PROBED:
            try:
                _PROBED[entry_point] = _ask_once(
                    isolation, {"op": Op.PROBE, "entry_point": entry_point},
                    f"importing the plugin {entry_point!r} alone")
            except ChildFailed:                   # one that fails to load provides nothing
                _PROBED[entry_point] = {"components": []}
        return _PROBED[entry_point]
    return probe


_PROBED: dict[str, Any] = {}


# -- the process -------------------------------------------------------------------------------
MAX_IDLE = 2
"""Decision processes kept started between batches (a unit of the same method reuses one and
pays its imports once); more would hold memory for methods no unit runs next."""
_IDLE: dict[tuple, "DecisionProcess"] = {}


def _spare_key(isolation: Isolation) -> tuple:
    return ("spare", (), os.getcwd(), isolation)


def prestart(isolation: Isolation) -> None:
    """Start a spare decision process, one that has run no method yet (so any method may have
    it) and shows no method's own code (so only a built-in or installed method can)."""
    key = _spare_key(isolation)
    if key not in _IDLE:
        _keep(DecisionProcess(key, None, ([], [], True), [], isolation))


def acquire(mission: Mission, registry: Register, isolation: Isolation) -> "DecisionProcess":
    """A decision process for a batch of `mission`: an idle one of the same method (the same
    public mission, code and files: never another method's, which could have left something in
    it), told to build its components anew, else a new one."""
    modules, binds, paths, only = method_code(mission, registry)
    blob = pickle.dumps(mission.public(), protocol=5)
    same = pickle.dumps(mission.replace(scenarios=1, first_scenario=0).public(), protocol=5)
    key = (same, tuple(binds), os.getcwd(), isolation)
    process = _IDLE.pop(key, None)
    if process is not None and process.alive and process.proc.poll() is None:
        process.begin(blob, modules, paths, only)
        return process
    if process is not None:
        process.close()
    spare = _IDLE.pop(_spare_key(isolation), None) if not binds else None
    if spare is not None and spare.alive and spare.proc.poll() is None:
        spare.key = key
        spare.begin(blob, modules, paths, only)
        return spare
    if spare is not None:
        spare.close()
    return DecisionProcess(key, blob, (modules, paths, only), binds, isolation)


def release(process: "DecisionProcess") -> None:
    """A batch is over and went well: keep its process for the method's next batch."""
    if not (process.alive and process.proc.poll() is None):
        process.close()
        return
    _keep(process)


def _keep(process: "DecisionProcess") -> None:
    """Keep `process` idle under its key, ending the one it replaces and the oldest beyond
    `MAX_IDLE`."""
    other = _IDLE.pop(process.key, None)
    if other is not None and other is not process:
        other.close()
    _IDLE[process.key] = process
    while len(_IDLE) > MAX_IDLE:
        _IDLE.pop(next(iter(_IDLE))).close()


def close_idle() -> None:
    """End every idle decision process (a plan's end, this process's exit)."""
    while _IDLE:
        _IDLE.popitem()[1].close()


atexit.register(close_idle)


class DecisionProcess:
    """One sandboxed decision process: started at once (its imports overlap the host's set-up),
    told a batch's mission with `begin`, asked with `call`, ended with `close` (or killed)."""

    def __init__(self, key: tuple, blob: bytes | None,
                 code: tuple[list[str], list[str], bool], binds: list[str],
                 isolation: Isolation):
        self.key, self.isolation = key, isolation
        missions = os.path.join(sandbox.ata_dir(), "missions")
        argv = [sys.executable, "-s", *(["-P"] if sys.version_info >= (3, 11) else []),
                "-m", "ata.runtime.decider"]
        cmd = sandbox.command(argv, binds=binds, cwd=os.getcwd(),
                              hide=[missions] if os.path.isdir(missions) else [])
        self.stderr = tempfile.TemporaryFile()
        self.proc = subprocess.Popen(cmd, stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                                     stderr=self.stderr, env=sandbox.host_env(),
                                     start_new_session=True, close_fds=True,
                                     preexec_fn=sandbox.limits(memory.memory_limit()))
        self.pipe = HostPipe(self.proc.stdin.fileno(), self.proc.stdout.fileno())
        self.alive = True
        self.ready = True           # nothing asked yet (a spare): nothing to wait for
        if blob is not None:
            self.begin(blob, *code)

    def begin(self, blob: bytes, modules: list[str], paths: list[str], only: bool) -> None:
        """Have the process build a batch's decision components (answered at the next call)."""
        self.ready = False
        try:
            # the mission pickled apart: its settings classes may come from the method's own
            # module, which the process can import once it has the paths
            self.pipe.send({"op": Op.INIT, "mission": blob, "modules": modules, "paths": paths,
                            "only": only},
                           time.monotonic() + self.isolation.startup_timeout_s)
        except (PeerGone, PeerTimeout):
            self._failed("start")

    def call(self, req: dict[str, Any], limit: float, what: str, max_bytes: int = MAX_FRAME
             ) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
        """Send a request and wait for its answer, at most `limit` seconds (a DecisionTimeout
        past it, the process killed) and `max_bytes` long (`frames.answer_limit`); a
        ChildFailed for an error in the process or an answer out of bounds."""
        if not self.alive:
            raise ChildFailed("the decision process has ended")
        if not self.ready:
            limit_s = self.isolation.startup_timeout_s
            try:
                header, _ = self.pipe.recv(time.monotonic() + limit_s, HEADER_ONLY)
            except PeerTimeout:
                self.kill()
                raise ChildFailed(f"the decision process did not build the method within "
                                  f"{limit_s:g} s; it was stopped") from None
            except (PeerGone, FrameError) as exc:
                self._failed("start", exc)
            self._check(header, "start")
            self.ready = True
        try:
            deadline = time.monotonic() + limit
            self.pipe.send(req, deadline)
            header, arrays = self.pipe.recv(deadline, max_bytes)
        except PeerTimeout:
            self.kill()
            raise DecisionTimeout(f"{what} took longer than the decision time limit of "
                                  f"{limit:g} s (--decision-timeout); its process was "
                                  "stopped") from None
        except (PeerGone, FrameError) as exc:
            self._failed(what, exc)
        self._check(header, what)
        return header, arrays

    def _check(self, header: dict[str, Any], what: str) -> None:
        if "error" in header:
            self.kill()
            text = str(header.get("error"))[-20000:]
            if header.get("kind") == "MissionError" and what in ("start", RESOLVE):
                raise MissionError("--isolate", None, f"the decision process could not "
                                   f"{'build' if what == 'start' else 'load'} the method: "
                                   f"{text}")
            raise ChildFailed(f"{what} failed in the decision process (sandboxed): {text}")

    def _failed(self, what: str, exc: Exception | None = None) -> None:
        self.kill()
        self.stderr.seek(0)
        tail = self.stderr.read()[-4000:].decode("utf-8", "replace").strip()
        raise ChildFailed(f"the decision process failed during {what}"
                          + (f" ({exc})" if exc else "") + (f"; its output ended with:\n{tail}"
                                                          if tail else ""))

    def kill(self) -> None:
        if self.proc.poll() is None:
            try:
                os.killpg(self.proc.pid, signal.SIGKILL)   # bwrap; the sandbox dies with it
            except ProcessLookupError:
                pass
        self.proc.wait()
        self.alive = False

    def close(self, ask: bool = True) -> None:
        """End the process: asked first (`ask`), killed if it does not go within a second;
        killed at once after an error or Ctrl-C, when it may be busy."""
        if ask and self.alive and self.proc.poll() is None:
            try:
                self.pipe.send({"op": Op.CLOSE}, time.monotonic() + 1.0)
                self.proc.wait(timeout=1.0)
            except (PeerGone, PeerTimeout, subprocess.TimeoutExpired):
                pass
        self.kill()
        for f in (self.proc.stdin, self.proc.stdout, self.stderr):
            try:
                f.close()
            except OSError:
                pass

