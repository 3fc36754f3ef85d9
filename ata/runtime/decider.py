"""The sandboxed decision process of `--isolate`: it builds and runs a method's components.

It builds a mission's decision components itself and answers the host's decision calls, one
request per phase and batch.

Run as ``python -m ata.runtime.decider`` inside the sandbox (`ata.runtime.sandbox`), its stdin
and stdout the channel (`ata.runtime.frames`): pickled requests in, safe frames out. It gets the
public mission (no seed), builds the components of the decision slots with a plugin manager of
its own, as the kernel would (one instance per name, the same hook order and slot checks), and
draws their numbers from the decision generator keys the host sends. It never sees the world:
only what a `DecisionContext` holds crosses the channel.
"""

from __future__ import annotations

import copy
import importlib
from importlib import metadata
import os
import pickle
import shutil
import sys
import time
import traceback
from types import MappingProxyType, SimpleNamespace
from typing import Any

import numpy as np
import pluggy

from ata.core import hookspecs
from ata.core.channel import read_only
from ata.core.components import DECISION_SLOTS
from ata.core.errors import ContractError, MissionError
from ata.core.kernel import REFERENCE_HOOK, build_component, is_reference, refuse_world_hooks
from ata.core.mission import SLOT_HOOKS, SLOT_KINDS, Mission, validate
from ata.core.registry import collect_components, get_plugin_manager
from ata.core.rng import StreamRNG
from ata.core.settings import settings_dict
from ata.core.state import Allocation, DecisionContext, DecisionView, EpisodeOutcome
from ata.runtime.frames import child_recv, child_send
from ata.runtime.messages import ALLOCATION, OPERATIONS, SLOT_OPERATIONS, Op


def _names(value: str | list[str]) -> list[str]:
    return value if isinstance(value, list) else [value]


def _frozen(value: Any) -> Any:
    """What the kernel hands a decision-maker: a read-only copy (an array, or a table's
    `frozen`), so that a component behaves here as it does in the host's process."""
    if value is None:
        return None
    if isinstance(value, np.ndarray):
        return read_only(value)
    return value.frozen() if hasattr(value, "frozen") else value


def plugins(mission: Mission, modules: list[str], only: bool) -> pluggy.PluginManager:
    """The plugin manager the components are built from. With `only`, just the plugin modules
    that register the method's components (the host names them): the world's plugins and
    their imports (scipy's, for the MILP baseline) would cost this process's start for
    nothing. Else every plugin a worker process would load, and the modules named."""
    if only:
        pm = pluggy.PluginManager("ata")
        pm.add_hookspecs(hookspecs)
    else:
        pm = get_plugin_manager(optional=mission.settings.plugins)
    for name in modules:             # a method's plugin that no entry point declares
        module = importlib.import_module(name)
        if pm.get_plugin(name) is None and not pm.is_registered(module):
            pm.register(module, name=name)
    pm.check_pending()
    return pm


