"""The data the kernel passes between components: clock, entity tables, allocations, records.

Every array has a leading scenario axis of length B. The kernel does not know what a human or
a robot is: the models declare entity groups ("humans", "robots", "tasks") by name and fill
them; policies read them by column name.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Iterable, Mapping

import numpy as np

from ata.core.errors import ContractError
from ata.core.queues import Queue
from ata.core.channel import Channel, T, check_published, read_only  # noqa: F401 (public here)
from ata.core.rng import BatchRNG, StreamRNG


@dataclass(frozen=True)
class Clock:
    """Kernel tick, decision epoch and horizon, in seconds."""

    tick_s: float = 10.0
    epoch_s: float = 60.0
    horizon_s: float = 1800.0

    @property
    def ticks_per_epoch(self) -> int:
        return int(round(self.epoch_s / self.tick_s))

    @property
    def n_epochs(self) -> int:
        return int(round(self.horizon_s / self.epoch_s))

    @property
    def n_ticks(self) -> int:
        return self.n_epochs * self.ticks_per_epoch


@dataclass(frozen=True)
class TeamSize:
    """Numbers of humans, robots and tasks (POIs) in every scenario of a batch."""

    humans: int
    robots: int
    tasks: int


class EntityTable:
    """Features of one kind of entity: an array (B, N, F) with named columns and a mask (B, N).

    ``holds`` (B, N) int, when a model sets it (`Observation.hold`): the task each row holds,
    which may not be reallocated (-1: none). It belongs to the row: a stale row holds what it
    held when it was observed.
    """

    def __init__(self, names: Iterable[str], features: np.ndarray, mask: np.ndarray | None = None,
                 holds: np.ndarray | None = None):
        self.names: tuple[str, ...] = tuple(names)
        if features.ndim != 3 or features.shape[2] != len(self.names):
            raise ValueError(f"features must be (B, N, {len(self.names)}), got {features.shape}")
        self.features = features
        self.mask = np.ones(features.shape[:2], dtype=bool) if mask is None else mask
        self.holds = holds
        self._index = {n: i for i, n in enumerate(self.names)}

    def index(self, name: str) -> int:
        try:
            return self._index[name]
        except KeyError:
            raise KeyError(f"no column {name!r}; columns: {', '.join(self.names)}") from None

    def col(self, name: str) -> np.ndarray:
        """A view (B, N) of one column; writing to it writes the table."""
        return self.features[:, :, self.index(name)]

    def set(self, name: str, values: np.ndarray) -> None:
        self.features[:, :, self.index(name)] = values

    def copy(self) -> "EntityTable":
        return EntityTable(self.names, self.features.copy(), self.mask.copy(),
                           None if self.holds is None else self.holds.copy())

    def frozen(self) -> "EntityTable":
        """A copy whose arrays are read-only (`read_only`)."""
        return EntityTable(self.names, read_only(self.features), read_only(self.mask),
                           None if self.holds is None else read_only(self.holds))

    def take(self, rows: np.ndarray) -> "EntityTable":
        """The table of a sub-batch of scenarios."""
        return EntityTable(self.names, self.features[rows], self.mask[rows],
                           None if self.holds is None else self.holds[rows])

    def keep_rows(self, stale: np.ndarray, previous: "EntityTable") -> None:
        """Show the rows where `stale` (B, N) holds as they were in `previous` (an injector's
        latency): their features and what they held."""
        self.features[:] = np.where(stale[..., None], previous.features, self.features)
        if self.holds is not None and previous.holds is not None:
            self.holds = np.where(stale, previous.holds, self.holds)


class Observation(dict):
    """Entity tables by group name ("humans", "robots", "tasks"), plus named extra arrays, and
    the declared field ``reallocatable``: (B, P) bool, the tasks whose triple may change now
    (None until a model restricts it: then every task may).

    ``reallocatable`` is read off the observation itself: no row of any table holds the task
    (`hold`), and no model's other restriction forbids it (`restrict_reallocation`). A stale
    row shows what it held when it was observed, so the field is as observed, like the rest.
    """

    def __init__(self, *args: Any, **kwargs: Any):
        super().__init__(*args, **kwargs)
        self.extras: dict[str, np.ndarray] = {}
        self.hidden: dict[str, np.ndarray] = {}
        """Values of the true state that are never observed (`hide`)."""
        self.allowed: np.ndarray | None = None   # the restrictions not tied to a row
        self.n_tasks: int | None = None

    def hide(self, name: str, values: np.ndarray) -> None:
        """Add a value of the true state that no observation shows (a hidden parameter of the
        world, leading axis B): the kernel leaves it out of the observed S (`observable`), and
        only a reference reconstructor (``ata_reconstruct_reference``) receives it."""
        self.hidden[name] = np.asarray(values)

    def restrict_reallocation(self, allowed: np.ndarray) -> None:
        """A model's say on which tasks may be reallocated now: (B, P) bool, combined with the
        other models' by logical and. A restriction that follows from a table's rows is better
        declared with `hold`, so that it goes stale with them."""
        allowed = np.asarray(allowed, dtype=bool)
        self.allowed = allowed if self.allowed is None else self.allowed & allowed
        self.n_tasks = allowed.shape[1]

    def hold(self, group: str, tasks: np.ndarray, n_tasks: int) -> None:
        """Declare the task each row of table `group` holds: (B, N) int, -1 for none. A held
        task may not be reallocated (a robot's leg under way, a task's own capture)."""
        self[group].holds = np.asarray(tasks, dtype=np.int64)
        self.n_tasks = int(n_tasks)

    @property
    def reallocatable(self) -> np.ndarray | None:
        held = [t.holds for t in self.values() if t.holds is not None]
        if not held:
            return None if self.allowed is None else self.allowed.copy()
        out = np.ones((held[0].shape[0], self.n_tasks), dtype=bool) if self.allowed is None \
            else self.allowed.copy()
        for holds in held:
            b, n = np.nonzero(holds >= 0)
            out[b, holds[b, n]] = False
        return out

    def add(self, group: str, names: Iterable[str], features: np.ndarray,
            mask: np.ndarray | None = None) -> EntityTable:
        table = EntityTable(names, features, mask)
        self[group] = table
        return table

    def _with(self, tables: dict[str, EntityTable], extras: dict[str, np.ndarray],
              allowed: np.ndarray | None, hidden: dict[str, np.ndarray]) -> "Observation":
        out = Observation(tables)
        out.extras, out.allowed, out.n_tasks = extras, allowed, self.n_tasks
        out.hidden = hidden
        return out

    def copy(self) -> "Observation":
        """A deep copy, hidden values included (a copy of the truth is the truth)."""
        return self._with({k: v.copy() for k, v in self.items()},
                          {k: v.copy() for k, v in self.extras.items()},
                          None if self.allowed is None else self.allowed.copy(),
                          {k: v.copy() for k, v in self.hidden.items()})

    def frozen(self) -> "Observation":
        """A copy without the hidden values whose arrays are read-only: what a decision-maker
        receives, so that an edit in place changes neither the world nor what the kernel or
        another decision-maker reads."""
        return self._with({k: v.frozen() for k, v in self.items()},
                          {k: read_only(v) for k, v in self.extras.items()},
                          None if self.allowed is None else read_only(self.allowed), {})

    def observable(self) -> "Observation":
        """A deep copy without the hidden values: what an observation may show of it."""
        out = self.copy()
        out.hidden = {}
        return out

    def take(self, rows: np.ndarray) -> "Observation":
        """The observation of a sub-batch of scenarios."""
        return self._with({k: v.take(rows) for k, v in self.items()},
                          {k: v[rows] for k, v in self.extras.items()},
                          None if self.allowed is None else self.allowed[rows],
                          {k: v[rows] for k, v in self.hidden.items()})


AUTO = -1
"""Navigator value for autonomous driving."""
ONBOARD = -1
"""Classifier value for the robot's onboard detector."""


