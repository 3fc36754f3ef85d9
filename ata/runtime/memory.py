"""Memory: what a batch of a mission's scenarios needs at its peak, what this machine has, and the
largest batch that fits, so that a mission too large is cut into smaller batches, or refused,
before any work starts (a run that outgrows memory is killed, and Ctrl-C has no effect inside
one long numpy operation).
"""

from __future__ import annotations

import os
import resource
from typing import Any

from ata.core.errors import MissionError
from ata.core.mission import Mission
from ata.model import greedy_planner

USABLE_SHARE = 0.75
"""The share of the memory available that a run plans to use: the estimate is rough, and other
processes use memory too."""


def memory_limit() -> int | None:
    """The bytes a run may use: `USABLE_SHARE` of the memory available now (MemAvailable of
    /proc/meminfo, else the physical memory), capped by the address-space limit; None when
    nothing is known."""
    limits = []
    try:
        with open("/proc/meminfo", encoding="ascii") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    limits.append(int(int(line.split()[1]) * 1024 * USABLE_SHARE))
    except (OSError, ValueError):
        pass
    if not limits:
        try:
            limits.append(int(os.sysconf("SC_PHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
                              * USABLE_SHARE))
        except (ValueError, OSError, AttributeError):
            pass
    soft, _ = resource.getrlimit(resource.RLIMIT_AS)
    if soft != resource.RLIM_INFINITY:
        limits.append(soft)
    return min(limits) if limits else None


WORKER_BYTES = 330 * 2**20
"""What each worker process holds before its first batch (the interpreter, numpy, the plugins,
and torch with a learned method's weights): about 330 MB measured with ATA-HRL. The memory
free is measured with this process running, so a serial run pays none of it."""

_BUILT: dict[int, tuple[Mission, Any]] = {}


def remember(mission: Mission, pm: Any) -> None:
    """Keep the plugin manager of `mission`'s components, built once (`runner.build_once`), so
    that the estimate asks them (``ata_peak_bytes``)."""
    _BUILT[id(mission)] = (mission, pm)


def record_bytes(mission: Mission, batch: int) -> int:
    """The kernel's episode record of a batch: an allocation (three int16) per scenario, epoch
    and POI, and a few numbers per scenario and epoch."""
    epochs, tasks = mission.clock.n_epochs, mission.sizes.tasks
    return batch * epochs * (6 * tasks + 32) + batch * tasks * 64


def component_bytes(mission: Mission, batch: int) -> int:
    """What the mission's components say they add (``ata_peak_bytes``), once they were built
    and remembered; 0 before, or for components that do not say."""
    mission_pm = _BUILT.get(id(mission))
    if mission_pm is None or mission_pm[0] is not mission:
        return 0
    answers = mission_pm[1].hook.ata_peak_bytes(mission=mission, batch=batch)
    return sum(int(a) for a in answers if a)


def batch_peak(mission: Mission, batch: int) -> int:
    """The memory one batch of `batch` scenarios of `mission` adds at its peak, in bytes: the
    planner's estimate (`ata.model.greedy_planner.peak_bytes`, what every policy that plans
    with the projection model needs, and the default of a component that says nothing), the
    kernel's record (`record_bytes`) and what the components say (`component_bytes`); what a
    process holds anyway (the interpreter, numpy, weights) is not counted here, as the memory
    available is measured with this process running (its workers: `run_peak`)."""
    s = mission.sizes
    return (greedy_planner.peak_bytes(batch, s.humans, s.robots, s.tasks)
            + record_bytes(mission, batch) + component_bytes(mission, batch))


def run_peak(mission: Mission, batch: int, concurrent: int) -> int:
    """`concurrent` batches at once, each in a worker process of its own when there are
    several (`WORKER_BYTES` each)."""
    return concurrent * batch_peak(mission, batch) + (concurrent * WORKER_BYTES
                                                      if concurrent > 1 else 0)


def largest_batch(mission: Mission, size: int, concurrent: int, limit: int | None) -> int:
    """The largest batch, at most `size`, of which `concurrent` at once fit in `limit` bytes
    (`size` when the limit is unknown; 0 when not even one scenario fits)."""
    if limit is None:
        return size
    lo, hi = 0, size
    while lo < hi:                        # the estimate grows with the batch: bisect
        mid = (lo + hi + 1) // 2
        if run_peak(mission, mid, concurrent) <= limit:
            lo = mid
        else:
            hi = mid - 1
    return lo


def gib(n: float) -> str:
    return f"{n / 2**30:.1f} GiB"


def limit_text(limit: int) -> str:
    """How the messages name the limit."""
    return f"the {gib(limit)} a run may use here ({USABLE_SHARE:.0%} of the memory free now)"


def too_large(mission: Mission, concurrent: int, limit: int) -> MissionError:
    """The refusal of a mission of which not even one scenario per worker fits in memory."""
    s = mission.sizes
    each = "" if concurrent == 1 else (f" in each of {concurrent} workers (with "
                                       f"{gib(WORKER_BYTES)} each worker holds anyway)")
    return MissionError("[mission]", "tasks", f"one scenario of {s.tasks} POIs, {s.robots} "
                        f"robots and {s.humans} humans needs about "
                        f"{gib(batch_peak(mission, 1))} of memory{each} (the planner's arrays "
                        f"and the components' own grow with the POIs), more than "
                        f"{limit_text(limit)}; run fewer POIs"
                        + (", or fewer workers" if concurrent > 1 else ""),
                        file=mission.source)


def check(missions: list[Mission], sizes: list[int], concurrent: int) -> None:
    """Refuse (a MissionError naming the limit) a plan whose largest batch of some mission does
    not fit in memory `concurrent` at a time."""
    limit = memory_limit()
    if limit is None:
        return
    for mission, size in zip(missions, sizes):
        if size and run_peak(mission, size, concurrent) > limit:
            if largest_batch(mission, size, concurrent, limit) == 0:
                raise too_large(mission, concurrent, limit)
            raise MissionError("--chunk-size", None, f"batches of {size} scenarios of "
                               f"{mission.settings.name!r} need about "
                               f"{gib(run_peak(mission, size, concurrent))} of memory, more "
                               f"than {limit_text(limit)}; give a --chunk-size of at "
                               f"most {largest_batch(mission, size, concurrent, limit)}")
