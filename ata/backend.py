"""Where a batch's decisions run: a *backend*, chosen once per method and carried by its session.

The run path (`ata.experiment`) knows one protocol, `Backend`, and three kinds fill it:

* `InProcess` (here): the mission's components are built in this process (or a worker's) and
  the kernel calls them directly; `ata run` and `ata eval` without ``--isolate``.
* ``ata.isolation.Isolated``: the decision components run in a sandboxed process of their own
  and proxies fill their slots (``--isolate``).
* ``ata.published.PublishedRows``: a suite's ``published:METHOD``, whose rows are read from a
  published set; nothing is built or run.

A session (`ata.session.load_session`) asks its backend for the registry its mission is
validated against; a plan asks each job's backend for its part of the plan key and opens and
closes it around the units; a work unit asks it for the registry a worker builds and for the
batch's per-scenario arrays. A new backend is one class with these methods, and no edit to the
run path.
"""

from __future__ import annotations

from typing import Any, Callable, Protocol, runtime_checkable

import numpy as np

from ata.core.kernel import Simulation
from ata.core.mission import Mission
from ata.core.references import restore
from ata.core.registry import Register, collect_components, get_plugin_manager
from ata.runtime import memory

Part = dict[str, Any]
"""A batch's results: ``scenario``, ``total``, ``upper_bound``, ``reallocations``, one
``m:NAME`` array per metric, and ``warnings`` (a list of text)."""
OnEpoch = Callable[[int], None]


@runtime_checkable
class Backend(Protocol):
    """Where the decisions of a method's batches run (see the module's text)."""

    label: str
    """How messages and summaries name it ("in-process", "isolated", "published rows")."""

    def key(self) -> dict[str, Any]:
        """What a plan key holds of it (empty where it cannot change a row)."""

    def registry(self, raw: dict[str, Any], optional: list[str], source: str,
                 extra: tuple = ()) -> tuple[Register, dict[str, Any]]:
        """The registry a mission (``raw``, read from ``source``, with the ``optional`` plugins
        it asks for and ``extra`` plugin objects) is validated against, and the raw mission to
        validate."""

    def check(self, mission: Mission, registry: Register,
              inspect: Callable[[Simulation], None]) -> None:
        """Build the mission's components once, on its first scenario, and hand the simulation
        to ``inspect`` (nothing, where nothing is built)."""

    def worker_registry(self, mission: Mission) -> Register | None:
        """The registry a worker process builds for a unit of ``mission``."""

    def run_batch(self, mission: Mission, registry: Register | None, ids: np.ndarray,
                  on_epoch: OnEpoch | None = None) -> Part:
        """One batch's per-scenario results."""

    def notes(self, mission: Mission) -> list[str]:
        """What the user should know before a plan of `mission` runs here."""

    def open(self, parallel: bool) -> None:
        """A plan of units starts (on worker processes when ``parallel``)."""

    def close(self) -> None:
        """The plan ended: release what was kept between its batches."""


def batch_part(ids: np.ndarray, record: Any) -> Part:
    """A batch's results from the kernel's run record."""
    out: Part = {"scenario": np.asarray(ids), "total": record.total,
                 "upper_bound": record.upper_bound.copy(),
                 "reallocations": record.reallocated.sum(axis=1)}
    out.update({f"m:{k}": np.asarray(v, dtype=float) for k, v in record.metrics.items()})
    out["warnings"] = list(record.warnings)
    return out


class Quiet:
    """A backend's parts that hold nothing between batches and have nothing to say."""

    def notes(self, mission: Mission) -> list[str]:
        return []

    def open(self, parallel: bool) -> None:
        pass

    def close(self) -> None:
        pass


class InProcess(Quiet):
    """The mission's components built and called in this process (or in a worker's)."""

    label = "in-process"

    def key(self) -> dict[str, Any]:
        return {}

    def registry(self, raw: dict[str, Any], optional: list[str], source: str,
                 extra: tuple = ()) -> tuple[Register, dict[str, Any]]:
        return collect_components(get_plugin_manager(optional=optional, extra=extra)), raw

    def check(self, mission: Mission, registry: Register,
              inspect: Callable[[Simulation], None]) -> None:
        sim = Simulation(mission.replace(scenarios=1), registry,
                         [mission.settings.first_scenario])
        memory.remember(mission, sim.pm)      # the memory estimate asks them (ata_peak_bytes)
        inspect(sim)

    def worker_registry(self, mission: Mission) -> Register:
        registry = collect_components(get_plugin_manager(optional=mission.settings.plugins))
        restore(mission.references, registry)    # the components it names by reference
        return registry

    def run_batch(self, mission: Mission, registry: Register | None, ids: np.ndarray,
                  on_epoch: OnEpoch | None = None) -> Part:
        registry = registry if registry is not None else self.worker_registry(mission)
        return batch_part(ids, Simulation(mission, registry, ids).run(on_epoch=on_epoch))

    def __eq__(self, other: object) -> bool:
        return isinstance(other, InProcess)

    def __hash__(self) -> int:
        return hash(InProcess)


IN_PROCESS = InProcess()
"""The backend of every session that names no other."""