class Decider:
    """The decision components of one batch and what they have been shown so far."""

    def __init__(self, mission: Mission, modules: list[str], only: bool):
        registry = collect_components(plugins(mission, modules, only))
        self.mission = mission = realize(mission, registry)
        built: dict[str, Any] = {}
        ordered: list[tuple[str, Any]] = []
        for slot in DECISION_SLOTS:
            for name in _names(getattr(mission.slots, slot)):
                if name not in built:
                    built[name] = build_component(registry, mission, SLOT_KINDS[slot], name)
                ordered.append((f"{slot}:{name}", built[name]))
        # the kernel's registration: once per instance, reversed (pluggy calls the last first)
        self.pm = pluggy.PluginManager("ata")
        self.pm.add_hookspecs(hookspecs)
        unique = [(n, c) for i, (n, c) in enumerate(ordered)
                  if not any(c is other for _, other in ordered[:i])]
        for plugin_name, component in reversed(unique):
            self.pm.register(component, name=plugin_name)
        self.pm.check_pending()
        self._refuse(unique)
        everyone = [c for _, c in ordered]
        self.callers = {}
        for slot, hook_name in SLOT_HOOKS.items():
            name = _names(getattr(mission.slots, slot))[0]
            component = built[name]
            impls = [i.plugin for i in getattr(self.pm.hook, hook_name).get_hookimpls()]
            if not any(p is component for p in impls):
                raise MissionError("[components]", slot, f"component {name!r} cannot fill this "
                                   f"slot: it implements no {hook_name}")
            self.callers[slot] = self.pm.subset_hook_caller(
                hook_name, remove_plugins=[c for c in everyone if c is not component])
        names = {n for slot in DECISION_SLOTS for n in _names(getattr(mission.slots, slot))}
        self.settings = MappingProxyType(
            {n: copy.deepcopy(mission.component_settings.get(n)) for n in sorted(names)})
        self.sizes, self.clock = mission.sizes, mission.clock
        self.rng: StreamRNG | None = None
        self.channel = None
        self.inherent = None
        self.observed = None
        self.recon: dict[str, np.ndarray] = {}
        self.recon_epoch = -1

    def _refuse(self, unique: list[tuple[str, Any]]) -> None:
        """The kernel's refusals, for the components the host's kernel never sees."""
        refuse_world_hooks(self.pm, unique)
        impls = [i.plugin for i in getattr(self.pm.hook, REFERENCE_HOOK).get_hookimpls()]
        for name, component in unique:
            if any(p is component for p in impls) or is_reference(component):
                raise ContractError(f"{name}: a reference reads the true state; --isolate "
                                    "runs methods, which never do")

    # -- requests --------------------------------------------------------------------------------
    def take(self, req: dict[str, Any]) -> None:
        """Keep what a request brings the first time it is sent: the batch's decision keys, the
        published constants, I, this epoch's observed S."""
        if "keys" in req:
            self.rng = StreamRNG(req["keys"])
            self.channel = req["channel"]
            self.inherent = _frozen(req["inherent"])
        if "observed" in req:
            self.observed = _frozen(req["observed"])
        torch = sys.modules.get("torch")
        if torch is not None and torch.get_num_threads() != 1:
            torch.set_num_threads(1)     # as a unit in the host runs: one reduction order

    def context(self, req: dict[str, Any]) -> DecisionContext:
        recon = self.recon if self.recon_epoch == req["epoch"] else {}
        return DecisionContext(epoch=req["epoch"], time=req["time"], sizes=self.sizes,
                               clock=self.clock, inherent=self.inherent, observed=self.observed,
                               reconstructed={k: _frozen(v) for k, v in recon.items()},
                               previous=_frozen(req["allocation"]),
                               reallocatable=_frozen(req["reallocatable"]), rng=self.rng,
                               settings=self.settings, channel=self.channel)

    HANDLERS = {Op.RECONSTRUCT: "_reconstruct", Op.TRAINED_ON: "_trained_on",
                Op.EPISODE_SCORED: "_episode_scored",
                **{op: "_decide" for slot, op in SLOT_OPERATIONS.items()
                   if slot != "reconstructors"}}
    """The method that answers each decision operation: a decision slot's by `_decide`, from
    its declared `Operation`."""

    def handle(self, req: dict[str, Any]) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
        """Answer one decision operation (`ata.runtime.messages`): a header and named arrays."""
        self.take(req)
        name = self.HANDLERS.get(req["op"])
        if name is None:
            raise ValueError(f"unknown request {req['op']!r}")
        return getattr(self, name)(req)

    def _reconstruct(self, req: dict[str, Any]) -> tuple[dict, dict[str, np.ndarray]]:
        view = DecisionView(SimpleNamespace(
            batch_size=self.rng.batch_size, sizes=self.sizes, clock=self.clock,
            epoch=req["epoch"], now=req["time"], allocation=req["allocation"],
            channel=self.channel), self.rng)
        recon: dict[str, np.ndarray] = {}
        self.pm.hook.ata_reconstruct(sim=view, obs=self.observed, inherent=self.inherent,
                                     out=recon)
        self.recon, self.recon_epoch = recon, req["epoch"]
        return {}, {k: np.asarray(v) for k, v in recon.items()}

    def _decide(self, req: dict[str, Any]) -> tuple[dict, dict[str, np.ndarray]]:
        """A decision slot's call, as its `Operation` declares it: the slot's hook on the
        context and the request's `hook_args`; its answer an Allocation's arrays or a (B,)
        bool array."""
        operation = OPERATIONS[req["op"]]
        slot = operation.slot
        out = self.callers[slot](ctx=self.context(req),
                                 **{k: req[k] for k in operation.hook_args})
        if operation.arrays == ALLOCATION:
            if not isinstance(out, Allocation):
                raise ContractError(f"{slot} policy returned {type(out).__name__}, not an "
                                    "Allocation")
            return {}, {f: np.asarray(getattr(out, f)) for f in ALLOCATION}
        return {}, {operation.arrays[0]: np.asarray(out, dtype=bool)}

    def _trained_on(self, req: dict[str, Any]) -> tuple[dict, dict[str, np.ndarray]]:
        ranges = [[[int(x) for x in r] for r in (found or [])]
                  for found in self.pm.hook.ata_trained_on()]
        return {"ranges": ranges}, {}

    def _episode_scored(self, req: dict[str, Any]) -> tuple[dict, dict[str, np.ndarray]]:
        outcome = EpisodeOutcome(r_perf=_frozen(req["r_perf"]),
                                 reallocated=_frozen(req["reallocated"]),
                                 allocations=_frozen(req["allocations"]))
        self.pm.hook.ata_episode_scored(episode=outcome)
        return ({"warnings": [str(w) for w in outcome.warnings]},
                {k: np.asarray(v, dtype=float) for k, v in outcome.metrics.items()})


