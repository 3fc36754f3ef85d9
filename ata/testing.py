"""Checkers a plugin author runs on a component before publishing it (cf. gymnasium's check_env).

    from ata.testing import check_component
    check_component("injector", MyInjector, settings={"probability": 0.3})

It builds a small mission with the component in its slot, runs it, and checks the contract:
the component is accepted by the kernel, policies return legal allocations, the observation
keeps its tables and shapes, and a scenario's results do not depend on the batch it runs in
(components must draw from ``sim.rng``/``ctx.rng`` streams, never from a shared generator).
Each failure raises ``AssertionError`` with what broke.

A policy fills the slots whose hooks it implements: with ``ata_initial_allocation`` the initial
slot (else ``greedy`` does); with ``ata_reallocate`` the reallocation slot, called at every
epoch (else ``keep`` fills it and the condition is ``never``). See docs/plugins.md.
"""

from __future__ import annotations

from typing import Any, Callable

import numpy as np

from ata import hookimpl
from ata.core.errors import ContractError
from ata.core.kernel import Simulation
from ata.core.mission import SLOTS, ComponentSlots, Mission, validate
from ata.core.registry import collect_components, get_plugin_manager

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


def _run(mission: Mission, registry: Any, ids: list[int]) -> tuple[np.ndarray, list]:
    sim = Simulation(mission, registry, ids)
    sim.reset()
    observations = []
    for _ in range(sim.sim.clock.n_epochs):
        sim.step_epoch()
        obs = sim.last_context.observed
        observations.append({g: t.features.copy() for g, t in obs.items()})
    sim.pm.hook.ata_episode_end(sim=sim.sim)
    return sim.sim.record.r_perf.copy(), observations


def check_component(kind: str, factory: Callable[..., Any], *, name: str = "under_test",
                    settings: dict | None = None, mission: dict | None = None) -> None:
    """Run the contract checks on one component factory; raise AssertionError on a breach.

    :param kind: one of ``ata.core.registry.KINDS``.
    :param settings: the component's settings table, as it would stand in a mission file.
    :param mission: extra ``[mission]`` keys for the small test mission.
    """
    m, registry = _mission(kind, name, factory, settings, mission)
    ids = list(range(m.settings.scenarios))
    try:
        r_perf, observations = _run(m, registry, ids)
    except ContractError as exc:   # the kernel's contract checks
        raise AssertionError(f"{kind} {name!r} broke the kernel's contract: {exc}") from exc
    assert np.isfinite(r_perf).all(), "r_perf has non-finite values"
    for k, obs in enumerate(observations):
        for group, feats in obs.items():
            assert feats.shape[0] == len(ids), f"epoch {k}: table {group!r} lost scenarios"
    again, _ = _run(m, registry, ids)
    assert np.array_equal(r_perf, again), "two runs with the same seed differ"
    # the last scenario alone must reproduce its row of the batch
    alone, obs_alone = _run(m, registry, ids[-1:])
    assert np.array_equal(alone[0], r_perf[-1]), (
        "a scenario's results depend on the batch it runs in: draw random numbers from "
        "sim.rng / ctx.rng streams, never from a generator shared by the batch")
    for k, (a, b) in enumerate(zip(obs_alone, observations)):
        for group in a:
            assert np.array_equal(a[group][0], b[group][-1]), (
                f"epoch {k}: observed {group!r} of a scenario depends on its batch")
