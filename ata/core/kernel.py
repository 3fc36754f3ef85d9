"""The simulation kernel: builds a batch's components, then calls their hooks phase by phase.

It knows the clock (ticks, decision epochs, horizon), the allocation it must keep legal, and the
record it must keep; it knows nothing of humans, robots or POIs. One call of each phase hook
serves the whole batch. A component's exception propagates: nothing is swallowed.
"""

from __future__ import annotations

import copy
from types import MappingProxyType
from typing import Any, Callable, Sequence

import numpy as np
import pluggy

from ata.core import hookspecs
from ata.core.errors import ContractError, MissionError
from ata.core.components import DECISION_KINDS, DECISION_SLOTS
from ata.core.mission import SLOT_HOOKS, SLOT_KINDS, Mission
from ata.core.registry import Register
from ata.core.rng import BatchRNG, decision_rng
from ata.core.settings import for_team
from ata.core.state import (Allocation, DecisionContext, DecisionView, EpisodeOutcome,
                            EpisodeRecord, Observation, SimState, read_only)

WORLD_HOOKS = ("ata_setup", "ata_inherent", "ata_observe", "ata_inject",
               "ata_allocation_changed", "ata_advance", "ata_epoch_end", "ata_episode_end")
"""The phase hooks that receive the world (``sim``): a decision-maker may implement none of
them (at the end of an episode it has ``ata_episode_scored``)."""
REFERENCE_HOOK = "ata_reconstruct_reference"
"""The hook that hands a reconstructor the true state: only a declared reference may have it."""
REFERENCE_COLUMN = "reference"
"""The results column (1 in every row) of a mission with a reference reconstructor."""


def is_reference(component: Any) -> bool:
    """Whether a component declares itself a reference (``reference = True``): a yardstick that
    reads the true state, never a method."""
    return getattr(component, "reference", False) is True


def build_component(registry: Register, mission: Mission, kind: str, name: str) -> Any:
    """Create one component instance from its factory and its resolved settings (its defaults
    when the mission does not choose it, as for a trainer's teacher). A decision-maker's factory
    gets the mission without its root seed."""
    info = registry.get(kind, name, "[components]")
    if kind in DECISION_KINDS:
        mission = mission.public()
    settings = mission.component_settings.get(name)
    if settings is None and getattr(info.factory, "Settings", None) is not None:
        settings = info.factory.Settings()
        settings = for_team(settings, mission.settings)   # as `validate` does for chosen ones
    component = info.factory(settings, mission)
    try:
        component.component_name = name
    except AttributeError:
        pass
    return component


def refuse_world_hooks(pm: pluggy.PluginManager, deciders: list[tuple[str, Any]]) -> None:
    """Raise a ContractError when a decision-maker (`deciders`: ("slot:name", component)
    pairs) implements a hook of `pm` that would hand it the world (its state, its generator)."""
    for hook_name in WORLD_HOOKS:
        impls = [i.plugin for i in getattr(pm.hook, hook_name).get_hookimpls()]
        for name, component in deciders:
            if any(p is component for p in impls):
                slot = name.split(":", 1)[0]
                comp = getattr(component, "component_name", None) or type(component).__name__
                instead = (" (it learns its episode's record and score through "
                           "ata_episode_scored)") if hook_name == "ata_episode_end" else ""
                raise ContractError(
                    f"{slot} component {comp!r} implements {hook_name}, which "
                    "hands it the world's state and generator: a decision-maker sees the "
                    "scenario through its DecisionContext alone (a reconstructor through "
                    f"ata_reconstruct; see docs/decisions.md){instead}")


def _names(value: str | list[str]) -> list[str]:
    return value if isinstance(value, list) else [value]


