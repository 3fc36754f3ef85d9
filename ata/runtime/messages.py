"""The messages between the host and a sandboxed decision process (``--isolate``), declared once
for both sides: the host's proxies and process pool (``ata.isolation``) send them, the decision
process (`ata.runtime.decider`) answers them.

A request is a mapping with ``op`` (an `Op`) and the fields its `Operation` lists; an answer is
a frame (`ata.runtime.frames`) of a JSON header and named arrays. Every decision slot of the
kernel has the operation that serves it (`SLOT_OPERATIONS`); a test holds the two together.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import StrEnum


class Op(StrEnum):
    """What a request asks the decision process to do."""

    RESOLVE = "resolve"
    """Load every plugin, validate a mission, answer the resolved settings asked for."""
    PROBE = "probe"
    """Import one ``ata``-group entry point alone and answer what it registers."""
    INIT = "init"
    """Build a batch's decision components from the public mission."""
    RECONSTRUCT = "reconstruct"
    INITIAL = "initial"
    CONDITION = "condition"
    REALLOCATE = "reallocate"
    TRAINED_ON = "trained_on"
    """The (seed, first id, end id) ranges the components' weights were trained on."""
    EPISODE_SCORED = "episode_scored"
    """The batch's episodes are scored: the components' own results columns."""
    CLOSE = "close"


CONTEXT = ("epoch", "time", "allocation", "reallocatable")
"""What every decision call sends of its `DecisionContext`; the first call of a batch adds the
decision generator's ``keys``, the published ``channel`` and the ``inherent`` I, and the first
of an epoch the ``observed`` S."""
ALLOCATION = ("robot", "navigator", "classifier")


@dataclass(frozen=True)
class Operation:
    """One operation: the request's fields, the answer's header keys and array names (``None``:
    names the components choose, checked by the host), and the decision slot it serves with
    the request fields its hook takes besides the context (``hook_args``). A decision slot's
    answer is an `Allocation`'s arrays (`ALLOCATION`) or one (B,) bool array."""

    op: Op
    request: tuple[str, ...] = ()
    header: tuple[str, ...] = ()
    arrays: tuple[str, ...] | None = ()
    slot: str | None = None
    hook_args: tuple[str, ...] = ()


OPERATIONS: dict[Op, Operation] = {o.op: o for o in (
    Operation(Op.RESOLVE, ("mission", "source", "components", "paths")),
    Operation(Op.PROBE, ("entry_point",)),
    Operation(Op.INIT, ("mission", "modules", "paths", "only"), header=("ready",)),
    Operation(Op.RECONSTRUCT, ("epoch", "time", "allocation"), arrays=None,
              slot="reconstructors"),
    Operation(Op.INITIAL, CONTEXT, arrays=ALLOCATION, slot="initial"),
    Operation(Op.CONDITION, CONTEXT, arrays=("active",), slot="condition"),
    Operation(Op.REALLOCATE, CONTEXT + ("active",), arrays=ALLOCATION, slot="reallocation",
              hook_args=("active",)),
    Operation(Op.TRAINED_ON, header=("ranges",)),
    Operation(Op.EPISODE_SCORED, ("r_perf", "reallocated", "allocations"),
              header=("warnings",), arrays=None),
    Operation(Op.CLOSE),
)}

SLOT_OPERATIONS: dict[str, Op] = {o.slot: o.op for o in OPERATIONS.values() if o.slot}
"""The operation that serves each decision slot of the kernel."""
