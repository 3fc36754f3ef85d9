"""Policies that try to peek at the world from inside their process (tests/test_isolate.py).

Each is what an adversarial author could write: it decides as greedy unless its route finds the
world, the mission's seed or the host's secrets, and then decides otherwise, with what it found.
"""

from __future__ import annotations

import gc
import os
import sys
import threading
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ata import hookimpl
from ata.core.settings import param
from ata.core.state import Allocation
from ata.plugins.policies.greedy import GreedyPolicy

SECRET_ENV = "ATA_ISOLATE_TEST_SECRET"
"""An environment variable the tests set in the host: a sandboxed policy must not see it."""
SEED_ENV = "ATA_ISOLATE_TEST_SEED"
"""The environment variable of the secret-seed test's ``seed = "env:..."``."""
WORLD_TYPES = ("SimState", "BatchRNG", "Simulation")


def world_in(objects) -> object | None:
    """The first of `objects` that is the world: its state, its generator, the simulation, or a
    mission that still has its root seed."""
    for obj in objects:
        try:
            name = type(obj).__name__
            if name in WORLD_TYPES:
                return obj
            if name == "Mission" and obj.settings.seed is not None:
                return obj
        except Exception:  # noqa: BLE001 - an object that cannot be looked at is not the world
            continue
    return None


class Peeker:
    """Greedy, unless `look` finds something: then every POI goes to its robot alone (no human
    navigator or classifier), where the found generator says so, or everywhere."""

    def __init__(self, settings, mission):
        self.greedy = GreedyPolicy(GreedyPolicy.Settings(), mission)
        self.found = None

    def look(self):
        return None

    def twist(self, alloc: Allocation, found) -> Allocation:
        rng = found if hasattr(found, "uniform") else getattr(found, "rng", None)
        B, P = alloc.robot.shape
        mask = np.ones((B, P), dtype=bool)
        if rng is not None and getattr(rng, "batch_size", None) == B:
            mask = rng.uniform("peek", 0, (P,)) < 0.5        # uses the world's generator
        return Allocation(alloc.robot, np.where(mask, -1, alloc.navigator),
                          np.where(mask, -1, alloc.classifier))

    @hookimpl
    def ata_initial_allocation(self, ctx):
        alloc = self.greedy.ata_initial_allocation(ctx)
        self.found = self.look()
        return alloc if self.found is None else self.twist(alloc, self.found)

    @hookimpl
    def ata_reallocate(self, ctx, active):
        return self.greedy.ata_reallocate(ctx, active)


class PeekGc(Peeker):
    """Every object the interpreter tracks."""

    def look(self):
        return world_in(gc.get_objects())


class PeekFrames(Peeker):
    """The callers' frames, up to the bottom of the stack: the kernel's locals."""

    def look(self):
        frame = sys._getframe()
        while frame is not None:
            found = world_in(frame.f_locals.values())
            if found is not None:
                return found
            frame = frame.f_back
        return None


class PeekThread(Peeker):
    """A thread started when the policy is built that scans gc in the background."""

    def __init__(self, settings, mission):
        super().__init__(settings, mission)
        self.seen = None
        self.done = threading.Event()
        threading.Thread(target=self._scan, daemon=True).start()

    def _scan(self):
        end = time.monotonic() + 5.0
        while time.monotonic() < end and self.seen is None:
            self.seen = world_in(gc.get_objects())
            time.sleep(0.01)
        self.done.set()

    def look(self):
        self.done.wait(0.5)
        return self.seen


class PeekArgv(Peeker):
    """The command line: a mission file, a --set of the seed."""

    def look(self):
        hits = [a for a in sys.argv if ".toml" in a or "seed" in a]
        return hits or None


def _read(path: str) -> bytes:
    try:
        with open(path, "rb") as f:
            return f.read()
    except OSError:
        return b""


class PeekEnv(Peeker):
    """The environment: os.environ, /proc/self, /proc/1, the parent's /proc/PPID, and every
    other process it can see; the host's secrets are in its environment."""

    def look(self):
        for name in (SECRET_ENV, SEED_ENV):
            if name in os.environ:
                return os.environ[name]
        pids = {"self", "1", str(os.getppid())}
        pids |= {p for p in os.listdir("/proc") if p.isdigit()} if os.path.isdir("/proc") \
            else set()
        for pid in sorted(pids):
            for what in ("environ", "cmdline"):
                text = _read(f"/proc/{pid}/{what}")
                for name in (SECRET_ENV, SEED_ENV):
                    if name.encode() in text:
                        return text
        return None


class PeekFiles(Peeker):
    """The files: the checkout the `ata` package was installed from, with its missions."""

    def look(self):
        import ata
        root = Path(ata.__file__).resolve().parents[1]
        found = [p for p in (root / "pyproject.toml", root / "examples" / "missions",
                             root / "ata" / "missions" / "greedy.toml") if p.exists()]
        return found or None


class Sleepy(Peeker):
    """Greedy that sleeps `seconds` in each decision from epoch `at_epoch` on."""

    @dataclass
    class Settings:
        seconds: float = param(5.0, help="how long each late decision sleeps (below 0: an error)")
        at_epoch: int = param(2, min=0, help="the first epoch that sleeps")

    def __init__(self, settings, mission):
        super().__init__(settings, mission)
        self.settings = settings

    def _nap(self, ctx):
        if ctx.epoch >= self.settings.at_epoch:
            time.sleep(self.settings.seconds)

    @hookimpl
    def ata_initial_allocation(self, ctx):
        self._nap(ctx)
        return super().ata_initial_allocation(ctx)

    @hookimpl
    def ata_reallocate(self, ctx, active):
        self._nap(ctx)
        return super().ata_reallocate(ctx, active)


PEEKERS = {"peek_gc": PeekGc, "peek_frames": PeekFrames, "peek_thread": PeekThread,
           "peek_argv": PeekArgv, "peek_env": PeekEnv, "peek_files": PeekFiles}


@hookimpl
def ata_register_components(register):
    register("policy", "peek_none", Peeker)
    for name, factory in PEEKERS.items():
        register("policy", name, factory)
    register("policy", "sleepy", Sleepy)