def realize(mission: Mission, registry: Any) -> Mission:
    """The mission with the real settings of the components the host knows only by their
    resolved values (`ata.isolation.remote`): validated again here, from its resolved form,
    by the plugins that provide them; still without the root seed."""
    if not any(getattr(s, "as_dict", None) for s in mission.component_settings.values()):
        return mission
    raw = mission.resolved()
    raw["mission"]["seed"] = 0
    return validate(raw, registry, source=mission.source).public()


def resolve(req: dict[str, Any]) -> dict[str, Any]:
    """The host's question of `ata.isolation.remote`: the resolved settings of the components
    it did not load. Every plugin is loaded here (never in the host) and the whole mission is
    validated, as a worker would; the answer is plain values."""
    raw, wanted = req["mission"], [tuple(x) for x in req["components"]]
    plugins_ = get_plugin_manager(optional=[p for p in raw.get("mission", {}).get("plugins", [])
                                            if isinstance(p, str)])
    registry = collect_components(plugins_)
    mission = validate(raw, registry, source=req.get("source", "<isolated>"))
    out = []
    by_source = {r.source: r for r in mission.references.values()}
    for kind, name in wanted:
        ref = by_source.get(name)           # a reference: the component's name is its own
        if ref is not None:
            info = registry.get(kind, ref.name, "[components]")
            st = mission.component_settings.get(ref.name)
            out.append({"kind": kind, "name": name, "resolved": ref.name, "sha256": ref.sha256,
                        "values": None if st is None else settings_dict(st)})
            continue
        info = registry.get(kind, name, "[components]")
        if is_reference(info.factory):
            raise MissionError("--isolate", None, f"{kind} {name!r} is a reference that reads "
                               "the true state, not a method: run it without --isolate")
        st = mission.component_settings.get(name)
        out.append({"kind": kind, "name": name, "plugin": info.plugin,
                    "values": None if st is None else settings_dict(st)})
    return {"components": out}


def probe(req: dict[str, Any]) -> dict[str, Any]:
    """What one entry point of the ``ata`` group registers, imported alone (the host finds the
    package of an undeclared world component so: `ata.isolation.remote`)."""
    eps = [ep for ep in metadata.entry_points(group="ata") if ep.name == req["entry_point"]]
    pm = pluggy.PluginManager("ata")
    pm.add_hookspecs(hookspecs)
    for ep in eps[:1]:
        pm.register(ep.load(), name=ep.name)
    return {"components": [list(key) for key in collect_components(pm).components]}


