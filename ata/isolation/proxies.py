"""The host's stand-ins for isolated decision components, forwarding each call to their process.

They fill the decision slots of a `Simulation` (its ``overrides``), implement the same hooks,
and forward each call to the batch's sandboxed decision process (`ata.isolation.process`).

What crosses, per batch: once, the decision generator's keys, the published constants and I;
once per epoch, the observed S; per call, the epoch, time, allocation in force, reallocatable
and (reallocation) the active scenarios. What comes back is checked here: shapes, dtypes,
names; the kernel checks allocations again.
"""

from __future__ import annotations

import contextlib
import re
from typing import Any, Iterator

import numpy as np

from ata import hookimpl
from ata.core.components import DECISION_SLOTS
from ata.core.errors import ContractError
from ata.core.kernel import Simulation
from ata.core.mission import Mission
from ata.core.registry import Register
from ata.core.state import Allocation
from ata.isolation.process import (TIMEOUT_COLUMN, DecisionProcess, DecisionTimeout,
                                    Isolation, acquire, release)
from ata.runtime.frames import HEADER_ONLY, answer_limit
from ata.runtime.messages import ALLOCATION, OPERATIONS, SLOT_OPERATIONS, Op


COLUMN = re.compile(r"[a-z][a-z0-9_]{0,63}")
"""A results column an isolated method may add: a plain name (a results.csv header)."""
RESERVED = frozenset({"method", "setting", "uncertainty", "scenario", "seed", "score",
                      "upper_bound", "fraction_of_u", "reallocations", "wall_s", "total",
                      "warnings", TIMEOUT_COLUMN})
"""The columns the run itself writes: an untrusted method may not replace its own score."""


class Link:
    """One batch's channel to its decision process, shared by the proxies of its slots: what
    the process was shown already, and whether it timed out."""

    def __init__(self, process: DecisionProcess, mission: Mission, batch_size: int):
        self.process = process
        self.limit = process.isolation.decision_timeout_s
        self.mission = mission
        self.batch = batch_size
        self.sent_batch = False
        self.obs_epoch = -1
        self.timeouts = 0
        self.timed_out: str | None = None     # what timed out, once one did

    def request(self, op: Op, epoch: int, time: float, previous: Allocation | None,
                observed: Any, inherent: Any, rng: Any, channel: Any, **extra: Any
                ) -> dict[str, Any]:
        req = {"op": op, "epoch": int(epoch), "time": float(time), "allocation": previous,
               **extra}
        if not self.sent_batch:
            req.update(keys=np.asarray(rng.keys), channel=channel, inherent=inherent)
            self.sent_batch = True
        if self.obs_epoch != epoch:
            req["observed"] = observed
            self.obs_epoch = epoch
        return req

    def call(self, req: dict[str, Any], what: str, fatal: bool):
        """The answer, or None where the call timed out and need not fail the batch (the
        process is then gone, and every later call of the batch answers None too)."""
        if self.timed_out is not None:
            return None
        try:
            return self.process.call(req, self.limit, what, answer_limit(self.batch))
        except DecisionTimeout as exc:
            if fatal:
                raise DecisionTimeout(f"{exc}: an initial allocation is needed to run at all, "
                                      "so the batch fails") from None
            self.timed_out = f"{what} at epoch {req['epoch']}"
            self.timeouts += 1
            return None

    def allocation(self, arrays: dict[str, np.ndarray], where: str) -> Allocation:
        shape = (self.batch, self.mission.sizes.tasks)
        fields = []
        for f in ALLOCATION:
            arr = arrays.get(f)
            if arr is None or arr.shape != shape or not np.issubdtype(arr.dtype, np.integer):
                got = "nothing" if arr is None else f"{arr.dtype} {arr.shape}"
                raise ContractError(f"{where}: {f} came back as {got}, expected integers of "
                                    f"shape {shape} (scenarios, POIs)")
            fields.append(arr)
        return Allocation(*fields)


PROXIES: dict[str, type["_Proxy"]] = {}
"""The proxy of each decision slot of the kernel, by slot: a proxy class names the slot it
serves (``class X(_Choice, serves="slot")``) and is found here; each forwards its slot's
operation (`ata.runtime.messages.SLOT_OPERATIONS`)."""


class _Proxy:
    def __init_subclass__(cls, serves: str | None = None, **kwargs: Any) -> None:
        super().__init_subclass__(**kwargs)
        if serves is not None:
            PROXIES[serves] = cls

    def __init__(self, link: Link, slot: str, name: str):
        self.link, self.slot = link, slot
        self.component_name = name

    def _ctx_request(self, op: Op, ctx: Any, **extra: Any) -> dict[str, Any]:
        return self.link.request(op, ctx.epoch, ctx.time, ctx.previous, ctx.observed,
                                 ctx.inherent, ctx.rng, ctx.channel,
                                 reallocatable=np.asarray(ctx.reallocatable, dtype=bool), **extra)


class ReconstructorsProxy(_Proxy, serves="reconstructors"):
    """The whole reconstructors slot: one round trip per epoch runs every reconstructor."""

    @hookimpl
    def ata_reconstruct(self, sim, obs, inherent, out) -> None:
        link = self.link
        req = link.request(Op.RECONSTRUCT, sim.epoch, sim.now, sim.allocation, obs, inherent,
                           sim.rng, sim.channel)
        answer = link.call(req, f"reconstructors {self.component_name}", fatal=sim.epoch == 0)
        if answer is None:
            return
        for name, arr in answer[1].items():
            if arr.ndim < 1 or arr.shape[0] != link.batch:
                raise ContractError(f"reconstructor output {name!r} has shape {arr.shape}; its "
                                    f"leading axis must be the batch's {link.batch} scenarios")
            out[name] = arr


