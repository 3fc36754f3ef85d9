"""Components named by reference, and the digests of every component's code.

A mission's ``[components]`` slot may name a class instead of a registered component, as
Gymnasium's ``entry_point`` strings do: ``"./my_policy.py:NearestCapable"`` (a Python file, its
path relative to the mission file) or ``"my_pkg.policies:NearestCapable"`` (a module Python can
import). The class keeps the contract of a registered component (docs/plugins.md): it is called
as ``factory(settings, mission)``, its ``Settings`` dataclass gives its keys, and its hooks are
marked with ``ata.hookimpl``. Its **name** is its ``name`` class attribute when that is a string,
else the class name: the resolved mission names it so, its settings table is named after it, and
the resolved mission's ``[references]`` table records where it came from and the SHA-256 of its
file. A file's code is loaded once per version of the file; the modules of its folder are
importable from it (its folder is appended to ``sys.path``) and are part of its code digest.

`code_digest` is the digest of the source files a component's code comes from (its plugin's
package or module, the factory's module; for a reference, its file and the modules of its folder
that it imports): the plan of a run records
it, so that results made with other code are never resumed as if they were current.
"""

from __future__ import annotations

import ast
import hashlib
import importlib
import importlib.machinery
import importlib.util
import inspect
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable

from ata.core.components import ComponentInfo, Components
from ata.core.errors import MissionError

TABLE = "references"
"""The resolved mission's table of components named by reference: NAME = {source, sha256}."""
_FILES: dict[tuple[str, str], Any] = {}      # (absolute path, sha256) -> the loaded module
_SOURCES: dict[tuple[str, int, int], str] = {}


def is_reference(value: Any) -> bool:
    """Whether a ``[components]`` value names a class (``PATH.py:Class``, ``module:Class``)."""
    return isinstance(value, str) and ":" in value


@dataclass(frozen=True)
class Reference:
    """A component named by reference: `source` is absolute (a file) or a module path."""

    name: str
    kind: str            # its kinds, comma-separated (a policy that also decides when)
    source: str          # "/abs/path/my_policy.py:NearestCapable" or "my_pkg.policies:Name"
    sha256: str          # of the file (a module's source file)

    def table(self) -> dict[str, str]:
        return {"source": self.source, "kind": self.kind, "sha256": self.sha256}


def _sha256_file(path: Path) -> str:
    stat = path.stat()
    key = (str(path), stat.st_mtime_ns, stat.st_size)
    if key not in _SOURCES:
        _SOURCES[key] = hashlib.sha256(path.read_bytes()).hexdigest()
    return _SOURCES[key]


def absolute(text: str, base: Path | None) -> str:
    """The reference with a file path made absolute (relative to `base`, the mission file's
    folder, else the current one); a module reference unchanged."""
    target, _, cls = text.rpartition(":")
    if not target.endswith(".py") and "/" not in target and "\\" not in target:
        return text
    path = Path(target).expanduser()
    if not path.is_absolute():
        # relative to the mission file; one given by --set on a mission elsewhere (a built-in
        # one) may be relative to the current folder
        found = [p for p in ((base or Path.cwd()) / path, Path.cwd() / path) if p.is_file()]
        path = found[0] if found else (base or Path.cwd()) / path
    return f"{path.resolve()}:{cls}"


def load(text: str, where: str, base: Path | None = None) -> tuple[Any, str, str]:
    """(the class, the absolute reference, the SHA-256 of its file) of a reference; a
    MissionError naming `where` when it cannot be loaded."""
    source = absolute(text, base)
    target, _, cls_name = source.rpartition(":")
    if not target or not cls_name.isidentifier():
        raise MissionError(where, None, f"{text!r} is not a reference: write PATH.py:Class "
                           "(a path relative to the mission file) or module:Class")
    if target.endswith(".py") or "/" in target:
        path = Path(target)
        if not path.is_file():
            raise MissionError(where, None, f"{text!r}: no such file {path}")
        digest = _sha256_file(path)
        module = _FILES.get((str(path), digest))
        if module is None:
            module = _load_file(path, digest, text, where)
    else:
        try:
            module = importlib.import_module(target)
        except Exception as exc:                     # noqa: BLE001 - named, not raised raw
            raise MissionError(where, None, f"{text!r}: module {target!r} cannot be imported: "
                               f"{type(exc).__name__}: {exc}") from None
        file = getattr(module, "__file__", None)
        digest = _sha256_file(Path(file)) if file else "unknown"
    factory = getattr(module, cls_name, None)
    if factory is None or not callable(factory):
        found = sorted(n for n, v in vars(module).items() if inspect.isclass(v)
                       and v.__module__ == module.__name__)
        raise MissionError(where, None, f"{text!r}: {target} defines no class {cls_name!r}; "
                           f"its classes: {', '.join(found) or '(none)'}")
    return factory, source, digest


