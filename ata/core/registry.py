"""Plugin manager factory and the registry of components that plugins contribute by name.

Start-up order, fixed and readable: hook specs, built-in plugins, optional plugins named by the
user, entry points of the ``ata`` group, then ``check_pending()`` so that a misspelt hook name
fails here rather than being ignored.
"""

from __future__ import annotations

import difflib
import importlib
import os
import sys
from dataclasses import dataclass
from importlib import metadata
from typing import Any, Callable, Iterable

import pluggy

from ata.core import hookspecs
from ata.core.errors import MissionError

KINDS = ("task_model", "human_model", "robot_model", "perturbation", "injector", "reconstructor",
         "policy", "condition", "trainer")
"""Component kinds. A ``policy`` may fill the initial and the reallocation slot; a ``trainer``
is built by `ata train` only (``ata.training``)."""

BUILTIN_GROUP = "ata.builtin"
OPTIONAL_GROUP = "ata.optional"
THIRD_PARTY_GROUP = "ata"
"""Entry-point groups: the default tier (always loaded), the optional tier (loaded only when
named: the torch-based learned methods) and third-party packages. The core knows no plugin:
ata's own are declared in its pyproject.toml like any other package's."""


def _entry_points(group: str) -> dict[str, str]:
    """name -> module of the entry points of `group`, in the order of their modules."""
    found = {ep.name: ep.value for ep in metadata.entry_points(group=group)}
    return dict(sorted(found.items(), key=lambda item: item[1]))


BUILTIN_PLUGINS: tuple[str, ...] = tuple(_entry_points(BUILTIN_GROUP).values())
"""Default-tier plugin modules, always loaded."""
OPTIONAL_PLUGINS: dict[str, str] = _entry_points(OPTIONAL_GROUP)
"""Optional-tier plugins, name -> module, loaded only when named."""


def requires(name: str) -> tuple[str, ...]:
    """The optional plugins that optional plugin `name` brings along (its module's
    ``ATA_REQUIRES``: the full method's parts need its ITA policy)."""
    module = importlib.import_module(OPTIONAL_PLUGINS[name])
    return tuple(getattr(module, "ATA_REQUIRES", ()))


@dataclass(frozen=True)
class ComponentInfo:
    """One registered component."""

    kind: str
    name: str
    factory: Callable[..., Any]
    plugin: str          # the registering plugin's name
    dist: str            # distribution name and version, "ata 0.1.0"


def _one_table(a: Callable[..., Any], b: Callable[..., Any]) -> bool:
    """Whether two factories are one component's: the same, or reading one Settings class."""
    settings = getattr(a, "Settings", None)
    return a is b or (settings is not None and settings is getattr(b, "Settings", None))


class Register:
    """The callable that ``ata_register_components`` receives; collects components by name."""

    def __init__(self) -> None:
        self.components: dict[tuple[str, str], ComponentInfo] = {}
        self._plugin = "?"
        self._dist = "?"

    def __call__(self, kind: str, name: str, factory: Callable[..., Any]) -> None:
        if kind not in KINDS:
            raise ValueError(f"plugin {self._plugin}: unknown component kind {kind!r}; "
                             f"kinds: {', '.join(KINDS)}")
        # A name means one component (its settings table is named after it): the same factory
        # may be registered under several kinds (a policy that also decides when), or factories
        # that read one Settings class (a method's policy and its trainer), nothing else.
        for (other_kind, other_name), info in self.components.items():
            if other_name == name and (other_kind == kind or not _one_table(info.factory,
                                                                            factory)):
                raise ValueError(f"plugin {self._plugin}: component name {name!r} is already "
                                 f"registered ({other_kind}) by {info.plugin}")
        key = (kind, name)
        self.components[key] = ComponentInfo(kind, name, factory, self._plugin, self._dist)

    def names(self, kind: str) -> list[str]:
        return sorted(n for k, n in self.components if k == kind)

    def get(self, kind: str, name: str, where: str) -> ComponentInfo:
        try:
            return self.components[(kind, name)]
        except KeyError:
            known = ", ".join(self.names(kind)) or "(none)"
            hint = ""
            if name in OPTIONAL_PLUGINS:
                hint = f"; it comes with the optional plugin {name!r} (--plugins {name})"
            other = [k for k, n in self.components if n == name]
            if other:
                hint = (f"; {name!r} is registered as a {other[0]}, which goes in another "
                        "[components] slot")
            raise MissionError(where, None, f"unknown {kind} {name!r}; registered: {known} "
                               f"(see: ata plugins){hint}") from None