class _Choice(_Proxy):
    """A single-choice decision slot: its hook forwards the slot's operation, with the context
    and the hook's own arguments (`Operation.hook_args`). The answer is an allocation, checked
    here (a call that timed out keeps the allocation in force; before the initial allocation
    none is, so that call fails the batch), or one (B,) bool array (a call that timed out: False
    in every scenario, nothing changes)."""

    def _forward(self, ctx: Any, *args: Any) -> Any:
        operation = OPERATIONS[SLOT_OPERATIONS[self.slot]]
        where = f"{self.slot} policy {self.component_name!r}"
        extra = {k: np.asarray(v) for k, v in zip(operation.hook_args, args)}
        answer = self.link.call(self._ctx_request(operation.op, ctx, **extra), where,
                                fatal=ctx.previous is None)
        if operation.arrays == ALLOCATION:
            return ctx.previous if answer is None else self.link.allocation(answer[1], where)
        (name,) = operation.arrays
        if answer is None:
            return np.zeros(self.link.batch, dtype=bool)
        arr = answer[1].get(name)
        if arr is None or arr.dtype != bool or arr.shape != (self.link.batch,):
            raise ContractError(f"{where} answered no ({self.link.batch},) bool array {name!r}")
        return arr


class InitialProxy(_Choice, serves="initial"):
    """The initial slot; it also answers for the whole method at the ends: the scenarios its
    weights saw (`ata_trained_on`) and its per-scenario results (`ata_episode_scored`)."""

    @hookimpl
    def ata_initial_allocation(self, ctx):
        return self._forward(ctx)

    @hookimpl
    def ata_trained_on(self):
        header, _ = self.link.process.call({"op": Op.TRAINED_ON}, self.link.limit,
                                           "ata_trained_on", HEADER_ONLY)
        out = []
        for ranges in header.get("ranges", []):
            for r in ranges:
                if not (isinstance(r, list) and len(r) == 3
                        and all(isinstance(x, int) for x in r)):
                    raise ContractError(f"ata_trained_on answered {str(r)[:100]}, not a (seed, "
                                        "first id, end id) range")
                out.append(tuple(r))
        return out

    @hookimpl
    def ata_episode_scored(self, episode) -> None:
        link = self.link
        answer = link.call({"op": Op.EPISODE_SCORED, "epoch": -1, "time": 0.0,
                            "r_perf": np.asarray(episode.r_perf),
                            "reallocated": np.asarray(episode.reallocated),
                            "allocations": np.asarray(episode.allocations)},
                           "ata_episode_scored", fatal=False)
        if answer is not None:
            header, metrics = answer
            for name, arr in metrics.items():
                if not COLUMN.fullmatch(name) or name in RESERVED or arr.shape != (link.batch,):
                    raise ContractError(f"a decision component's results column "
                                        f"{name[:80]!r} has shape {arr.shape} (expected "
                                        f"({link.batch},)), or a name that is not a plain "
                                        "lower-case identifier or is one the run writes")
                episode.metrics[name] = arr.astype(float)   # the kernel checks the names
            episode.warnings += [str(w)[:1000] for w in header.get("warnings", [])
                                 if isinstance(w, str)]
        episode.metrics[TIMEOUT_COLUMN] = np.full(link.batch, float(link.timeouts))
        if link.timed_out is not None:
            episode.warnings.append(
                f"the decision time limit of {link.limit:g} s was exceeded ({link.timed_out}) "
                f"in a batch of {link.batch} scenarios: its decision process was stopped and "
                "the allocation in force kept for the rest of their episode (column "
                f"{TIMEOUT_COLUMN})")


class ConditionProxy(_Choice, serves="condition"):
    @hookimpl
    def ata_should_reallocate(self, ctx):
        return self._forward(ctx)


class ReallocationProxy(_Choice, serves="reallocation"):
    @hookimpl
    def ata_reallocate(self, ctx, active):
        return self._forward(ctx, active)


def overrides(link: Link, mission: Mission) -> dict[str, Any]:
    """The proxies for a `Simulation`'s ``overrides``, one per decision slot the mission fills
    (the reconstructors' one only where it lists some)."""
    out: dict[str, Any] = {}
    for slot in DECISION_SLOTS:
        value = getattr(mission.slots, slot)
        if isinstance(value, list):
            if not value:
                continue
            value = ",".join(value)
        out[slot] = PROXIES[slot](link, slot, value)
    return out


@contextlib.contextmanager
def isolated_simulation(mission: Mission, registry: Register, scenario_ids: Any,
                        isolation: Isolation) -> Iterator[Simulation]:
    """A batch's `Simulation` whose decision slots hold proxies of a sandboxed decision
    process, started (or told the batch) first, so that its start overlaps the world's
    construction; killed on an error or Ctrl-C, else kept for the method's next batch."""
    process = acquire(mission, registry, isolation)
    try:
        link = Link(process, mission, len(scenario_ids))
        yield Simulation(mission, registry, scenario_ids, overrides=overrides(link, mission))
    except BaseException:
        process.close(ask=False)
        raise
    release(process)        # kept for the method's next batch (`isolate.acquire`)
