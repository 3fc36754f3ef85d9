"""`--isolate` with a method from another package: the host never imports the method's code.

Under `--isolate` the host (the process with the world and the root seed) loads ata's own
plugins and the third-party plugins *declared* (entry-point group ``ata.components``) to provide
a world component the mission names; nothing else of a third-party package is imported there,
not even to read a settings class. A decision component that ata's own plugins do not provide is
a *remote* component: a sandboxed process (`ata.runtime.decider`, op ``resolve``) loads every
plugin, validates the mission as a worker would, and answers each remote component's resolved
settings as plain values. The host then stands a `RemoteComponent` in its registry for each: its
settings (a `RemoteSettings`) are those values, recorded in the resolved mission and the plan
key as any component's are; building one raises (it is built in the decision process only).

A world component of a package that does not declare it is found by importing each installed
``ata`` entry point alone in a sandboxed process of its own (`_world_providers`); the one entry
point that provides it is then loaded in the host, as the world's code it is.

What the host takes from the sandboxed process is data, checked here: names it asked for, of the
kinds it asked for, values TOML can write. Which code the decision process may see (the folders
of the third-party packages and their distribution records) is found here from the installed
metadata and `importlib.util.find_spec` of a top-level name, which runs none of the package's
code.
"""

from __future__ import annotations

import hashlib
import importlib.util
import json
import math
import os
import re
from dataclasses import dataclass
from pathlib import Path
from importlib import metadata
from typing import Any

from ata.core import references as refs_mod
from ata.core.components import DECISION_SLOTS
from ata.core.errors import ContractError, MissionError
from ata.core.mission import SLOT_KINDS, TRAINER_SLOT
from ata.core.registry import (COMPONENTS_GROUP, THIRD_PARTY_GROUP, ComponentInfo, Register,
                               collect_components, declared_components, get_plugin_manager)


@dataclass(frozen=True)
class RemoteSettings:
    """The settings of a component that lives in the decision process: the values it resolved
    there (None: the component takes no settings), with what the host's registry needs to
    stand the component in again in a worker process."""

    kind: str            # its kinds, comma-separated (a class that fills two slots)
    name: str
    plugin: str
    dist: str
    values_json: str | None
    code: str = ""                          # the digest of its code, for the plan keys
    reference: tuple[tuple[str, str], ...] = ()   # the [references] entry of one named so
    binds: tuple[str, ...] = ()             # its own files the decision process is shown
    paths: tuple[str, ...] = ()             # and the folders put on its sys.path

    @property
    def kinds(self) -> list[str]:
        return self.kind.split(",")

    @property
    def values(self) -> dict[str, Any] | None:
        return None if self.values_json is None else json.loads(self.values_json)

    def as_dict(self) -> dict[str, Any]:
        """What the resolved mission writes for it (`ata.core.settings.settings_dict`)."""
        return self.values or {}


class _RemoteSettingsClass:
    """A remote component's ``Settings`` (a ``ata.core.settings.TableSettings``): it takes the
    table the decision process validated."""

    def __init__(self, settings: RemoteSettings):
        self.settings = settings

    def from_table(self, table: dict[str, Any] | None, where: str) -> RemoteSettings:
        return self.settings


class RemoteComponent:
    """Stands in the host's registry for a decision component built in the decision process."""

    def __init__(self, settings: RemoteSettings):
        self.remote = settings
        self.Settings = _RemoteSettingsClass(settings)
        self.__name__ = self.__qualname__ = f"RemoteComponent[{settings.name}]"
        self.__module__ = settings.plugin
        self.code = settings.code

    def __call__(self, *args: Any, **kwargs: Any) -> Any:
        raise ContractError(f"{self.remote.kind} {self.remote.name!r} runs in the sandboxed "
                            "decision process only (--isolate)")


def _third_party(value: str) -> bool:
    module = value.split(":")[0]
    return module != "ata" and not module.startswith("ata.")


