"""The slot model (`SLOTS`: each slot of a mission's ``[components]``, the kind it takes, the
hook asked of a decision slot's component), what a registered component is (`ComponentInfo`),
and what a mission's validation asks of the registry that holds them (`Components`, which
`ata.core.registry.Register` is). The component kinds, the decision slots and kinds, and the
world's kinds are read from `SLOTS`: a new slot is written there once.

They stand below the registry so that the mission and reference modules read them without
importing it: the registry imports the hook specs, and the hook specs name the `Mission` that
their hooks receive."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Callable, Protocol


@dataclass(frozen=True)
class Slot:
    """A slot of ``[components]``: the kind of component it takes; for a single-choice slot
    whose component alone is asked, the hook called on it; whether it holds a decision-maker
    (built without the seed, seeing the world through its context). List slots and the
    models take part in every phase hook."""

    name: str
    kind: str
    hook: str | None = None
    decision: bool = False


SLOTS = (Slot("task_model", "task_model"), Slot("human_model", "human_model"),
         Slot("robot_model", "robot_model"),
         Slot("perturbations", "perturbation"), Slot("injectors", "injector"),
         Slot("reconstructors", "reconstructor", decision=True),
         Slot("initial", "policy", "ata_initial_allocation", decision=True),
         Slot("condition", "condition", "ata_should_reallocate", decision=True),
         Slot("reallocation", "policy", "ata_reallocate", decision=True))
"""The slots a simulation fills, in hook-call order: the one place the slot model is written."""
DECISION_SLOTS = tuple(s.name for s in SLOTS if s.decision)
"""The slots of the decision-makers, in hook-call order."""
DECISION_KINDS = frozenset(s.kind for s in SLOTS if s.decision)
"""The decision-makers' kinds: built from the mission without its seed (`Mission.public`),
they see the world through their DecisionContext (a reconstructor through a DecisionView)."""
WORLD_KINDS = tuple(dict.fromkeys(s.kind for s in SLOTS if not s.decision))
"""The world's kinds (the models, perturbations and injectors): built with the seed."""
KINDS = (*dict.fromkeys(s.kind for s in SLOTS), "trainer")
"""Component kinds: those of the slots, and ``trainer``, built by `ata train` only
(``ata.training``). A ``policy`` may fill the initial and the reallocation slot."""


@dataclass(frozen=True)
class ComponentInfo:
    """One registered component."""

    kind: str
    name: str
    factory: Callable[..., Any]
    plugin: str          # the registering plugin's name
    dist: str            # distribution name and version, "ata 0.1.0"


class Components(Protocol):
    """The components by (kind, name), as a mission's validation reads and extends them."""

    components: dict[tuple[str, str], ComponentInfo]
    loaded: list[str]
    """The optional plugins loaded on demand because a mission named one of their components."""

    def names(self, kind: str) -> list[str]:
        """The registered names of `kind`, sorted."""

    def get(self, kind: str, name: str, where: str) -> ComponentInfo:
        """The component `name` of `kind` (loading the plugin declared to provide it); a
        MissionError at `where` when there is none."""
