"""Plugin manager factory and the registry of components that plugins contribute by name.

Start-up order, fixed and readable: hook specs, built-in plugins, optional plugins named by the
user, entry points of the ``ata`` group, then ``check_pending()`` so that a misspelt hook name
fails here rather than being ignored. Later, a mission that names a component no loaded plugin
registers loads the plugin declared to provide it (lazy registration, ``ata.components``).

A third-party plugin that cannot load (its module fails to import, its registration hook
raises, or it registers a name another plugin holds) is left out and reported, as stevedore's
load-failure callback does: one line names the package, the entry point and why
(`BrokenPlugin`), every other command keeps working, and a mission naming one of its
components fails with that line.
"""

from __future__ import annotations

import difflib
import importlib
import os
import sys
import weakref
from dataclasses import dataclass, field
from importlib import metadata
from typing import Any, Callable, Iterable

import pluggy

from ata.core import hookspecs
from ata.core.components import KINDS, ComponentInfo
from ata.core.errors import MissionError


BUILTIN_GROUP = "ata.builtin"
OPTIONAL_GROUP = "ata.optional"
COMPONENTS_GROUP = "ata.components"
THIRD_PARTY_GROUP = "ata"
"""Entry-point groups: the default tier (always loaded), the optional tier (loaded when named:
the torch-based learned methods), the components each lazily loaded plugin provides (entry point
``KIND.NAME = "plugin.module"``: a mission naming the component loads the module, as Gymnasium's
registry imports an environment's "module:Class" on first use), and third-party packages (always
loaded). The core knows no plugin: ata's own are declared in its pyproject.toml like any other
package's."""


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


def _declarations() -> dict[tuple[str, str], metadata.EntryPoint]:
    """(kind, name) -> the ``ata.components`` entry point declaring it (the first, if two
    packages declare one name: loading both would fail as a clash anyway)."""
    out: dict[tuple[str, str], metadata.EntryPoint] = {}
    for ep in metadata.entry_points(group=COMPONENTS_GROUP):
        kind, _, name = ep.name.partition(".")
        out.setdefault((kind, name), ep)
    return out


def declared_components() -> dict[tuple[str, str], str]:
    """(kind, name) -> plugin module of every component an installed package declares in the
    ``ata.components`` group. Read at each call: it is consulted only when a name is unknown."""
    return {key: ep.value for key, ep in _declarations().items()}


def plugin_label(module: str) -> str:
    """How `[mission] plugins` names a lazily loaded plugin: its optional name, else its
    module."""
    return next((n for n, m in OPTIONAL_PLUGINS.items() if m == module), module)


def providers(names: Iterable[str]) -> list[str]:
    """The plugins declared to provide components of these names, by `plugin_label`, in order."""
    declared = declared_components()
    out = [plugin_label(declared[k]) for name in names for k in declared if k[1] == name]
    return list(dict.fromkeys(out))


@dataclass(frozen=True)
class BrokenPlugin:
    """A third-party plugin left out because it failed to load."""

    package: str         # "dist version" of the distribution that declares it
    entry_point: str     # "NAME = module" as its entry_points.txt writes it
    group: str
    reason: str          # "ExceptionType: message"
    components: tuple[tuple[str, str], ...] = field(default=())
    """(kind, name) it declares or had registered, for the refusal of a mission naming one."""

    def line(self) -> str:
        return (f"plugin package {self.package}, entry point {self.entry_point} (group "
                f"{self.group!r}) failed to load and is left out: {self.reason}")


def _reason(exc: BaseException) -> str:
    text = " ".join(str(exc).split())
    if len(text) > 300:          # a message can hold a whole file; the line stays one line
        text = text[:300] + "..."
    return f"{type(exc).__name__}: {text}" if text else type(exc).__name__


_reported: "weakref.WeakKeyDictionary[Any, set[str]]" = weakref.WeakKeyDictionary()


def _default_on_failure(broken: BrokenPlugin) -> None:
    sys.stderr.write(f"warning: {broken.line()}\n")


on_load_failure: Callable[[BrokenPlugin], None] = _default_on_failure
"""Called with each plugin left out (stevedore's on_load_failure_callback), once per line and
stderr: once per command, as each `ata` command is one process (and each in-process test
invocation gets a stderr of its own); by default one warning line on stderr."""