@dataclass
class Allocation:
    """One (robot, navigator, classifier) triple per task: three int arrays of shape (B, P).

    navigator is AUTO (-1) or a human index; classifier is ONBOARD (-1) or a human index.
    """

    robot: np.ndarray
    navigator: np.ndarray
    classifier: np.ndarray

    def copy(self) -> "Allocation":
        return Allocation(self.robot.copy(), self.navigator.copy(), self.classifier.copy())

    def frozen(self) -> "Allocation":
        """A copy whose arrays are read-only (the allocation in force, as a decision-maker
        receives it)."""
        return Allocation(read_only(self.robot), read_only(self.navigator),
                          read_only(self.classifier))

    def take(self, rows: np.ndarray) -> "Allocation":
        """The allocation of a sub-batch of scenarios."""
        return Allocation(self.robot[rows], self.navigator[rows], self.classifier[rows])

    def stack(self) -> np.ndarray:
        """(B, P, 3) int array of the triples."""
        return np.stack([self.robot, self.navigator, self.classifier], axis=-1)

    @classmethod
    def from_stack(cls, triples: np.ndarray) -> "Allocation":
        t = np.asarray(triples, dtype=np.int64)
        return cls(t[..., 0].copy(), t[..., 1].copy(), t[..., 2].copy())

    def matrix(self, n_robots: int, n_humans: int) -> np.ndarray:
        """The allocation matrix of docs/model.md: one-hot rows, (B, P, R + (1+H) + (1+H))."""
        B, P = self.robot.shape
        width = n_robots + 2 * (1 + n_humans)
        out = np.zeros((B, P, width), dtype=np.float32)
        b, p = np.indices((B, P))
        out[b, p, self.robot] = 1.0
        out[b, p, n_robots + 1 + self.navigator] = 1.0
        out[b, p, n_robots + (1 + n_humans) + 1 + self.classifier] = 1.0
        return out

    def where(self, mask: np.ndarray, other: "Allocation") -> "Allocation":
        """Per task, this allocation where mask (B, P) holds, else other's."""
        return Allocation(np.where(mask, self.robot, other.robot),
                          np.where(mask, self.navigator, other.navigator),
                          np.where(mask, self.classifier, other.classifier))