class Simulation:
    """One batch of scenarios of a mission, ready to run.

    :param scenario_ids: the global indices of the batch's scenarios; scenario i's numbers
        depend on (seed, i) alone, so any batching gives the same per-scenario results.
    :param overrides: slot -> component instance, to run a component not built from the
        registry (a policy under training, a test double).
    """

    def __init__(self, mission: Mission, registry: Register, scenario_ids: Sequence[int],
                 *, trace: bool = False, overrides: dict[str, Any] | None = None):
        self.mission = mission
        rng = BatchRNG(mission.settings.seed, np.asarray(scenario_ids))
        self.decision_rng = decision_rng(mission.settings.seed, np.asarray(scenario_ids))
        """The decision-makers' generator: streams of their own, never the world's."""
        self.sim = SimState(sizes=mission.sizes, clock=mission.clock, rng=rng,
                            trace=trace)
        self.pm = pluggy.PluginManager("ata")
        self.pm.add_hookspecs(hookspecs)
        overrides = overrides or {}
        ordered: list[tuple[str, Any]] = []   # (plugin name, instance), in hook-call order
        self.slot_component: dict[str, Any] = {}
        built: dict[str, Any] = {}            # one instance per component name and batch
        for slot, kind in SLOT_KINDS.items():
            value = getattr(mission.slots, slot)
            names = value if isinstance(value, list) else [value]
            for name in names:
                if slot in overrides:
                    component = overrides[slot]
                else:
                    if name not in built:
                        built[name] = build_component(registry, mission, kind, name)
                    component = built[name]
                ordered.append((f"{slot}:{name}", component))
                if slot in SLOT_HOOKS:
                    self.slot_component[slot] = component
        # One instance may fill several slots (a policy serving initial and reallocation, a
        # component registered under two kinds, one override for a whole list slot): register
        # it once, at its first place in the order.
        unique = [(n, c) for i, (n, c) in enumerate(ordered)
                  if not any(c is other for _, other in ordered[:i])]
        # pluggy calls the last registered implementation first: register in reverse.
        for plugin_name, component in reversed(unique):
            self.pm.register(component, name=plugin_name)
        self.pm.check_pending()
        self._callers: dict[str, Callable[..., Any]] = {}
        everyone = [c for _, c in ordered]
        for slot, hook_name in SLOT_HOOKS.items():
            component = self.slot_component[slot]
            impls = [i.plugin for i in getattr(self.pm.hook, hook_name).get_hookimpls()]
            if not any(p is component for p in impls):
                name = self._component_name(slot)
                raise MissionError("[components]", slot, f"component {name!r} cannot fill this "
                                   f"slot: it implements no {hook_name}", file=mission.source)
            self._callers[slot] = self.pm.subset_hook_caller(
                hook_name, remove_plugins=[c for c in everyone if c is not component])
        self._refuse_world_hooks(ordered)
        self.references = self._references(ordered)
        """The reference reconstructors' names: those the kernel hands the true state."""
        names = {n for slot in DECISION_SLOTS for n in _names(getattr(mission.slots, slot))}
        self.decision_settings = MappingProxyType(
            {n: copy.deepcopy(mission.component_settings.get(n)) for n in sorted(names)})
        self.inherent: Observation | None = None
        self.last_context: DecisionContext | None = None
        self.last_truth: Observation | None = None
        """The true S of the epoch begun last: never in a policy's context; a teacher that
        needs it (supervised training of reconstructors) reads it from the Simulation."""
        self._pending: DecisionContext | None = None   # the context of an epoch begun, not ended
        self.shown: np.ndarray | None = None

    def _refuse_world_hooks(self, ordered: list[tuple[str, Any]]) -> None:
        refuse_world_hooks(self.pm, [(n, c) for n, c in ordered
                                     if n.split(":")[0] in DECISION_SLOTS])

    def _references(self, ordered: list[tuple[str, Any]]) -> list[str]:
        """The reference reconstructors of the mission; a ContractError when a component that
        is not one implements the hook that would hand it the true state."""
        impls = [i.plugin for i in getattr(self.pm.hook, REFERENCE_HOOK).get_hookimpls()]
        names = []
        for name, component in ordered:
            slot = name.split(":", 1)[0]
            comp = getattr(component, "component_name", None) or type(component).__name__
            declared = slot == "reconstructors" and is_reference(component)
            if any(p is component for p in impls) and not declared:
                raise ContractError(
                    f"{slot} component {comp!r} implements {REFERENCE_HOOK}, which hands it "
                    "the true state: only a reconstructor whose class declares reference = "
                    "True may, and its results are labelled a reference, never a method (see "
                    "docs/decisions.md)")
            if declared and comp not in names:
                names.append(comp)
        return names

    @property
    def batch_size(self) -> int:
        return self.sim.batch_size

    def _component_name(self, slot: str) -> str:
        """The name of the component filling a single-choice slot (its class for an override)."""
        component = self.slot_component[slot]
        return getattr(component, "component_name", None) or type(component).__name__

    def _reallocatable(self, obs: Observation) -> np.ndarray:
        """(B, P) bool: the tasks `obs` says may change now (every task where no model
        restricted it)."""
        if obs.reallocatable is None:
            return np.ones((self.sim.batch_size, self.sim.sizes.tasks), dtype=bool)
        return obs.reallocatable

    def _context(self, observed: Observation, recon: dict[str, np.ndarray]) -> DecisionContext:
        """The decision context of this epoch: every array in it a read-only copy, so that
        no edit in place reaches the allocation the kernel applies, the world, or what another
        decision-maker reads."""
        sim = self.sim
        # as observed: an injector may make it stale
        realloc = read_only(self._reallocatable(observed))
        return DecisionContext(epoch=sim.epoch, time=sim.now, sizes=sim.sizes, clock=sim.clock,
                               inherent=self.inherent, observed=observed,
                               reconstructed={k: read_only(v) for k, v in recon.items()},
                               previous=None if sim.allocation is None
                               else sim.allocation.frozen(),
                               reallocatable=realloc, rng=self.decision_rng,
                               settings=self.decision_settings, channel=sim.channel)

    def _check(self, alloc: Any, slot: str) -> Allocation:
        sim = self.sim
        where = f"{slot} policy {self._component_name(slot)!r}"
        if not isinstance(alloc, Allocation):
            raise ContractError(f"{where} returned {type(alloc).__name__}, not an Allocation")
        shape = (sim.batch_size, sim.sizes.tasks)
        for field, low, high in (("robot", 0, sim.sizes.robots), ("navigator", -1, sim.sizes.humans),
                                 ("classifier", -1, sim.sizes.humans)):
            arr = np.asarray(getattr(alloc, field))
            if arr.shape != shape:
                raise ContractError(f"{where}: {field} has shape {arr.shape}, expected {shape} "
                                    "(scenarios, POIs)")
            if not np.issubdtype(arr.dtype, np.integer):
                raise ContractError(f"{where}: {field} has dtype {arr.dtype}; an allocation "
                                    "holds integer indices (a float is never truncated "
                                    "silently)")
            if arr.size and (arr.min() < low or arr.max() >= high):
                raise ContractError(f"{where}: {field} values must lie in [{low}, {high}); "
                                    f"got {arr.min()}..{arr.max()}")
        # copies: a policy that keeps the arrays it returned cannot change what is in force
        return Allocation(np.array(alloc.robot, dtype=np.int64),
                          np.array(alloc.navigator, dtype=np.int64),
                          np.array(alloc.classifier, dtype=np.int64))

    def step_epoch(self) -> None:
        """Run one decision epoch: observe, inject, reconstruct, decide, then its ticks.

        It is `begin_epoch`, the decision of the mission's components (`decide`), then
        `end_epoch`; an outside agent (the `ata.gym` environments) calls the two halves itself
        and makes the decision in between.
        """
        self.end_epoch(*self.decide(self.begin_epoch()))

    def begin_epoch(self) -> DecisionContext:
        """The first part of an epoch, up to its decision: observe, inject and reconstruct at
        t = epoch * epoch_s; return the context of the decision (kept as ``last_context``)."""
        sim, hook = self.sim, self.pm.hook
        if self._pending is not None:
            raise RuntimeError(f"epoch {sim.epoch} has begun already: end it with end_epoch")
        if sim.epoch >= sim.clock.n_epochs:
            raise RuntimeError(f"the episode is over: all {sim.clock.n_epochs} epochs were run")
        sim.now = sim.epoch * sim.clock.epoch_s
        truth = Observation()
        hook.ata_observe(sim=sim, obs=truth)
        observed = truth.observable()             # the hidden values never reach S
        hook.ata_inject(sim=sim, obs=observed)
        # the decision-makers' copy, read-only: the injectors may keep the arrays they wrote
        observed = observed.frozen()
        recon: dict[str, np.ndarray] = {}
        view = DecisionView(sim, self.decision_rng)
        hook.ata_reconstruct(sim=view, obs=observed, inherent=self.inherent, out=recon)
        if self.references:
            # a copy: a reference may not change the truth the kernel checks reallocations by
            getattr(hook, REFERENCE_HOOK)(sim=view, truth=truth.copy(), obs=observed,
                                          inherent=self.inherent, out=recon)
        ctx = self._context(observed, recon)
        self.shown = ctx.reallocatable
        """What S showed reallocatable at the epoch begun (the kernel's own reference: a
        decision-maker that rebinds ``ctx.reallocatable`` changes nothing here)."""
        self.last_context = self._pending = ctx
        self.last_truth = truth
        return ctx

    def decide(self, ctx: DecisionContext) -> tuple[Any, np.ndarray | None]:
        """What the mission's own decision components decide at `ctx`: at epoch 0 (the initial
        allocation, None); later (the reallocation policy's proposal, or None where the
        condition policy reallocates no scenario; the condition policy's (B,) bool)."""
        sim = self.sim
        if ctx.epoch == 0:
            return self._callers["initial"](ctx=ctx), None
        active = np.asarray(self._callers["condition"](ctx=ctx), dtype=bool)
        if active.shape != (sim.batch_size,):
            name = self._component_name("condition")
            raise ContractError(f"condition policy {name!r} returned shape {active.shape}, "
                                f"expected ({sim.batch_size},)")
        if not active.any():
            return None, active
        return self._callers["reallocation"](ctx=ctx, active=active), active

    def end_epoch(self, allocation: Allocation | None, active: np.ndarray | None = None) -> None:
        """The rest of the epoch begun by `begin_epoch`: apply its decision, run its ticks,
        record it.

        :param allocation: at epoch 0, the initial allocation; later, the proposed allocation of
            the scenarios in `active` (None when there are none). Tasks outside the context's
            ``reallocatable`` and the scenarios not in `active` keep their triples. It is checked
            as the initial or the reallocation policy's answer.
        :param active: (B,) bool, the scenarios that reallocate (unused at epoch 0).
        """
        sim, hook, clock, ctx = self.sim, self.pm.hook, self.sim.clock, self._pending
        if ctx is None:
            raise RuntimeError("no epoch has begun: call begin_epoch first")
        k = sim.epoch
        if k == 0:
            alloc = self._check(allocation, "initial")
            sim.allocation = alloc
            sim.log("allocate", k, int(sim.batch_size))
            hook.ata_allocation_changed(sim=sim, changed=np.ones(alloc.robot.shape, dtype=bool),
                                        previous=None)
        else:
            active = np.asarray(active, dtype=bool)
            if active.shape != (sim.batch_size,):
                raise ContractError(f"active must have shape ({sim.batch_size},), got "
                                    f"{active.shape}")
            if active.any():
                proposed = self._check(allocation, "reallocation")
                previous = sim.allocation
                # what the policy saw as reallocatable and what truly is: a stale observation
                # may show a captured POI, or one a robot is on its way to, as open. Its triple
                # stays, and a change proposed there counts as refused.
                shown = active[:, None] & self.shown
                truly = self._reallocatable(self.last_truth)
                refused = shown & ~truly & ((proposed.robot != previous.robot)
                                            | (proposed.navigator != previous.navigator)
                                            | (proposed.classifier != previous.classifier))
                if refused.any():
                    sim.record.refused += refused.sum(axis=1)
                    sim.log("refused", k, int(refused.sum()))
                allowed = shown & truly
                merged = proposed.where(allowed, previous)
                changed = ((merged.robot != previous.robot) | (merged.navigator != previous.navigator)
                           | (merged.classifier != previous.classifier))
                sim.allocation = merged
                sim.record.reallocated[:, k] = active
                sim.log("reallocate", k, int(active.sum()), int(changed.sum()))
                if changed.any():
                    hook.ata_allocation_changed(sim=sim, changed=changed, previous=previous)
        self._pending = None
        sim.record.allocations[:, k] = sim.allocation.stack()
        for j in range(clock.ticks_per_epoch):
            sim.tick = k * clock.ticks_per_epoch + j
            t0 = sim.tick * clock.tick_s
            hook.ata_advance(sim=sim, t0=t0, t1=t0 + clock.tick_s)
        hook.ata_epoch_end(sim=sim, epoch=k)
        sim.epoch = k + 1
        sim.now = sim.epoch * clock.epoch_s

    def reset(self) -> Observation:
        """Sample the batch and collect the inherent information I."""
        hook = self.pm.hook
        hook.ata_setup(sim=self.sim)
        inherent = Observation()
        hook.ata_inherent(sim=self.sim, inherent=inherent)
        self.inherent = inherent.frozen()         # I as every decision-maker sees it
        return self.inherent

    def run(self, on_epoch: Callable[[int], None] | None = None) -> EpisodeRecord:
        """Run the whole episode for the batch and return its record."""
        self.reset()
        for _ in range(self.sim.clock.n_epochs):
            self.step_epoch()
            if on_epoch is not None:
                on_epoch(self.sim.epoch)
        return self.end_episode()

    def end_episode(self) -> EpisodeRecord:
        """After the last epoch: the components write their per-scenario results; the record."""
        record = self.sim.record
        record.metrics["refused_changes"] = record.refused.astype(float)
        if self.references:
            record.metrics[REFERENCE_COLUMN] = np.ones(self.sim.batch_size)
        self.pm.hook.ata_episode_end(sim=self.sim)
        self._episode_scored(record)
        return record

    def _episode_scored(self, record: EpisodeRecord) -> None:
        """Tell the components the episode's record without the world (`ata_episode_scored`);
        add the per-scenario results they give to the record's."""
        outcome = EpisodeOutcome(r_perf=read_only(record.r_perf),
                                 reallocated=read_only(record.reallocated),
                                 allocations=read_only(record.allocations))
        self.pm.hook.ata_episode_scored(episode=outcome)
        for name, values in outcome.metrics.items():
            values = np.asarray(values, dtype=float)
            if name in record.metrics:
                raise ContractError(f"results column {name!r} is written twice: a component "
                                    "adds it in ata_episode_scored, another wrote it before")
            if values.shape != (self.sim.batch_size,):
                raise ContractError(f"results column {name!r} has shape {values.shape}, "
                                    f"expected ({self.sim.batch_size},)")
            record.metrics[name] = values
        record.warnings.extend(outcome.warnings)