def _entry_points() -> list[tuple[metadata.EntryPoint, Any]]:
    out = []
    for dist in metadata.distributions():
        for ep in dist.entry_points:
            if ep.group in (THIRD_PARTY_GROUP, COMPONENTS_GROUP) and _third_party(ep.value):
                out.append((ep, dist))
    return out


def code_locations() -> tuple[list[str], list[str]]:
    """(paths to show read-only, folders to put on sys.path) for every third-party plugin
    package, found without running any of it: its package folder (or module file) by
    `find_spec` of its top-level name, and its distribution record (which holds its entry
    points)."""
    binds, paths = [], []
    for ep, dist in _entry_points():
        for w in _folders(_top(ep.value)):
            binds.append(w)
            paths.append(os.path.dirname(w))
        record = getattr(dist, "_path", None)         # a PathDistribution's .dist-info folder
        if record is not None and os.path.isdir(str(record)):
            binds.append(os.path.realpath(str(record)))
            paths.append(os.path.dirname(os.path.realpath(str(record))))
    return list(dict.fromkeys(binds)), list(dict.fromkeys(paths))


def _names(raw: dict[str, Any]) -> list[tuple[str, str, str]]:
    """(slot, kind, name) of every component the raw mission's [components] names."""
    table = raw.get("components")
    table = table if isinstance(table, dict) else {}
    out = []
    for slot, kind in [*SLOT_KINDS.items(), TRAINER_SLOT]:
        value = table.get(slot)
        for name in value if isinstance(value, list) else [value]:
            if isinstance(name, str) and (slot, name) != (TRAINER_SLOT[0], "none"):
                out.append((slot, kind, name))
    return out


def _own_registry(optional: list[str], world: tuple[str, ...] = ()) -> Register:
    """The registry of ata's own plugins, the third-party plugins declared to provide a world
    component (loaded when named) and the entry points `world` of the ``ata`` group (those found
    to provide a world component the mission names): no other third-party plugin is loaded."""
    pm = get_plugin_manager(optional=optional, entry_points=False)
    for ep, dist in _entry_points():
        if ep.group == THIRD_PARTY_GROUP and ep.name in world and pm.get_plugin(ep.name) is None:
            pm.register(ep.load(), name=ep.name)
            pm.ata_entry_points[ep.name] = (f"{dist.metadata['name']} {dist.version}",
                                            f"{ep.name} = {ep.value}", THIRD_PARTY_GROUP)
    pm.check_pending()
    return collect_components(pm)


def _world_providers(needed: list[tuple[str, str, str]], probe: Any) -> tuple[str, ...]:
    """The ``ata``-group entry points that provide the world components `needed` ((slot, kind,
    name)), which nothing declares. Each third-party entry point is imported alone in a
    sandboxed process of its own (`probe`), which answers the components it registers: a
    package can then only speak for itself, and a world component two of them claim is refused
    as ambiguous."""
    claims: dict[tuple[str, str], list[str]] = {}
    for ep, _ in _entry_points():
        if ep.group != THIRD_PARTY_GROUP:
            continue
        answer = probe(ep.name)
        for item in answer.get("components", []) if isinstance(answer, dict) else []:
            if isinstance(item, list) and len(item) == 2:
                claims.setdefault((str(item[0]), str(item[1])), []).append(ep.name)
    chosen = []
    for slot, kind, name in needed:
        who = list(dict.fromkeys(claims.get((kind, name), [])))
        if len(who) != 1:
            why = "no installed package provides it" if not who else \
                f"packages {', '.join(who)} all say they provide it"
            raise MissionError("[components]", slot, f"{kind} {name!r}: {why}; under --isolate "
                               f"a package can declare it: entry point {kind}.{name} = "
                               f"\"MODULE\" in the group {COMPONENTS_GROUP!r} (docs/plugins.md)")
        chosen.append(who[0])
    return tuple(dict.fromkeys(chosen))


