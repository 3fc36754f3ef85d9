"""Memory: what a batch of a mission's scenarios needs at its peak, what this machine has, and the
largest batch that fits, so that a mission too large is cut into smaller batches, or refused,
before any work starts (a run that outgrows memory is killed, and Ctrl-C has no effect inside
one long numpy operation).
"""

from __future__ import annotations

import os
import resource

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


def batch_peak(mission: Mission, batch: int) -> int:
    """The memory one batch of `batch` scenarios of `mission` adds at its peak, in bytes: the
    planner's estimate (`ata.model.greedy_planner.peak_bytes`), the largest of the built-in
    components'; what a process holds anyway (the interpreter, numpy, weights) is not counted,
    as the memory available is measured with this process running."""
    s = mission.sizes
    return greedy_planner.peak_bytes(batch, s.humans, s.robots, s.tasks)


def largest_batch(mission: Mission, size: int, concurrent: int, limit: int | None) -> int:
    """The largest batch, at most `size`, of which `concurrent` at once fit in `limit` bytes
    (`size` when the limit is unknown; 0 when not even one scenario fits)."""
    if limit is None:
        return size
    lo, hi = 0, size
    while lo < hi:                        # the estimate grows with the batch: bisect
        mid = (lo + hi + 1) // 2
        if concurrent * batch_peak(mission, mid) <= limit:
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
    each = "" if concurrent == 1 else f" in each of {concurrent} workers"
    return MissionError("[mission]", "tasks", f"one scenario of {s.tasks} POIs, {s.robots} "
                        f"robots and {s.humans} humans needs about "
                        f"{gib(batch_peak(mission, 1))} of memory{each} (the planner's arrays "
                        f"grow as POIs squared), more than {limit_text(limit)}; run "
                        "fewer POIs" + (", or fewer workers" if concurrent > 1 else ""),
                        file=mission.source)


def check(missions: list[Mission], sizes: list[int], concurrent: int) -> None:
    """Refuse (a MissionError naming the limit) a plan whose largest batch of some mission does
    not fit in memory `concurrent` at a time."""
    limit = memory_limit()
    if limit is None:
        return
    for mission, size in zip(missions, sizes):
        if size and concurrent * batch_peak(mission, size) > limit:
            if largest_batch(mission, size, concurrent, limit) == 0:
                raise too_large(mission, concurrent, limit)
            raise MissionError("--chunk-size", None, f"batches of {size} scenarios of "
                               f"{mission.settings.name!r} need about "
                               f"{gib(concurrent * batch_peak(mission, size))} of memory, more "
                               f"than {limit_text(limit)}; give a --chunk-size of at "
                               f"most {largest_batch(mission, size, concurrent, limit)}")