def get_plugin_manager(*, optional: Iterable[str] = (), entry_points: bool = True,
                       extra: Iterable[Any] = ()) -> pluggy.PluginManager:
    """Build a fresh plugin manager: specs, built-ins, optional ones, entry points, extras."""
    pm = pluggy.PluginManager("ata")
    pm.add_hookspecs(hookspecs)
    if not BUILTIN_PLUGINS:
        raise MissionError("", None, "ata's built-in plugins are not registered (no entry "
                           f"points in the group {BUILTIN_GROUP!r}): install the package, "
                           "e.g. pip install -e .")
    for module in BUILTIN_PLUGINS:
        pm.register(importlib.import_module(module), name=module)
    wanted: list[str] = []
    for name in optional:
        if name not in OPTIONAL_PLUGINS:
            known = ", ".join(sorted(OPTIONAL_PLUGINS)) or "(none yet)"
            raise MissionError("--plugins", None, f"unknown optional plugin {name!r}; "
                               f"available: {known}")
        wanted += [*requires(name), name]
    for name in dict.fromkeys(wanted):
        module = OPTIONAL_PLUGINS[name]
        if pm.get_plugin(module) is None:
            pm.register(importlib.import_module(module), name=module)
    if entry_points:
        pm.load_setuptools_entrypoints(THIRD_PARTY_GROUP)
    for plugin in extra:
        pm.register(plugin)
    _check_pending(pm)
    if os.environ.get("ATA_TRACE_HOOKS"):
        pm.trace.root.setwriter(lambda text: sys.stderr.write(text))
        pm.enable_tracing()
    return pm


def _check_pending(pm: pluggy.PluginManager) -> None:
    """pm.check_pending(), with the known hooks and the closest name in the message."""
    try:
        pm.check_pending()
    except pluggy.PluginValidationError as exc:
        known = sorted(n for n in dir(hookspecs) if n.startswith("ata_"))
        bad = [name for name, caller in vars(pm.hook).items()
               if not caller.has_spec() and caller.get_hookimpls()]
        close = difflib.get_close_matches(bad[0], known, n=1) if bad else []
        hint = f"; did you mean {close[0]!r}?" if close else ""
        raise pluggy.PluginValidationError(exc.plugin, f"{exc}{hint} (hooks: "
                                           f"{', '.join(known)})") from None


def plugin_version(pm: pluggy.PluginManager, plugin: Any) -> str:
    """'dist version' of the package a plugin comes from ('ata x.y.z' for the built-ins)."""
    for p, dist in pm.list_plugin_distinfo():
        if p is plugin:
            return f"{dist.project_name} {dist.version}"
    module = getattr(plugin, "__name__", type(plugin).__module__)
    top = module.split(".")[0]
    try:
        return f"{top} {metadata.version(top)}"
    except metadata.PackageNotFoundError:
        from ata import __version__
        return f"{top} {__version__}" if top == "ata" else f"{top} (not installed)"


def collect_components(pm: pluggy.PluginManager) -> Register:
    """Ask every plugin for its components, remembering who registered what."""
    register = Register()
    # in start-up order (get_plugins() is a set): a clash names the later plugin, every run
    for name, plugin in pm.list_name_plugin():
        if plugin is None:      # blocked
            continue
        caller = pm.subset_hook_caller("ata_register_components",
                                       remove_plugins=[p for p in pm.get_plugins()
                                                       if p is not plugin])
        register._plugin = name
        register._dist = plugin_version(pm, plugin)
        caller(register=register)
    return register