def frobenius_change(a: Allocation, b: Allocation) -> np.ndarray:
    """||A - B||_F of the two allocation matrices, per scenario (B,), without building them.

    Each changed choice of a task flips two entries of a one-hot row by 1, adding 2 to the square.
    """
    changes = ((a.robot != b.robot).sum(1) + (a.navigator != b.navigator).sum(1)
               + (a.classifier != b.classifier).sum(1))
    return np.sqrt(2.0 * changes)


@dataclass
class EpisodeRecord:
    """What the kernel keeps of an episode, enough to compute every reward of docs/model.md."""

    r_perf: np.ndarray                  # (B, T) points gained in each epoch
    reallocated: np.ndarray             # (B, T) bool: a reallocation was made at epoch t
    allocations: np.ndarray             # (B, T, P, 3) int16: the allocation in force during epoch t
    upper_bound: np.ndarray             # (B,) the capacity-free upper bound U
    metrics: dict[str, np.ndarray] = field(default_factory=dict)   # (B,) per-scenario extras
    task_gain: np.ndarray | None = None  # (B, P) points each POI's classification earned
    task_epoch: np.ndarray | None = None  # (B, P) epoch of that classification (-1: never)
    r_expected: np.ndarray | None = None  # (B, T) r_perf in expectation: the points the
    #                                       epoch's classifications expected, given how they
    #                                       were made (for training; the outcome draws aside)
    warnings: list[str] = field(default_factory=list)   # for the run's summary
    refused: np.ndarray | None = None   # (B,) changes the kernel refused: proposed for a task
    #                                     shown reallocatable (a stale row) that truly was not

    @classmethod
    def empty(cls, batch: int, n_epochs: int, n_tasks: int) -> "EpisodeRecord":
        return cls(r_perf=np.zeros((batch, n_epochs)),
                   reallocated=np.zeros((batch, n_epochs), dtype=bool),
                   allocations=np.zeros((batch, n_epochs, n_tasks, 3), dtype=np.int16),
                   upper_bound=np.zeros(batch), r_expected=np.zeros((batch, n_epochs)),
                   refused=np.zeros(batch, dtype=np.int64))

    @property
    def total(self) -> np.ndarray:
        """Total team performance per scenario: the sum of r_perf over the episode."""
        return self.r_perf.sum(axis=1)