def isolated_registry(raw: dict[str, Any], optional: list[str], source: str,
                      resolve: Any, probe: Any) -> tuple[Register, dict[str, Any]]:
    """The host's registry for a mission run under --isolate (see the module's text), and the
    raw mission with each decision component named by reference renamed to its name.

    :param resolve: called with (raw mission without its seed, source, [(kind, name)], the files
        and sys.path folders of those named by reference) for the remote components; returns
        the sandboxed process's answer (`ata.runtime.decider`).
    :param probe: called with an ``ata``-group entry point's name; returns what a sandboxed
        process that imported it alone says it registers.
    """
    raw, refs = _references(raw, source)
    registry = _own_registry(optional)
    declared = declared_components()
    remote: list[tuple[str, str]] = []
    world: set[str] = set()
    undeclared = []
    for slot, kind, name in _names(raw):
        if name in refs:
            remote.append((kind, name))
            continue
        if (kind, name) in registry.components:
            continue
        module = declared.get((kind, name))
        if slot in DECISION_SLOTS or slot == TRAINER_SLOT[0]:
            if module is not None and not _third_party(module):
                continue                          # ata's own learned methods load lazily
            remote.append((kind, name))
        elif module is None:
            undeclared.append((slot, kind, name))
        elif _third_party(module):
            world.add(_top(module))
    if undeclared:
        eps = _world_providers(undeclared, probe)
        world |= {_top(_module_of(e)) for e in eps}
        registry = _own_registry(optional, eps)
    remote = list(dict.fromkeys(remote))
    if not remote:
        return registry, raw
    public = json.loads(json.dumps(raw, default=str))
    public.setdefault("mission", {})["seed"] = 0           # the root seed never leaves the host
    answer = resolve(public, source, remote, [b for r in refs.values() for b in r.binds],
                     [q for r in refs.values() for q in r.paths])
    names = _stand_in(registry, answer, remote, refs)
    raw = _renamed(raw, names)
    for kind, name in remote:
        if name in refs:
            continue
        package = _top(_module_of(registry.components[(kind, name)].plugin))
        if package in world:
            raise MissionError("[components]", None, f"--isolate cannot keep {kind} {name!r} "
                               f"apart from the world: its package {package!r} also provides "
                               "a world component of the mission, which runs in the world's "
                               "process")
    return registry, raw


def _top(module: str) -> str:
    return module.split(":")[0].split(".")[0]


def _module_of(plugin: str) -> str:
    """The module of a plugin named by its entry point's name (or a module already)."""
    for ep, _ in _entry_points():
        if plugin == ep.name:
            return ep.value
    return plugin