def _load_file(path: Path, digest: str, text: str, where: str) -> Any:
    name = f"ata_file_{path.stem}_{digest[:12]}"
    folder = str(path.parent)
    if folder not in sys.path:        # its own folder's modules importable from it, as for a
        sys.path.append(folder)       # script; after every other folder: it shadows nothing
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module                     # dataclasses and pickle look it up there
    try:
        spec.loader.exec_module(module)
    except Exception as exc:                         # noqa: BLE001 - named, not raised raw
        del sys.modules[name]
        raise MissionError(where, None, f"{text!r}: {path} fails to load: "
                           f"{type(exc).__name__}: {exc}") from None
    _FILES[(str(path), digest)] = module
    return module


def component_name(factory: Any) -> str:
    """A referenced class's name: its ``name`` class attribute if a string, else its name."""
    name = getattr(factory, "name", None)
    return name if isinstance(name, str) and name else getattr(factory, "__name__", "component")


def _info(kind: str, name: str, factory: Any, source: str, digest: str) -> ComponentInfo:
    return ComponentInfo(kind, name, factory, plugin=f"reference {source}",
                         dist=f"{source.rpartition(':')[0]} sha256:{digest[:16]}")


def _register(registry: Components, ref: Reference, factory: Any) -> None:
    for (kind, name), info in registry.components.items():
        if name == ref.name and info.factory is not factory:
            raise MissionError("[components]", None, f"{ref.source!r} is named {ref.name!r}, "
                               f"which the {kind} of {info.plugin} already holds: give the "
                               "class another `name` attribute")
    for kind in ref.kind.split(","):
        registry.components[(kind, ref.name)] = _info(kind, ref.name, factory, ref.source,
                                                      ref.sha256)


def resolve(raw: dict[str, Any], registry: Components, source: str,
            slot_kinds: dict[str, str]) -> tuple[dict[str, Any], dict[str, Reference]]:
    """A raw mission with every reference in ``[components]`` replaced by its component's name
    (each registered into `registry`), and the references by name. A ``[references]`` table (a
    resolved mission's) gives names their source; a recorded sha256 must match the file now."""
    base = Path(source).resolve().parent if source and not source.startswith("<") else None
    given = raw.get(TABLE, {})
    if not isinstance(given, dict):
        raise MissionError(f"[{TABLE}]", None, "must be a table")
    slots = raw.get("components")
    if not isinstance(slots, dict):
        if given:
            raise MissionError(f"[{TABLE}]", None, "names no component of [components]")
        return raw, {}
    refs: dict[str, Reference] = {}
    out_slots = dict(slots)
    for slot, value in slots.items():
        kind = slot_kinds.get(slot)
        if kind is None:
            continue
        values = value if isinstance(value, list) else [value]
        names = []
        for v in values:
            text = v
            recorded = None
            if isinstance(v, str) and v in given:
                entry = given[v]
                text = entry.get("source") if isinstance(entry, dict) else entry
                recorded = entry.get("sha256") if isinstance(entry, dict) else None
                if not isinstance(text, str):
                    raise MissionError(f"[{TABLE}]", v, "needs source = 'PATH.py:Class'")
            if not is_reference(text):
                names.append(v)
                continue
            where = f"[components] key {slot!r}"
            factory, target, digest = load(text, where, base)
            if recorded and recorded != digest:
                raise MissionError(f"[{TABLE}]", v, f"{target.rpartition(':')[0]} has changed "
                                   f"since this mission was resolved (sha256 {recorded[:16]} "
                                   f"then, {digest[:16]} now)")
            name = component_name(factory)
            kinds = set(refs[name].kind.split(",")) if name in refs else set()
            ref = Reference(name, ",".join(sorted(kinds | {kind})), target, digest)
            _register(registry, ref, factory)
            refs[ref.name] = ref
            names.append(ref.name)
        out_slots[slot] = names if isinstance(value, list) else names[0]
    unused = [n for n in given if n not in refs]
    if unused:
        raise MissionError(f"[{TABLE}]", unused[0], "names no component of [components]")
    out = {k: v for k, v in raw.items() if k != TABLE}
    out["components"] = out_slots
    return out, refs


def restore(references: dict[str, Reference],
            registry: Components | None = None) -> dict[str, Any]:
    """Load the references of a mission received from another process: name -> factory, each
    registered into `registry` when given (a worker's fresh one). A file that changed since the
    mission was resolved is refused (its rows would mix two codes)."""
    factories = {}
    for name, ref in references.items():
        factory, _, digest = load(ref.source, f"[{TABLE}] key {name!r}")
        if digest != ref.sha256:
            raise MissionError(f"[{TABLE}]", name, f"{ref.source.rpartition(':')[0]} changed "
                               f"while the run was under way (sha256 {ref.sha256[:16]} when "
                               f"it started, {digest[:16]} now): run it again")
        if registry is not None:
            for kind in ref.kind.split(","):
                registry.components[(kind, name)] = _info(kind, name, factory, ref.source, digest)
        factories[name] = factory
    return factories


# -- the digest of a component's code -----------------------------------------------------------
_IMPORTS: dict[tuple[str, int, int], list[str]] = {}
_CLOSURES: dict[tuple, list[Path]] = {}     # the files of a component, by its root files' stamps