def reset_reports() -> None:
    """Report each broken plugin again."""
    _reported.clear()


def _broken(pm: pluggy.PluginManager, broken: BrokenPlugin) -> None:
    """Record a plugin left out on `pm` and report it, once per process and line."""
    known = getattr(pm, "ata_broken", None)
    if known is None:
        known = pm.ata_broken = []
    known.append(broken)
    import multiprocessing   # on use: a plugin left out is rare, and its import is slow
    # a worker process rebuilds the registry: the command that started it has reported it
    seen = _reported.setdefault(sys.stderr, set())
    if broken.line() not in seen and multiprocessing.parent_process() is None:
        seen.add(broken.line())
        on_load_failure(broken)


def broken_plugins(pm: pluggy.PluginManager) -> list[BrokenPlugin]:
    """The third-party plugins `pm` left out, in the order they failed."""
    return list(getattr(pm, "ata_broken", []))


def _dist_label(ep: metadata.EntryPoint) -> str:
    return f"{ep.dist.name} {ep.dist.version}" if ep.dist else "(unknown package)"


def _one_table(a: Callable[..., Any], b: Callable[..., Any]) -> bool:
    """Whether two factories are one component's: the same, or reading one Settings class."""
    settings = getattr(a, "Settings", None)
    return a is b or (settings is not None and settings is getattr(b, "Settings", None))