@dataclass
class EpisodeOutcome:
    """What a decision-maker learns of an episode once it is over (``ata_episode_scored``):
    its record, read-only, and where to add per-scenario results. Never the world: the true
    state, its generator and the mission stay the models'."""

    r_perf: np.ndarray                  # (B, T) points gained in each epoch, read-only
    reallocated: np.ndarray             # (B, T) bool, read-only
    allocations: np.ndarray             # (B, T, P, 3) the allocation in force, read-only
    metrics: dict[str, np.ndarray] = field(default_factory=dict)
    """Per-scenario results to add, (B,) each: they become results.csv columns."""
    warnings: list[str] = field(default_factory=list)
    """Lines for the run's summary."""

    @property
    def batch_size(self) -> int:
        return int(self.r_perf.shape[0])

    @property
    def total(self) -> np.ndarray:
        """The score of each scenario: the sum of r_perf over the episode."""
        return self.r_perf.sum(axis=1)


class ReadOnlyState:
    """Another model's state as a model may see it: every array a read-only view.

    Writing through it raises; a model passes work to another through a `Queue`.
    """

    __slots__ = ("_name", "_state")

    def __init__(self, name: str, state: Any):
        object.__setattr__(self, "_name", name)
        object.__setattr__(self, "_state", state)

    def __getattr__(self, attr: str) -> Any:
        value = getattr(object.__getattribute__(self, "_state"), attr)
        if isinstance(value, np.ndarray):
            value = value.view()
            value.flags.writeable = False
        return value

    def __setattr__(self, attr: str, value: Any) -> None:
        raise AttributeError(f"the {self._name!r} state is written by its owner only; pass work "
                             "to it through a queue (sim.queue)")

    def as_dict(self) -> dict[str, Any]:
        """Every field, arrays as read-only views."""
        return {k: getattr(self, k) for k in vars(object.__getattribute__(self, "_state"))}

    def __repr__(self) -> str:
        return f"ReadOnlyState({self._name!r}, {type(self._state).__name__})"


class SimState:
    """Everything one batch of scenarios holds while it runs.

    Each model owns the typed state of its group (``sim.own("humans", HumanState(...))``, which
    returns it for the owner to write); every other component sees it read-only through
    ``sim.group("humans")``. Work passes between models through named queues
    (``sim.queue(name)``). Typed values one component provides for others (a team model's
    constants) go through ``sim.publish(value)`` and ``sim.published(Type)``. ``sim.rng`` draws
    per-scenario numbers: it is the world's, and no decision hook receives it.
    """

    def __init__(self, *, sizes: TeamSize, clock: Clock, rng: BatchRNG, trace: bool = False):
        self.sizes = sizes
        self.clock = clock
        self.rng = rng
        self.batch_size = rng.batch_size
        self.now = 0.0
        self.epoch = 0
        self.tick = 0
        self.groups: dict[str, Any] = {}
        """Group name -> the owner's state (writable: for its owner, and for tests)."""
        self.queues: dict[str, Queue] = {}
        self.allocation: Allocation | None = None
        self.record = EpisodeRecord.empty(self.batch_size, clock.n_epochs, sizes.tasks)
        self.trace: list[tuple] | None = [] if trace else None
        self.channel = Channel()
        """What components published (`publish`); decision-makers see it on their context."""

    def publish(self, value: Any) -> None:
        """Publish a typed value for the other components and the policies (in ``ata_setup``)."""
        self.channel.publish(value)

    def published(self, kind: type[T]) -> T:
        """The value some component published as `kind`; ``ContractError`` when none did."""
        return self.channel.get(kind)

    def own(self, name: str, state: Any) -> Any:
        """Declare the state of group `name`, owned by the caller, and return it."""
        if name in self.groups:
            raise ValueError(f"group {name!r} has an owner already: "
                             f"{type(self.groups[name]).__name__}")
        self.groups[name] = state
        return state

    def group(self, name: str) -> ReadOnlyState:
        """Group `name`'s state, read-only (its owner keeps what `own` returned)."""
        try:
            return ReadOnlyState(name, self.groups[name])
        except KeyError:
            raise KeyError(f"no group {name!r}: a model declares it with sim.own; groups: "
                           f"{', '.join(sorted(self.groups)) or 'none'}") from None

    def queue(self, name: str) -> Queue:
        """The queue `name`, created empty on first use."""
        if name not in self.queues:
            self.queues[name] = Queue(name)
        return self.queues[name]

    def log(self, *event: Any) -> None:
        """Append an event to the trace when tracing is on (tests assert on it)."""
        if self.trace is not None:
            self.trace.append(event)


