"""Checkers a plugin author runs on a component before publishing it (cf. gymnasium's check_env).

    from ata.testing import check_component
    check_component("injector", MyInjector, settings={"probability": 0.3})

It builds a small mission with the component in its slot, runs it, and checks the contract:
the component is accepted by the kernel, policies return legal allocations, the observation
keeps its tables and shapes, and a scenario's results do not depend on the batch it runs in
(components must draw from ``sim.rng``/``ctx.rng`` streams, never from a shared generator).
A decision-maker (policy, condition, reconstructor) must also pass the integrity check: run
again with the world's unseen draws redrawn (the classification outcomes; the robot failures
and task attribute changes), it must decide the same until what it observes differs. Each
failure raises ``AssertionError`` with what broke.

A policy fills the slots whose hooks it implements: with ``ata_initial_allocation`` the initial
slot (else ``greedy`` does); with ``ata_reallocate`` the reallocation slot, called at every
epoch (else ``keep`` fills it and the condition is ``never``). See docs/plugins.md.

A reference reconstructor (``reference = True``: the kernel hands it the true state) is no
method and fails the integrity check by design: `check_component` refuses it unless told
``reference=True``, and then runs every check but that one.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Callable

import numpy as np

from ata import hookimpl
from ata.core.errors import ContractError
from ata.core.kernel import DECISION_KINDS, Simulation, is_reference
from ata.core.mission import SLOTS, ComponentSlots, Mission, validate
from ata.core.registry import collect_components, get_plugin_manager
from ata.core.state import Allocation, DecisionContext

LIST_SLOT_BASE = {"perturbations": ComponentSlots().perturbations,
                  "injectors": ComponentSlots().injectors, "reconstructors": []}
"""A component of a list slot is checked after these built-ins (the mission defaults)."""
SLOT_OF_KIND = {s.kind: s.name for s in reversed(SLOTS)}
"""The slot a component of each kind is checked in (a policy's: the first, initial)."""


def _contributor(kind: str, name: str, factory: Callable[..., Any]) -> Any:
    """A throw-away plugin that registers the component under test."""

    class Contributor:
        @hookimpl
        def ata_register_components(self, register) -> None:
            register(kind, name, factory)

    return Contributor()


def _mission(kind: str, name: str, factory: Callable[..., Any], settings: dict | None,
             mission_keys: dict | None) -> tuple[Mission, Any]:
    pm = get_plugin_manager(extra=[_contributor(kind, name, factory)], entry_points=False)
    registry = collect_components(pm)
    slot = SLOT_OF_KIND[kind]
    raw: dict[str, Any] = {"mission": {"setting": "custom", "humans": 3, "robots": 4,
                                       "tasks": 12, "scenarios": 6, "batch_size": 6,
                                       "horizon_s": 600.0, "uncertainty": "high",
                                       **(mission_keys or {})},
                           "components": {}}
    if slot in LIST_SLOT_BASE:
        raw["components"][slot] = LIST_SLOT_BASE[slot] + [name]
    elif kind == "policy":
        # a policy fills the slots whose hooks it implements; built-ins fill the others
        initial = hasattr(factory, "ata_initial_allocation")
        realloc = hasattr(factory, "ata_reallocate")
        if not (initial or realloc):
            raise AssertionError(f"policy {name!r} implements neither ata_initial_allocation "
                                 "nor ata_reallocate")
        raw["components"]["initial"] = name if initial else "greedy"
        raw["components"]["reallocation"] = name if realloc else "keep"
        raw["components"]["condition"] = "always" if realloc else "never"
    else:
        raw["components"][slot] = name
    if settings:
        raw[name] = settings
    return validate(raw, registry, source=f"<check {kind} {name}>"), registry


UNSEEN_STREAMS = ("tasks.outcome", "robot_failure.", "attribute_change.")
"""The built-in world's draws that S does not show until they happen: the classification
outcomes (never shown), the robot failures and the task attribute changes (shown once they
happen). The integrity check redraws them."""
INTEGRITY_RUNS = (UNSEEN_STREAMS[:1], UNSEEN_STREAMS)
"""The two redrawn runs: the outcomes alone (S is the same throughout, so every decision is
checked), then every unseen draw (decisions checked until S first differs)."""
RESALT = 0x5EED


@dataclass
class Trace:
    """One run of the check mission: its rewards, and per epoch what the decision-makers saw
    and what they decided, each an array with a leading scenario axis."""

    r_perf: np.ndarray
    observations: list[dict[str, np.ndarray]] = field(default_factory=list)
    seen: list[dict[str, np.ndarray]] = field(default_factory=list)
    decided: list[dict[str, np.ndarray]] = field(default_factory=list)


def _seen(ctx: DecisionContext) -> dict[str, np.ndarray]:
    """What a decision-maker sees at `ctx` besides I (the same in every run): S, its extras,
    what S shows reallocatable, and the allocation in force."""
    out = {f"S.{g}": t.features.copy() for g, t in ctx.observed.items()}
    out.update({f"S.{g}.holds": t.holds.copy() for g, t in ctx.observed.items()
                if t.holds is not None})
    out.update({f"S.extras.{k}": np.asarray(v).copy() for k, v in ctx.observed.extras.items()})
    out["reallocatable"] = ctx.reallocatable.copy()
    if ctx.previous is not None:
        out["allocation in force"] = ctx.previous.stack()
    return out


def _decided(ctx: DecisionContext, allocation: Allocation | None, active: np.ndarray | None
             ) -> dict[str, np.ndarray]:
    """What the decision-makers made of it: the reconstructors' outputs, the condition, the
    allocation (at t = 0) or the reallocation proposed (in the scenarios it was asked for)."""
    out = {f"reconstructed {k!r}": np.asarray(v).copy() for k, v in ctx.reconstructed.items()}
    if ctx.epoch == 0:
        out["initial allocation"] = allocation.stack()
        return out
    out["condition"] = active.copy()
    if allocation is not None:
        out["reallocation"] = np.where(active[:, None, None], allocation.stack(),
                                       np.iinfo(np.int64).min)
    return out


def _run(mission: Mission, registry: Any, ids: list[int],
         redraw: tuple[str, ...] = ()) -> Trace:
    sim = Simulation(mission, registry, ids)
    if redraw:
        sim.sim.rng = sim.sim.rng.resalted(redraw, RESALT)
    sim.reset()
    trace = Trace(r_perf=np.zeros(0))
    for _ in range(sim.sim.clock.n_epochs):
        ctx = sim.begin_epoch()
        trace.seen.append(_seen(ctx))
        trace.observations.append({g: t.features.copy() for g, t in ctx.observed.items()})
        allocation, active = sim.decide(ctx)
        sim.end_epoch(allocation, active)          # the kernel checks the contract first
        trace.decided.append(_decided(ctx, allocation, active))
    trace.r_perf = sim.end_episode().r_perf.copy()
    return trace


def _difference(a: dict[str, np.ndarray], b: dict[str, np.ndarray], s: int
                ) -> tuple[str, tuple] | None:
    """The first entry (name, index within scenario s's row) where two epoch records differ
    in scenario s; None where they agree."""
    for name in sorted(set(a) | set(b)):
        x, y = a.get(name), b.get(name)
        if x is None or y is None:
            return name, ()
        x, y = np.asarray(x[s]), np.asarray(y[s])
        if not np.array_equal(x, y, equal_nan=x.dtype.kind == "f" and y.dtype.kind == "f"):
            where = np.argwhere(np.asarray(x != y))
            return name, tuple(int(i) for i in where[0]) if where.size else ()
    return None


def _value(record: dict[str, np.ndarray], name: str, s: int, index: tuple) -> str:
    x = record.get(name)
    if x is None:
        return "none"
    row = np.asarray(x[s])
    if name in ("initial allocation", "reallocation") and index:
        triple = row[index[0]]
        return f"(robot {triple[0]}, navigator {triple[1]}, classifier {triple[2]})" \
            if triple[0] != np.iinfo(np.int64).min else "none"
    return str(row[index] if index else row)


def _integrity(kind: str, name: str, base: Trace, mission: Mission, registry: Any,
               ids: list[int]) -> None:
    """Run again with the unseen world draws redrawn; raise AssertionError at the first
    decision that changed while what the decision-makers observed had not."""
    T = len(base.seen)
    for streams in INTEGRITY_RUNS:
        other = _run(mission, registry, ids, redraw=streams)
        found = []                              # (epoch, scenario, what, index)
        for s in range(len(ids)):
            for k in range(T):
                if _difference(base.seen[k], other.seen[k], s) is not None:
                    break                       # from here on it may decide otherwise
                diff = _difference(base.decided[k], other.decided[k], s)
                if diff is not None:
                    found.append((k, s, *diff))
                    break
        if not found:
            continue
        k, s, what, index = min(found, key=lambda f: (f[0], f[1]))
        seen_until = next((j for j in range(T)
                           if _difference(base.seen[j], other.seen[j], s) is not None), None)
        poi = f" for POI {index[0]}" if what.endswith("allocation") and index else \
            (f" at row {index[0]}" if index else "")
        until = "throughout" if seen_until is None else f"before epoch {seen_until}"
        raise AssertionError(
            f"{kind} {name!r} decides from what it cannot observe: in scenario {ids[s]}, at "
            f"epoch {k}, its {what}{poi} was {_value(base.decided[k], what, s, index)} as the "
            f"world drew it and {_value(other.decided[k], what, s, index)} with the unseen "
            f"draws ({', '.join(streams)}) drawn again; what it observed was the same in both "
            f"runs {until}. A decision-maker decides from I, the observed S, the allocation "
            "in force, its settings and ctx.rng alone (docs/plugins.md, 'Submitting a method')")


def check_component(kind: str, factory: Callable[..., Any], *, name: str = "under_test",
                    settings: dict | None = None, mission: dict | None = None,
                    reference: bool = False) -> None:
    """Run the contract checks on one component factory; raise AssertionError on a breach.

    :param kind: one of ``ata.core.registry.KINDS``.
    :param settings: the component's settings table, as it would stand in a mission file.
    :param mission: extra ``[mission]`` keys for the small test mission.
    :param reference: the factory is a reference reconstructor (``reference = True``, it reads
        the true state): say so to run every check but the integrity check, which a reference
        fails by design. Without it, a reference is refused.
    """
    if is_reference(factory) != reference:
        raise AssertionError(
            f"{kind} {name!r} is a reference: it reads the true state, so it is no method and "
            "the integrity check does not apply; check the rest of its contract with "
            "check_component(..., reference=True)" if reference is False else
            f"{kind} {name!r} is not a reference (its class does not declare reference = "
            "True): check it as a method, without reference=True")
    m, registry = _mission(kind, name, factory, settings, mission)
    ids = list(range(m.settings.scenarios))
    try:
        base = _run(m, registry, ids)
        again = _run(m, registry, ids)
        alone = _run(m, registry, ids[-1:])
        if kind in DECISION_KINDS and not reference:
            _integrity(kind, name, base, m, registry, ids)
    except ContractError as exc:   # the kernel's contract checks
        raise AssertionError(f"{kind} {name!r} broke the kernel's contract: {exc}") from exc
    r_perf, observations = base.r_perf, base.observations
    assert np.isfinite(r_perf).all(), "r_perf has non-finite values"
    for k, obs in enumerate(observations):
        for group, feats in obs.items():
            assert feats.shape[0] == len(ids), f"epoch {k}: table {group!r} lost scenarios"
    assert np.array_equal(r_perf, again.r_perf), "two runs with the same seed differ"
    # the last scenario alone must reproduce its row of the batch
    assert np.array_equal(alone.r_perf[0], r_perf[-1]), (
        "a scenario's results depend on the batch it runs in: draw random numbers from "
        "sim.rng / ctx.rng streams, never from a generator shared by the batch")
    for k, (a, b) in enumerate(zip(alone.observations, observations)):
        for group in a:
            assert np.array_equal(a[group][0], b[group][-1]), (
                f"epoch {k}: observed {group!r} of a scenario depends on its batch")