class Register:
    """The callable that ``ata_register_components`` receives; collects components by name."""

    def __init__(self, pm: pluggy.PluginManager | None = None) -> None:
        self.components: dict[tuple[str, str], ComponentInfo] = {}
        self.loaded: list[str] = []
        """The optional plugins (by name) loaded on demand because a mission named one of
        their components, in load order: the resolved mission records them. A plugin declared
        only in ``ata.components`` has no name to record; it loads on demand again."""
        self._pm = pm
        self._plugin = "?"
        self._dist = "?"

    def __call__(self, kind: str, name: str, factory: Callable[..., Any]) -> None:
        if hasattr(self, "_attempted"):
            self._attempted.append((kind, name))
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

    @property
    def pm(self) -> pluggy.PluginManager | None:
        """The plugin manager the components came from (None for a bare registry)."""
        return self._pm

    @property
    def broken(self) -> list["BrokenPlugin"]:
        """The third-party plugins left out because they failed to load (`broken_plugins`)."""
        return broken_plugins(self._pm) if self._pm is not None else []

    def get(self, kind: str, name: str, where: str) -> ComponentInfo:
        """The component `name` of `kind`; an unknown one loads the plugin declared to provide
        it (under any kind: a name in the wrong slot is then named as what it is)."""
        if (kind, name) not in self.components:
            self.load_declared(name)
        try:
            return self.components[(kind, name)]
        except KeyError:
            broken = [b for b in broken_plugins(self._pm) if any(n == name for _, n in
                                                               b.components)] if self._pm else []
            if broken:
                raise MissionError(where, None, f"{kind} {name!r} comes from a plugin that "
                                   f"could not be loaded: {broken[0].line()}") from None
            declared = declared_components()
            if (kind, name) in declared and self._pm is not None and \
                    self._pm.get_plugin(declared[(kind, name)]) is not None:
                ep = _declarations()[(kind, name)]
                raise MissionError(where, None, f"{kind} {name!r} is declared by package "
                                   f"{_dist_label(ep)} (entry point {ep.name} = {ep.value}, "
                                   f"group {COMPONENTS_GROUP!r}), but its plugin {ep.value} "
                                   f"registered no {kind} of that name: a bug in that package"
                                   ) from None
            # what a mission can name: registered, or declared by a plugin not loaded yet
            known = sorted(set(self.names(kind)) | {
                n for (k, n), m in declared.items()
                if k == kind and (self._pm is None or self._pm.get_plugin(m) is None)})
            hint = ""
            close = difflib.get_close_matches(name, [n for n in known if n != name], n=1)
            if (kind, name) in declared:    # declared, but this registry loads no plugin
                raise MissionError(where, None, f"{kind} {name!r} is declared by the plugin "
                                   f"{declared[(kind, name)]}, which this registry does not "
                                   "load (a registry made without a plugin manager loads "
                                   "none: build it with collect_components(get_plugin_manager()))") from None
            if close:
                hint = f"; did you mean {close[0]!r}?"
            if name in OPTIONAL_PLUGINS:
                gives = sorted(n for (k, n), m in declared.items() if m == OPTIONAL_PLUGINS[name])
                hint = (f"; {name!r} is an optional plugin, not a component: it provides "
                        f"{', '.join(gives) or 'no declared component'}")
            other = [k for k, n in self.components if n == name]
            if other:
                hint = (f"; {name!r} is registered as a {other[0]}, which goes in another "
                        "[components] slot")
            lost = [b for b in broken_plugins(self._pm) if not b.components] if self._pm else []
            if lost:             # their components are unknown: one of them may be this one
                hint += (f"; a plugin that may provide it could not be loaded: "
                         f"{lost[0].line()}")
            raise MissionError(where, None, f"unknown {kind} {name!r}; registered: "
                               f"{', '.join(known) or '(none)'} (see: ata plugins){hint}") \
                from None

    def load_declared(self, name: str | None = None) -> None:
        """Load the not yet loaded plugins declared to provide components named `name` (every
        declared plugin when None) into this registry's plugin manager, and register their
        components here. A registry made without a plugin manager loads nothing."""
        if self._pm is None:
            return
        wanted = [ep for (_, n), ep in _declarations().items() if name in (None, n)]
        # the declaring package, for plugins.toml (a module loaded here has no distinfo in pm)
        dists = {ep.value: f"{ep.dist.name} {ep.dist.version}" for ep in wanted if ep.dist}
        before = {n for n, _ in self._pm.list_name_plugin()}
        entries = getattr(self._pm, "ata_entry_points", None)
        if entries is None:
            entries = self._pm.ata_entry_points = {}
        failed = {b.entry_point for b in broken_plugins(self._pm)}
        for module in dict.fromkeys(ep.value for ep in wanted):
            eps = [ep for ep in wanted if ep.value == module]
            label = f"{eps[0].name} = {module}"
            if label in failed:
                continue
            if module.split(".")[0] == "ata":
                _add_optional(self._pm, module)        # ata's own: a failure is a bug, shown
                continue
            try:
                _add_optional(self._pm, module)
            except MissionError:
                raise
            except Exception as exc:                   # noqa: BLE001 - any failure leaves it out
                declared = tuple((k, n) for (k, n), ep in _declarations().items()
                                 if ep.value == module)
                _broken(self._pm, BrokenPlugin(_dist_label(eps[0]), label, COMPONENTS_GROUP,
                                               _reason(exc), declared))
                continue
            entries[module] = (_dist_label(eps[0]), label, COMPONENTS_GROUP)
        added = [(n, p) for n, p in self._pm.list_name_plugin() if n not in before]
        if not added:
            return
        _check_pending(self._pm)
        for plugin_name, plugin in added:
            if self._collect(plugin_name, plugin, dists.get(plugin_name)) and \
                    plugin_label(plugin_name) in OPTIONAL_PLUGINS:
                self.loaded.append(plugin_label(plugin_name))

    def _collect(self, plugin_name: str, plugin: Any, dist: str | None = None) -> bool:
        """Ask one plugin for its components, remembering who registered them (and from which
        distribution: `dist`, else `plugin_version`). A plugin loaded from an entry point whose
        registration fails is left out whole (its components and its hooks) and reported;
        False then. Any other plugin's failure is raised: it is ata's, or a test's, bug."""
        caller = self._pm.subset_hook_caller("ata_register_components",
                                             remove_plugins=[p for p in self._pm.get_plugins()
                                                             if p is not plugin])
        self._plugin = plugin_name
        self._dist = dist or plugin_version(self._pm, plugin)
        entry = getattr(self._pm, "ata_entry_points", {}).get(plugin_name)
        if entry is None:
            caller(register=self)
            return True
        before = dict(self.components)
        self._attempted: list[tuple[str, str]] = []
        try:
            caller(register=self)
        except Exception as exc:                       # noqa: BLE001 - any failure leaves it out
            self.components = before
            self._pm.unregister(plugin)                # its hooks must not run either
            package, label, group = entry
            _broken(self._pm, BrokenPlugin(package, label, group, _reason(exc),
                                           tuple(dict.fromkeys(self._attempted))))
            return False
        return True


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
    for name in optional:
        if name not in OPTIONAL_PLUGINS:
            known = ", ".join(sorted(OPTIONAL_PLUGINS)) or "(none yet)"
            raise MissionError("--plugins", None, f"unknown optional plugin {name!r}; "
                               f"available: {known}")
        _add_optional(pm, OPTIONAL_PLUGINS[name])
    pm.ata_broken = []
    pm.ata_entry_points = {}
    if entry_points:
        _load_third_party(pm)
    for plugin in extra:
        pm.register(plugin)
    _check_pending(pm)
    if os.environ.get("ATA_TRACE_HOOKS"):
        pm.trace.root.setwriter(lambda text: sys.stderr.write(text))
        pm.enable_tracing()
    return pm