class DecisionView:
    """What a reconstructor sees of the batch (the ``sim`` of ``ata_reconstruct``): its size,
    clock and time, the allocation in force and the decision-makers' generator; never the
    world's state, generator or settings."""

    __slots__ = ("batch_size", "sizes", "clock", "epoch", "now", "allocation", "rng", "channel")

    def __init__(self, sim: SimState, rng: StreamRNG):
        self.batch_size, self.sizes, self.clock = sim.batch_size, sim.sizes, sim.clock
        self.epoch, self.now = sim.epoch, sim.now
        self.allocation = None if sim.allocation is None else sim.allocation.frozen()
        self.rng = rng
        self.channel = sim.channel

    def published(self, kind: type[T]) -> T:
        """What the team models published as `kind` (their constants), as ``sim.published``."""
        return self.channel.get(kind)

    def __getattr__(self, name: str) -> Any:
        raise AttributeError(f"a reconstructor sees no {name!r}: it estimates the state from "
                             "the observation (obs, inherent) and the allocation in force; the "
                             "world's state and generator are the models' own")


REMOVED_CONTEXT_FIELDS = {
    "params": "the decision context carries no mission (its root seed would let a policy "
              "rebuild the world): a component reads its own settings from its factory's "
              "arguments or ctx.settings, the team models' constants from ctx.published(Type)"}


@dataclass
class DecisionContext:
    """What an allocation, condition or reallocation policy sees at a decision epoch: I, the
    observed S, the reconstructors' estimates, the allocation in force, the settings of the
    mission's decision components and the team models' constants, and a generator of its own.
    Nothing in it leads to the true state, the world's generator or the root seed."""

    epoch: int
    time: float
    sizes: TeamSize
    clock: Clock
    inherent: Observation               # I: humans, robots, tasks (task attributes as estimated)
    observed: Observation | None        # S after the injectors (at t = 0 too)
    reconstructed: dict[str, np.ndarray]  # reconstructors' outputs by name
    previous: Allocation | None         # the allocation in force; None at t = 0
    reallocatable: np.ndarray           # (B, P) bool: tasks whose triple may change now, as
    #                                     observed (S): under latency a row may be stale
    rng: StreamRNG                      # the decision-makers' own streams, never the world's
    settings: Mapping[str, Any] = field(default_factory=dict)
    """The resolved settings of the mission's decision components (policies, condition,
    reconstructors), by component name."""
    channel: Channel = field(default_factory=Channel)
    """What the team models published: their constants (``published(Type)``)."""

    def published(self, kind: type[T]) -> T:
        """The value a component published as `kind` (a team model's constants, say);
        ``ContractError`` naming the type and its publisher when none did."""
        return self.channel.get(kind)

    def __getattr__(self, name: str) -> Any:
        if name in REMOVED_CONTEXT_FIELDS:
            raise AttributeError(f"DecisionContext has no field {name!r}: "
                                 f"{REMOVED_CONTEXT_FIELDS[name]}")
        raise AttributeError(f"{type(self).__name__!r} object has no attribute {name!r}")

    def take(self, rows: np.ndarray) -> "DecisionContext":
        """The context of a sub-batch of scenarios (a policy may decide for those alone)."""
        def sub(x):
            return None if x is None else x.take(rows)
        return DecisionContext(epoch=self.epoch, time=self.time, sizes=self.sizes,
                               clock=self.clock, inherent=sub(self.inherent),
                               observed=sub(self.observed),
                               reconstructed={k: v[rows] for k, v in self.reconstructed.items()},
                               previous=sub(self.previous), reallocatable=self.reallocatable[rows],
                               rng=self.rng.subset(rows), settings=self.settings,
                               channel=self.channel)