def serve(fd_in: int, fd_out: int) -> None:
    """Answer requests until the host closes the channel (or says close)."""
    decider: Decider | None = None
    while True:
        req = child_recv(fd_in)
        if req is None or req.get("op") == Op.CLOSE:
            return
        try:
            if req["op"] in (Op.RESOLVE, Op.PROBE):
                sys.path[:0] = req.get("paths", [])
                child_send(fd_out, (resolve if req["op"] == Op.RESOLVE else probe)(req))
                continue
            if req["op"] == Op.INIT:
                sys.path[:0] = req.get("paths", [])
                for name in req.get("modules", []):
                    importlib.import_module(name)
                mission = pickle.loads(req["mission"])     # loads the plugin files it names
                seed_compiled_cache(req.get("modules", []) + sorted(
                    n for n in sys.modules if n.startswith("ata_file_")))
                decider = Decider(mission, req.get("modules", []), req.get("only", False))
                child_send(fd_out, {"ready": True})
                continue
            t0 = time.perf_counter()
            header, arrays = decider.handle(req)
            # the seconds its components took: the rest of a call's time is the channel's
            header["busy_s"] = time.perf_counter() - t0
            child_send(fd_out, header, arrays)
        except (ContractError, MissionError) as exc:
            child_send(fd_out, {"error": str(exc), "kind": type(exc).__name__})
        except Exception:               # noqa: BLE001 - the host shows it as text
            child_send(fd_out, {"error": traceback.format_exc(), "kind": "exception"})


_SEEDED: set[str] = set()        # the folders whose loops this process has copied


def seed_compiled_cache(modules: list[str] = ()) -> None:
    """The compiled loops the host cached beside ata's modules and beside the method's own
    (`modules`: a plugin package's, walked whole from its top-level folder; a plugin file's,
    the cache beside the file), copied into this process's numba cache (``NUMBA_CACHE_DIR``, in
    the sandbox's own tmpfs), laid out as numba looks for them there. In the sandbox the code
    is read-only, and numba uses no cache it cannot write: without this, each decision process
    compiled every loop again (tens of seconds a start). numba checks each copy against the
    sources as it checks its own cache; a loop the host never compiled is compiled here.
    Nothing goes back to the host."""
    target = os.environ.get("NUMBA_CACHE_DIR")
    if not target:
        return
    import ata   # on use: where the compiled loops are cached
    try:
        from numba.core.caching import _CacheLocator   # on use: numba's cache internals
        subpath = _CacheLocator.get_suitable_cache_subpath
    except (ImportError, AttributeError):
        return
    roots = {os.path.dirname(os.path.abspath(ata.__file__)): True}
    for name in modules:
        top = sys.modules.get(name.split(".")[0])
        file = getattr(top, "__file__", None)
        if file:
            roots.setdefault(os.path.dirname(os.path.abspath(file)), hasattr(top, "__path__"))
    for root, whole in roots.items():
        if root in _SEEDED:
            continue
        _SEEDED.add(root)
        caches = (os.path.join(f, "__pycache__") for f, _, _ in os.walk(root)) if whole \
            else [os.path.join(root, "__pycache__")]
        for folder in caches:
            try:
                cached = [f for f in os.listdir(folder) if f.endswith((".nbi", ".nbc"))]
            except OSError:
                continue
            # numba names a module's cache folder after the module's file
            dest = os.path.join(target, subpath(os.path.join(os.path.dirname(folder), "m.py")))
            try:
                os.makedirs(dest, exist_ok=True)
                for entry in cached:
                    shutil.copyfile(os.path.join(folder, entry), os.path.join(dest, entry))
            except OSError:
                return


def main() -> None:
    seed_compiled_cache()
    # the channel gets private descriptors; fd 1 becomes stderr, so that a component's print
    # cannot corrupt a frame
    fd_in, fd_out = os.dup(0), os.dup(1)
    devnull = os.open(os.devnull, os.O_RDONLY)
    os.dup2(devnull, 0)
    os.dup2(2, 1)
    serve(fd_in, fd_out)


if __name__ == "__main__":
    main()
