"""``--isolate`` as a backend (`ata.backend`): the decision components of every batch run in a
sandboxed process, proxies in their slots; the world, the seed and the scoring stay here."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Callable, ClassVar

import numpy as np

from ata.backend import IN_PROCESS, OnEpoch, Part, batch_part
from ata.core.errors import MissionError
from ata.core.kernel import Simulation
from ata.core.mission import Mission
from ata.core.registry import Register
from ata.isolation.process import (DEFAULT_DECISION_TIMEOUT, Isolation, close_idle, prestart,
                                   prober, resolver)
from ata.isolation.proxies import isolated_simulation
from ata.isolation.remote import isolated_registry, worker_registry
from ata.runtime import bytecode, sandbox


@dataclass(frozen=True)
class Isolated(Isolation):
    """Decisions in a sandboxed process (`Isolation`'s time limits): no third-party method is
    imported in the host or its workers; a mission is validated in a sandbox
    (`ata.isolation.remote`)."""

    label: ClassVar[str] = "isolated"

    def registry(self, raw: dict[str, Any], optional: list[str], source: str,
                 extra: tuple = ()) -> tuple[Register, dict[str, Any]]:
        if extra:                        # plugin objects of this process: nothing to isolate
            return IN_PROCESS.registry(raw, optional, source, extra)
        return isolated_registry(raw, optional, source, resolver(self), prober(self))

    def check(self, mission: Mission, registry: Register,
              inspect: Callable[[Simulation], None]) -> None:
        with isolated_simulation(mission.replace(scenarios=1), registry,
                                 [mission.settings.first_scenario], self) as sim:
            inspect(sim)                 # its hooks wait for the process to build them

    def worker_registry(self, mission: Mission) -> Register:
        # a method the host never imports stays out of its workers too
        return worker_registry(mission, prober(self))

    def run_batch(self, mission: Mission, registry: Register | None, ids: np.ndarray,
                  on_epoch: OnEpoch | None = None) -> Part:
        registry = registry if registry is not None else self.worker_registry(mission)
        with isolated_simulation(mission, registry, ids, self) as sim:
            return batch_part(ids, sim.run(on_epoch=on_epoch))

    def notes(self, mission: Mission) -> list[str]:
        on = (f"isolated: the decisions run in a sandboxed process (a decision time limit of "
              f"{self.decision_timeout_s:g} s)")
        if mission.secret_seed:
            return [on]
        return [on, f"--isolate on the public seed {mission.seed_label}: a method can recognise "
                "the scenarios of a seed it can guess; a ranking of untrusted methods needs a "
                "secret one (seed = 'env:NAME'; docs/isolation.md)"]

    def open(self, parallel: bool) -> None:
        if parallel:        # those the validation started here serve no worker process
            close_idle()

    def close(self) -> None:
        close_idle()        # the decision processes kept between batches end with the plan


def require_sandbox(timeout_s: float = DEFAULT_DECISION_TIMEOUT) -> Isolated:
    """The backend of `--isolate`; a MissionError (one line, exit 2) where no sandbox can run,
    saying why and how to get one. It starts a decision process at once (`prestart`), so that
    its start overlaps the loading and checking of the mission."""
    if not timeout_s > 0:
        raise MissionError("--decision-timeout", None, "must be a positive number of seconds")
    bytecode.guard()
    reason = sandbox.unavailable()
    if reason is not None:
        raise MissionError("--isolate", None, reason)
    isolation = Isolated(decision_timeout_s=float(timeout_s),
                         startup_timeout_s=max(300.0, float(timeout_s)))
    prestart(isolation)
    return isolation
