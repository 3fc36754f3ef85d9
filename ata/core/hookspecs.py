"""Hook specifications of ata, sectioned by the phase in which the kernel calls them.

Two kinds of plugin take part:

* *Package plugins* (the built-ins, third-party packages found through the ``ata`` entry-point
  group) implement only the start-up hook ``ata_register_components``: they contribute
  components by name.
* *Components* (a human model, an injector, a policy ...) are objects that the kernel creates
  for each batch from the mission file and registers into that batch's plugin manager. They
  implement the phase hooks below. Each phase hook is called once per phase for the whole batch;
  implementations run in mission order (task model, human model, robot model, perturbations,
  injectors in their listed order, reconstructors, then the policies).

The decision hooks (``ata_initial_allocation``, ``ata_should_reallocate``, ``ata_reallocate``)
are called only on the one component chosen for their slot. A decision-maker (a component in a
decision slot: reconstructors, initial, condition, reallocation) sees the scenario through its
``DecisionContext`` (a reconstructor through a ``DecisionView``), whose arrays are read-only
copies, and may implement no hook that hands it the world (``sim``), ``ata_episode_end``
included: the kernel refuses it. At the end of an episode it learns its record and score through
``ata_episode_scored``. The order in which a robot visits
its POIs is not a hook: it is a setting of the robot model (``[robot] routing``).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, Callable

import numpy as np
import pluggy

if TYPE_CHECKING:
    from ata.core.mission import Mission
    from ata.core.state import (Allocation, DecisionContext, DecisionView, EpisodeOutcome,
                                Observation, SimState)

hookspec = pluggy.HookspecMarker("ata")


# --- start-up ---------------------------------------------------------------------------------

@hookspec
def ata_register_components(register: "Callable[[str, str, Any], None]") -> None:
    """Contribute components by name.

    :param register: call ``register(kind, name, factory)`` once per component. ``kind`` is one
        of ``ata.core.registry.KINDS``; ``factory`` is a class whose ``Settings`` dataclass (if
        any) lists the component's mission-file keys, called as ``factory(settings, mission)``.
    """


# --- setup: once per batch, before t = 0 -------------------------------------------------------

@hookspec
def ata_peak_bytes(mission: "Mission", batch: int) -> int:
    """The memory, in bytes, the component adds at its peak while `batch` scenarios of
    `mission` run together (its own arrays, networks' activations, solver models).

    Asked before any work starts, of the components built once on one scenario
    (``ata.runtime.memory``): a run cuts its batches smaller, or refuses the mission, naming
    the figure and the limit. A component that does not implement it is counted at the
    default: the kernel's episode record, and for a policy the planner's working arrays
    (``ata.model.greedy_planner.peak_bytes``), are counted for every mission anyway.
    """


@hookspec
def ata_setup(sim: "SimState") -> None:
    """Sample the batch's scenarios: inherent information, initial state, event schedules.

    :param sim: the batch; models declare the state they own with ``sim.own(name, state)``
        (others read it with ``sim.group(name)``, read-only; work passes through
        ``sim.queue(name)``) and draw their numbers from ``sim.rng`` with stream names of their
        own; a value others need (a team model's constants) goes out through
        ``sim.publish(value)``, which they read with ``sim.published(Type)`` or
        ``ctx.published(Type)``.
    """


@hookspec
def ata_inherent(sim: "SimState", inherent: "Observation") -> None:
    """Write the inherent information I (humans, robots, estimated task attributes).

    :param inherent: add one ``EntityTable`` per group with ``inherent.add(group, names, array)``.
    """


# --- decision epoch: at t = k * epoch_s, k = 0 .. T-1 ------------------------------------------

@hookspec
def ata_observe(sim: "SimState", obs: "Observation") -> None:
    """Write the true dynamic state S at the current epoch into ``obs`` (one table per group)."""


@hookspec
def ata_inject(sim: "SimState", obs: "Observation") -> None:
    """Corrupt the observation in place (noise, staleness): an uncertainty injector's phase.

    :param obs: the observation so far; injectors run in the mission's listed order, each on the
        output of the one before it. The true state stays in ``sim``.
    """


@hookspec
def ata_reconstruct(sim: "DecisionView", obs: "Observation", inherent: "Observation",
                    out: dict[str, np.ndarray]) -> None:
    """Estimate the true state from the observation: a reconstructor's phase.

    :param sim: the batch as a decision-maker sees it: size, clock, time, the allocation in
        force and the decision-makers' generator (never the world's state or generator).

    :param out: put each estimate under a name of your own, shape (B, N, F); policies read it
        from ``DecisionContext.reconstructed``.
    """


@hookspec
def ata_reconstruct_reference(sim: "DecisionView", truth: "Observation", obs: "Observation",
                              inherent: "Observation", out: dict[str, np.ndarray]) -> None:
    """Hand the policies what the true state says: a reference reconstructor's phase.

    A yardstick, never a method: the kernel calls it after ``ata_reconstruct``, only on a
    component of the ``reconstructors`` slot whose class declares ``reference = True`` (it
    refuses any other component that implements it), and marks every results row of the
    mission with ``reference = 1``, so that reports label it a reference.

    :param truth: a copy of the true S of this epoch, before any injector, with the values no
        observation shows (``truth.hidden``, e.g. each human's fatigue curve).
    :param obs: the observed S, as ``ata_reconstruct`` received it.
    :param out: the estimates the reconstructors wrote; write (or overwrite) entries of it.
    """


@hookspec(firstresult=True)
def ata_initial_allocation(ctx: "DecisionContext") -> "Allocation":
    """Return the initial allocation (ITA) at t = 0. Called on the initial-policy component only."""


@hookspec(firstresult=True)
def ata_should_reallocate(ctx: "DecisionContext") -> np.ndarray:
    """Return a (B,) bool array: reallocate now? Called on the condition component only."""


@hookspec(firstresult=True)
def ata_reallocate(ctx: "DecisionContext", active: np.ndarray) -> "Allocation":
    """Return the new allocation for the scenarios where ``active`` (B,) holds.

    Only tasks in ``ctx.reallocatable`` (as observed) may change; the kernel keeps the previous
    triple for the others, for the tasks that truly may not change (captured, or a leg under way,
    though a stale observation shows them open: such a change is refused, and counted) and for
    inactive scenarios. Called on the reallocation component only.
    """


@hookspec
def ata_allocation_changed(sim: "SimState", changed: np.ndarray,
                           previous: "Allocation | None") -> None:
    """React to a new allocation in ``sim.allocation``; ``changed`` (B, P) marks changed tasks.

    :param previous: the allocation in force before the change; None for the initial one.
        The team models charge the re-tasking cost of docs/model.md from the difference.
    """


@hookspec
def ata_trained_on() -> list[tuple[int, int, int]]:
    """The scenarios the component's trained weights saw: (root seed, first id, end id) ranges.

    A learned component answers from its checkpoint (``ata.training``); `ata eval` refuses to
    evaluate on any of them. Components with nothing trained need not implement it.
    """


# --- tick: every tick_s seconds -----------------------------------------------------------------

@hookspec
def ata_advance(sim: "SimState", t0: float, t1: float) -> None:
    """Advance the true state from time t0 to t1 (seconds) for the whole batch."""


# --- epoch end and episode end -------------------------------------------------------------------

@hookspec
def ata_epoch_end(sim: "SimState", epoch: int) -> None:
    """Record what happened in epoch ``epoch`` (e.g. ``sim.record.r_perf[:, epoch]``)."""


@hookspec
def ata_episode_end(sim: "SimState") -> None:
    """Write per-scenario results: ``sim.record.upper_bound`` and ``sim.record.metrics``."""


@hookspec
def ata_episode_scored(episode: "EpisodeOutcome") -> None:
    """After ``ata_episode_end``: the episode's record and score, without the world.

    The end-of-episode hook a decision-maker may implement (it may not implement
    ``ata_episode_end``, which hands over the world, whose generator and mission would tell it
    the next scenarios' draws).

    :param episode: the rewards, reallocations and allocations of the episode (read-only); add
        per-scenario results to ``episode.metrics`` ((B,) arrays, new names only) and summary
        lines to ``episode.warnings``.
    """