def _load_third_party(pm: pluggy.PluginManager) -> None:
    """Register the entry points of the ``ata`` group (as pluggy's load_setuptools_entrypoints
    does); one that fails to import or register is left out and reported, not raised: one
    broken package must not stop every command."""
    seen: set[str] = set()
    for dist in list(metadata.distributions()):
        for ep in dist.entry_points:
            if ep.group != THIRD_PARTY_GROUP or ep.name in seen or pm.get_plugin(ep.name) \
                    or pm.is_blocked(ep.name):
                continue
            seen.add(ep.name)
            package = f"{dist.metadata['name']} {dist.version}"
            label = f"{ep.name} = {ep.value}"
            try:
                plugin = ep.load()
                pm.register(plugin, name=ep.name)
            except pluggy.PluginValidationError:
                raise                                  # a misspelt hook: fails at start-up
            except Exception as exc:                   # noqa: BLE001 - any failure leaves it out
                _broken(pm, BrokenPlugin(package, label, THIRD_PARTY_GROUP, _reason(exc)))
                continue
            pm.ata_entry_points[ep.name] = (package, label, THIRD_PARTY_GROUP)


def _add_optional(pm: pluggy.PluginManager, module: str) -> None:
    """Register an optional or declared plugin module, after the optional plugins it requires
    (its ``ATA_REQUIRES``); one already there is left alone."""
    if pm.get_plugin(module) is not None:
        return
    plugin = importlib.import_module(module)
    for name in getattr(plugin, "ATA_REQUIRES", ()):
        if name not in OPTIONAL_PLUGINS:
            raise MissionError("", None, f"plugin {module} requires the optional plugin {name!r}, "
                               f"which is not installed; available: "
                               f"{', '.join(sorted(OPTIONAL_PLUGINS)) or '(none)'}")
        _add_optional(pm, OPTIONAL_PLUGINS[name])
    pm.register(plugin, name=module)


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
    entry = getattr(pm, "ata_entry_points", {}).get(pm.get_name(plugin) or "")
    if entry is not None:
        return entry[0]
    for p, dist in pm.list_plugin_distinfo():
        if p is plugin:
            return f"{dist.project_name} {dist.version}"
    module = getattr(plugin, "__name__", type(plugin).__module__)
    top = module.split(".")[0]
    try:
        return f"{top} {metadata.version(top)}"
    except metadata.PackageNotFoundError:
        from ata import __version__   # on use: ata's package imports this module
        return f"{top} {__version__}" if top == "ata" else f"{top} (not installed)"


def collect_components(pm: pluggy.PluginManager, *, declared: bool = False) -> Register:
    """Ask every plugin for its components, remembering who registered what. The registry
    loads a declared plugin when asked for a component it lacks; `declared` loads them all now
    (to list every component a mission can name)."""
    register = Register(pm)
    # in start-up order (get_plugins() is a set): a clash names the later plugin, every run
    for name, plugin in pm.list_name_plugin():
        if plugin is not None:      # None: blocked
            register._collect(name, plugin)
    if declared:
        register.load_declared()
    return register