def _stand_in(registry: Register, answer: Any, remote: list[tuple[str, str]],
              refs: dict[str, "_Ref"]) -> dict[str, str]:
    """Check the decision process's answer and put a `RemoteComponent` in the registry for each
    remote component; the name of each one named by reference (reference -> name)."""
    items = answer.get("components") if isinstance(answer, dict) else None
    if not isinstance(items, list) or len(items) != len(remote):
        raise ContractError("the decision process answered the settings of other components "
                            "than it was asked for")
    names: dict[str, str] = {}
    made: dict[str, RemoteSettings] = {}
    for (kind, name), item in zip(remote, items):
        if not isinstance(item, dict) or (item.get("kind"), item.get("name")) != (kind, name):
            raise ContractError(f"the decision process did not resolve {kind} {name!r}")
        values = item.get("values")
        if values is not None and not (isinstance(values, dict) and _plain(values)):
            raise ContractError(f"the decision process gave settings of {name!r} that are not "
                                "plain values")
        values_json = None if values is None else json.dumps(values, sort_keys=True)
        ref = refs.get(name)
        if ref is None:
            plugin = str(item.get("plugin", "?"))[:200]
            settings = RemoteSettings(kind, name, plugin, _dist_of(plugin), values_json,
                                      code=_package_digest(_module_of(plugin)))
        else:
            resolved = item.get("resolved")
            if not (isinstance(resolved, str) and NAME.fullmatch(resolved)):
                raise ContractError(f"the decision process named {name!r} {resolved!r}")
            taken = [k for k in kind.split(",") if (k, resolved) in registry.components
                     or (k, resolved) in declared_components()]
            if taken:
                raise MissionError("[components]", None, f"{ref.source} names its component "
                                   f"{resolved!r}, the name of a {taken[0]} ata already has: a "
                                   "method from a file may not take another's name (give its "
                                   "class another name, or another `name` attribute)")
            if item.get("sha256") != ref.sha256:
                raise MissionError("[components]", None, f"{ref.path} changed while it was "
                                   "being loaded: run it again")
            names[name] = resolved
            before = made.get(resolved)
            kinds = ",".join(sorted({kind, *(before.kinds if before else [])}))
            settings = RemoteSettings(
                kinds, resolved, f"reference {ref.source}",
                f"{ref.path} sha256:{ref.sha256[:16]}", values_json, code=ref.sha256,
                reference=(("source", ref.source), ("kind", kinds), ("sha256", ref.sha256)),
                binds=ref.binds, paths=ref.paths)
            made[resolved] = settings
        for k in settings.kinds:
            registry.components[(k, settings.name)] = ComponentInfo(
                k, settings.name, RemoteComponent(settings), settings.plugin, settings.dist)
    return names


NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_.\-]{0,79}")
"""What a component's name may be (a class's name, or its ``name`` attribute)."""


@dataclass(frozen=True)
class _Ref:
    """A decision component named by reference, found without running it."""

    source: str                  # absolute: "/abs/my_policy.py:Class" or "pkg.mod:Class"
    path: str                    # its file, or its package's folder
    sha256: str                  # of the file (or of the package's files)
    binds: tuple[str, ...]
    paths: tuple[str, ...]


def _references(raw: dict[str, Any], source: str) -> tuple[dict[str, Any], dict[str, _Ref]]:
    """The raw mission with every reference in a decision slot made absolute (a name that a
    ``[references]`` table gives, replaced by its source, its recorded sha256 checked), and
    those references: found without running them, for the sandbox to load."""
    base = Path(source).resolve().parent if source and not source.startswith("<") else None
    given = raw.get(refs_mod.TABLE) or {}
    given = given if isinstance(given, dict) else {}
    table = raw.get("components") if isinstance(raw.get("components"), dict) else {}
    slots, used, refs = dict(table), set(), {}
    for slot in DECISION_SLOTS:
        value = slots.get(slot)
        out = []
        for v in value if isinstance(value, list) else [value]:
            text, recorded = v, None
            if isinstance(v, str) and isinstance(given.get(v), dict):
                text, recorded = given[v].get("source"), given[v].get("sha256")
                used.add(v)
            if isinstance(text, str) and refs_mod.is_reference(text):
                ref = _locate(refs_mod.absolute(text, base), f"[components] key {slot!r}")
                if recorded and recorded != ref.sha256:
                    raise MissionError(f"[{refs_mod.TABLE}]", v, f"{ref.path} has changed "
                                       f"since this mission was resolved (sha256 "
                                       f"{recorded[:16]} then, {ref.sha256[:16]} now)")
                refs[ref.source] = ref
                text = ref.source
            out.append(text)
        if value is not None:
            slots[slot] = out if isinstance(value, list) else out[0]
    raw = {**raw, "components": slots}
    rest = {k: v for k, v in given.items() if k not in used}
    raw.pop(refs_mod.TABLE, None)
    if rest:
        raw[refs_mod.TABLE] = rest
    return raw, refs