def _module_file(name: str) -> tuple[Path | None, bool]:
    """(the source file of a module, whether it is a package); (None, False) for a name that
    is no module (a class imported by name, say)."""
    module = sys.modules.get(name)
    file, package = getattr(module, "__file__", None), hasattr(module, "__path__")
    if module is None:
        spec = _find_spec(name)
        file = spec.origin if spec is not None and spec.has_location else None
        package = bool(spec is not None and spec.submodule_search_locations is not None)
    return (Path(file), package) if file and file.endswith(".py") else (None, False)


def _find_spec(name: str) -> Any:
    """The spec of module `name`, found without importing anything (``importlib.util.find_spec``
    of a dotted name imports its parent: a digest would import, say, torch along with the
    module a function imports it in)."""
    head, _, rest = name.partition(".")
    try:
        spec = importlib.util.find_spec(head)
        for part in rest.split(".") if rest else ():
            head = f"{head}.{part}"
            loaded = sys.modules.get(head)
            if loaded is not None:
                spec = getattr(loaded, "__spec__", None)
                continue
            paths = getattr(spec, "submodule_search_locations", None) if spec else None
            if not paths:
                return None
            spec = importlib.machinery.PathFinder.find_spec(head, list(paths))
    except (ImportError, ValueError, AttributeError):
        return None
    return spec


def _imported(path: Path, name: str, package: bool) -> list[str]:
    """The modules (and module.name candidates) a source file imports, absolute, wherever the
    import stands (a function's own included)."""
    stat = path.stat()
    key = (str(path), stat.st_mtime_ns, stat.st_size)
    if key not in _IMPORTS:
        here = name if package else name.rpartition(".")[0]
        found: list[str] = []
        try:
            tree = ast.parse(path.read_text(encoding="utf-8"))
        except (SyntaxError, UnicodeDecodeError):
            tree = None
        for node in ast.walk(tree) if tree is not None else ():
            if isinstance(node, ast.Import):
                found += [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom):
                base = node.module or ""
                if node.level:
                    parts = here.split(".")[:len(here.split(".")) - node.level + 1]
                    base = ".".join(parts + ([base] if base else []))
                found += [base] + [f"{base}.{a.name}" for a in node.names]
        _IMPORTS[key] = list(dict.fromkeys(n for n in found if n))
    return _IMPORTS[key]


def code_files(factory: Callable[..., Any], plugin: str | None = None) -> list[Path]:
    """The source files a component's code comes from: the module that defines its class (its
    file, for a component named by reference), the registering plugin's module or whole
    package, and every module of ata or of the component's own top-level package (for a
    component named by file, every module of the file's folder) that these import, directly or
    not (read from their import statements)."""
    module = getattr(factory, "__module__", None) or ""
    key = (module, plugin, tuple(_stamp(sys.modules.get(n)) for n in (module, plugin)))
    if key not in _CLOSURES:
        _CLOSURES[key] = _closure(module, plugin)
    return _CLOSURES[key]


def _stamp(module: Any) -> tuple[int, int]:
    file = getattr(module, "__file__", None)
    try:
        stat = Path(file).stat() if file else None
    except OSError:
        stat = None
    return (stat.st_mtime_ns, stat.st_size) if stat else (0, 0)


def _local(name: str, folder: Path | None) -> bool:
    """Whether the module `name` (its top-level module) is a file or package of `folder`."""
    if folder is None:
        return False
    path, _ = _module_file(name.split(".")[0])
    return path is not None and path.resolve().is_relative_to(folder)


def _closure(module: str, plugin: str | None) -> list[Path]:
    by_file = module.startswith("ata_file_")
    tops = {"ata"} | ({module.split(".")[0]} if not by_file else set())
    # a component named by file: the modules it imports from its own folder are its code too
    file = getattr(sys.modules.get(module), "__file__", None) if by_file else None
    folder = Path(file).resolve().parent if file else None
    todo = [n for n in (module, plugin) if n]
    seen: set[str] = set()
    files: set[Path] = set()
    while todo:
        name = todo.pop()
        if name in seen:
            continue
        seen.add(name)
        loaded = sys.modules.get(name)
        path, package = _module_file(name) if not name.startswith("ata_file_") else (
            Path(getattr(loaded, "__file__", "") or "."), False)
        if path is None or not path.is_file():
            continue
        files.add(path.resolve())
        if name == plugin and package:
            files |= {p.resolve() for p in path.parent.rglob("*.py")}
        todo += [n for n in _imported(path, name, package) if n not in seen
                 and (n.split(".")[0] in tops or _local(n, folder))]
    return sorted(files)


def code_digest(factory: Callable[..., Any], plugin: str | None = None) -> str:
    """The SHA-256 (first 16 hex digits) of the component's code files (`code_files`), each
    named by its file name and digested by its content."""
    h = hashlib.sha256()
    for path in code_files(factory, plugin):
        if path.is_file():
            h.update(f"{path.name}\0{_sha256_file(path)}\0".encode())
    return h.hexdigest()[:16]
