"""What a registered component is (`ComponentInfo`), and what a mission's validation asks of the
registry that holds them (`Components`, which `ata.core.registry.Register` is).

They stand below the registry so that the mission and reference modules read them without
importing it: the registry imports the hook specs, and the hook specs name the `Mission` that
their hooks receive."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Callable, Protocol


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