def _locate(source: str, where: str) -> _Ref:
    target = source.rpartition(":")[0]
    if target.endswith(".py") or "/" in target:
        path = Path(target)
        if not path.is_file():
            raise MissionError(where, None, f"{source!r}: no such file {path}")
        real = os.path.realpath(path)
        return _Ref(source, str(path), hashlib.sha256(path.read_bytes()).hexdigest(), (real,),
                    ())
    folders = _folders(target.split(".")[0])
    if not folders:
        raise MissionError(where, None, f"{source!r}: no module {target.split('.')[0]!r} "
                           "can be found")
    return _Ref(source, folders[0], _digest_files(folders), tuple(folders),
                tuple(dict.fromkeys(os.path.dirname(f) for f in folders)))


def _folders(top: str) -> list[str]:
    """A top-level module's folder (or file), by `find_spec`, which runs none of it."""
    try:
        spec = importlib.util.find_spec(top)
    except (ImportError, ValueError):
        return []
    if spec is None:
        return []
    where = list(spec.submodule_search_locations or []) or ([spec.origin] if spec.origin else [])
    return [os.path.realpath(w) for w in where if os.path.exists(w)]


def _digest_files(folders: list[str]) -> str:
    h = hashlib.sha256()
    for folder in folders:
        files = [Path(folder)] if os.path.isfile(folder) else sorted(Path(folder).rglob("*.py"))
        for f in files:
            h.update(str(f.relative_to(folder) if f != Path(folder) else f.name).encode())
            h.update(hashlib.sha256(f.read_bytes()).digest())
    return h.hexdigest()


def _package_digest(module: str) -> str:
    folders = _folders(_top(module))
    return "sha256:" + _digest_files(folders)[:16] if folders else "unknown"


def _renamed(raw: dict[str, Any], names: dict[str, str]) -> dict[str, Any]:
    slots = dict(raw.get("components") or {})
    for slot in DECISION_SLOTS:
        value = slots.get(slot)
        if isinstance(value, list):
            slots[slot] = [names.get(v, v) for v in value]
        elif isinstance(value, str):
            slots[slot] = names.get(value, value)
    return {**raw, "components": slots}


def _plain(value: Any, depth: int = 0) -> bool:
    if depth > 16:
        return False
    if isinstance(value, dict):
        return all(isinstance(k, str) and _plain(v, depth + 1) for k, v in value.items())
    if isinstance(value, list):
        return all(_plain(v, depth + 1) for v in value)
    if isinstance(value, float):
        return math.isfinite(value)
    return isinstance(value, (str, int, bool))


def _dist_of(plugin: str) -> str:
    """The distribution that declares `plugin` (an entry point's name or module), from the
    installed metadata: not from what the decision process says."""
    for ep, dist in _entry_points():
        if plugin in (ep.name, ep.value):
            return f"{dist.metadata['name']} {dist.version}"
    return "?"


def worker_registry(mission: Any, probe: Any) -> Register:
    """A worker's registry for a mission run under --isolate: ata's own plugins, the world's
    third-party plugins found as the host found them (`probe`: see `isolated_registry`), and a
    `RemoteComponent` for each remote component; no other third-party code is imported."""
    optional = list(mission.settings.plugins)
    registry = _own_registry(optional)
    declared = declared_components()
    undeclared = []
    for slot, kind in SLOT_KINDS.items():
        if slot in DECISION_SLOTS:
            continue
        value = getattr(mission.slots, slot)
        for name in value if isinstance(value, list) else [value]:
            if (kind, name) not in registry.components and (kind, name) not in declared:
                undeclared.append((slot, kind, name))
    if undeclared:
        registry = _own_registry(optional, _world_providers(undeclared, probe))
    for s in mission.component_settings.values():
        if isinstance(s, RemoteSettings):
            for k in s.kinds:
                registry.components[(k, s.name)] = ComponentInfo(k, s.name, RemoteComponent(s),
                                                                 s.plugin, s.dist)
    return registry
