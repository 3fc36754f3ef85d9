"""Checkers a plugin author runs on a component before publishing it (cf. gymnasium's check_env).

    from ata.testing import check_component
    check_component("injector", MyInjector, settings={"probability": 0.3})

It builds a small mission with the component in its slot, runs it, and checks the contract:
the component is accepted by the kernel, policies return legal allocations, the observation
keeps its tables and shapes, and a scenario's results do not depend on the batch it runs in
(components must draw from ``sim.rng``/``ctx.rng`` streams, never from a shared generator).
A decision-maker (policy, condition, reconstructor) must decide the same on the same
observations (run twice, nothing redrawn) and pass the integrity check: for every stream of
the world that I does not show, run again with that stream alone redrawn, it must decide the
same until what it observes differs. Each run is made in a fresh process (forked where the
platform can) with a private, empty HOME and temporary folder, under a seed and a salt drawn
anew for each check, with the global generators (numpy's, random's, torch's) seeded at random
in it. Each failure raises ``AssertionError``
with what broke.

It is a linter for honest mistakes, not a gate: code that means to peek can recognise the check,
or read the world some way no check foresees. Ranking methods one does not trust is done apart,
with ``ata eval --isolate`` (docs/isolation.md).

A policy fills the slots whose hooks it implements: with ``ata_initial_allocation`` the initial
slot (else ``greedy`` does); with ``ata_reallocate`` the reallocation slot, called at every
epoch (else ``keep`` fills it and the condition is ``never``). See docs/plugins.md.

A reference reconstructor (``reference = True``: the kernel hands it the true state) is no
method and fails the integrity check by design: `check_component` refuses it unless told
``reference=True``, and then runs every check but that one.
"""

from __future__ import annotations

import multiprocessing
import os
import random
import secrets
import shutil
import sys
import tempfile
import traceback
from dataclasses import dataclass, field
from typing import Any, Callable

import numpy as np

from ata import hookimpl
from ata.core import references
from ata.core.components import DECISION_KINDS
from ata.core.errors import ContractError, MissionError
from ata.core.kernel import Simulation, is_reference
from ata.core.mission import SLOTS, ComponentSlots, Mission, parse_override, validate
from ata.core.registry import KINDS, collect_components, get_plugin_manager
from ata.core.state import Allocation, DecisionContext
from ata.runtime import fingerprint

LIST_SLOT_BASE = {"perturbations": ComponentSlots().perturbations,
                  "injectors": ComponentSlots().injectors, "reconstructors": []}
"""A component of a list slot is checked after these built-ins (the mission defaults)."""
SLOT_OF_KIND = {s.kind: s.name for s in reversed(SLOTS)}
"""The slot a component of each kind is checked in (a policy's: the first, initial)."""


def _contributor(kind: str, name: str, factory: Callable[..., Any]) -> Any:
    """A throw-away plugin that registers the component under test."""

    class Contributor:
        @hookimpl
        def ata_register_components(self, register) -> None:
            register(kind, name, factory)

    return Contributor()


CHECK_HUMANS = {"t0_max_h": 0.5}
"""The built-in human model's settings in a decision-maker's check mission: no human has worked
past the earliest onset of fatigue (0.5 h at the default spread) when the episode starts."""


def check_team(seed: int) -> dict[str, Any]:
    """The check mission's team and horizon, drawn from its seed (2 to 4 humans, 3 to 5 robots,
    9 to 15 POIs, 10 to 12 minutes), so that a component cannot tell a check by its shape."""
    draw = random.Random(seed ^ 0x5EED)
    return {"setting": "custom", "humans": draw.randint(2, 4), "robots": draw.randint(3, 5),
            "tasks": draw.randint(9, 15), "horizon_s": float(draw.choice((600, 660, 720)))}


def _mission(kind: str, name: str, factory: Callable[..., Any], settings: dict | None,
             mission_keys: dict | None, seed: int = 0) -> tuple[Mission, Any]:
    registry = collect_components(get_plugin_manager(entry_points=False))
    known = registry.components.get((kind, name))
    if known is None or known.factory is not factory:   # a registered one is there already
        registry = collect_components(get_plugin_manager(
            extra=[_contributor(kind, name, factory)], entry_points=False))
    slot = SLOT_OF_KIND[kind]
    raw: dict[str, Any] = {"mission": {**check_team(seed), "scenarios": 6, "batch_size": 6,
                                       "uncertainty": "high", "seed": seed,
                                       **(mission_keys or {})},
                           "components": {}}
    if slot in LIST_SLOT_BASE:
        raw["components"][slot] = LIST_SLOT_BASE[slot] + [name]
    elif kind == "policy":
        # a policy fills the slots whose hooks it implements; built-ins fill the others
        initial = hasattr(factory, "ata_initial_allocation")
        realloc = hasattr(factory, "ata_reallocate")
        if not (initial or realloc):
            raise AssertionError(f"policy {name!r} implements neither ata_initial_allocation "
                                 "nor ata_reallocate")
        raw["components"]["initial"] = name if initial else "greedy"
        raw["components"]["reallocation"] = name if realloc else "keep"
        raw["components"]["condition"] = "always" if realloc else "never"
    else:
        raw["components"][slot] = name
    if kind in DECISION_KINDS:
        # every human starts before the earliest fatigue onset, so that S shows no fatigue at
        # first and a decision that follows the hidden curves is caught before it shows
        raw["human"] = dict(CHECK_HUMANS)
    if settings:
        raw[name] = settings
    return validate(raw, registry, source="mission.toml"), registry


@dataclass
class Trace:
    """One run of the check mission: its rewards, and per epoch what the decision-makers saw
    and what they decided, each an array with a leading scenario axis."""

    r_perf: np.ndarray
    inherent: dict[str, np.ndarray] = field(default_factory=dict)
    drawn: tuple[str, ...] = ()
    shown_in_inherent: bool = False     # a redrawn stream changed I: nothing to compare
    observations: list[dict[str, np.ndarray]] = field(default_factory=list)
    seen: list[dict[str, np.ndarray]] = field(default_factory=list)
    decided: list[dict[str, np.ndarray]] = field(default_factory=list)


def _seen(ctx: DecisionContext) -> dict[str, np.ndarray]:
    """What a decision-maker sees at `ctx` besides I (the same in every run): S, its extras,
    what S shows reallocatable, and the allocation in force."""
    out = {f"S.{g}": t.features.copy() for g, t in ctx.observed.items()}
    out.update({f"S.{g}.holds": t.holds.copy() for g, t in ctx.observed.items()
                if t.holds is not None})
    out.update({f"S.extras.{k}": np.asarray(v).copy() for k, v in ctx.observed.extras.items()})
    out["reallocatable"] = ctx.reallocatable.copy()
    if ctx.previous is not None:
        out["allocation in force"] = ctx.previous.stack()
    return out


def _decided(ctx: DecisionContext, allocation: Allocation | None, active: np.ndarray | None
             ) -> dict[str, np.ndarray]:
    """What the decision-makers made of it: the reconstructors' outputs, the condition, the
    allocation (at t = 0) or the reallocation proposed (in the scenarios it was asked for)."""
    out = {f"reconstructed {k!r}": np.asarray(v).copy() for k, v in ctx.reconstructed.items()}
    if ctx.epoch == 0:
        out["initial allocation"] = allocation.stack()
        return out
    out["condition"] = active.copy()
    # a scenario's entry does not depend on whether another scenario reallocated
    none = np.iinfo(np.int64).min
    proposed = allocation.stack() if allocation is not None else \
        np.full(ctx.previous.stack().shape, none)
    out["reallocation"] = np.where(active[:, None, None], proposed, none)
    return out


def _inherent(inherent: Any) -> dict[str, np.ndarray]:
    out = {f"I.{g}": np.asarray(t.features) for g, t in inherent.items()}
    out.update({f"I.extras.{k}": np.asarray(v) for k, v in inherent.extras.items()})
    return out


def _run(mission: Mission, registry: Any, ids: list[int], redraw: tuple[str, ...] = (),
         salt: int = 0, base: "Trace | None" = None) -> Trace:
    """One run of the check mission. With `redraw`, those world streams draw other numbers
    (under `salt`), and the run stops as soon as what every scenario observes differs from
    `base` (or at once, marked, when I differs): no decision after that is compared."""
    shared = fingerprint.state()
    sim = Simulation(mission, registry, ids)
    world = sim.sim.rng.resalted(redraw, salt) if redraw else sim.sim.rng
    world.drawn = set()
    sim.sim.rng = world
    trace = Trace(r_perf=np.zeros(0))
    trace.inherent = _inherent(sim.reset())
    if base is not None and any(_difference(base.inherent, trace.inherent, s) is not None
                                for s in range(len(ids))):
        trace.shown_in_inherent = True
        return trace
    diverged = np.zeros(len(ids), dtype=bool)
    for k in range(sim.sim.clock.n_epochs):
        ctx = sim.begin_epoch()
        trace.seen.append(_seen(ctx))
        trace.observations.append({g: t.features.copy() for g, t in ctx.observed.items()})
        allocation, active = sim.decide(ctx)
        sim.end_epoch(allocation, active)          # the kernel checks the contract first
        trace.decided.append(_decided(ctx, allocation, active))
        if base is not None:
            diverged |= [_difference(base.seen[k], trace.seen[k], s) is not None
                         for s in range(len(ids))]
            if diverged.all():
                break
    if sim.sim.epoch == sim.sim.clock.n_epochs:
        trace.r_perf = sim.end_episode().r_perf.copy()
    trace.drawn = tuple(sorted(world.drawn))
    edited = fingerprint.changed(shared, fingerprint.state())
    assert not edited, (f"the run changed what every component reads: {', '.join(edited[:5])} "
                        "(module state of ata.core or ata.model: copy a table before changing "
                        "it)")
    return trace


def _fresh_child(job: Callable[[], Any], conn: Any) -> None:
    """In a forked child: a private, empty HOME and temporary folder (no run finds what another
    left there, such as a memo of the missions seen), the global generators seeded at random (a
    method that uses them is told apart from one that peeks), the job run, its result or its
    exception sent back."""
    private = tempfile.mkdtemp(prefix="ata-check-")
    try:
        for name in ("HOME", "TMPDIR", "TEMP", "TMP"):
            os.environ[name] = os.path.join(private, "home" if name == "HOME" else "tmp")
            os.makedirs(os.environ[name], exist_ok=True)
        tempfile.tempdir = os.environ["TMPDIR"]
        seed = int.from_bytes(os.urandom(4), "little")
        np.random.seed(seed)
        random.seed(seed)
        torch = sys.modules.get("torch")
        if torch is not None:
            torch.set_num_threads(1)   # OpenMP's pool does not survive a fork
            torch.manual_seed(seed)
        out: Any = ("ok", job())
    except BaseException as exc:       # noqa: BLE001 - everything goes back to the parent
        out = ("error", exc, traceback.format_exc())
    try:
        conn.send(out)
    except Exception:                  # an exception that does not pickle: its text
        conn.send(("error", RuntimeError(out[2] if out[0] == "error" else "unpicklable result"),
                   out[2] if out[0] == "error" else ""))
    finally:
        conn.close()
        shutil.rmtree(private, ignore_errors=True)


def _in_fresh_processes(jobs: list[Callable[[], Any]], workers: int = 2) -> list[Any]:
    """Run each job in a process of its own, forked from this one before any job ran, so that
    no job sees what another left behind (a cache, a first read); `workers` at a time. Where
    the platform cannot fork, the jobs run here, one after another."""
    if "fork" not in multiprocessing.get_all_start_methods():
        return [job() for job in jobs]
    context = multiprocessing.get_context("fork")
    results: list[Any] = [None] * len(jobs)
    running: list[tuple[int, Any, Any]] = []
    pending = list(enumerate(jobs))
    while pending or running:
        while pending and len(running) < workers:
            i, job = pending.pop(0)
            receive, send = context.Pipe(duplex=False)
            process = context.Process(target=_fresh_child, args=(job, send), daemon=True)
            process.start()
            send.close()
            running.append((i, process, receive))
        i, process, receive = running.pop(0)
        try:
            out = receive.recv()
        except EOFError:
            process.join()
            raise RuntimeError(f"a check run died without an answer (exit code "
                               f"{process.exitcode})") from None
        process.join()
        if out[0] == "error":
            raise out[1]
        results[i] = out[1]
    return results


def _difference(a: dict[str, np.ndarray], b: dict[str, np.ndarray], s: int
                ) -> tuple[str, tuple] | None:
    """The first entry (name, index within scenario s's row) where two epoch records differ
    in scenario s; None where they agree."""
    for name in sorted(set(a) | set(b)):
        x, y = a.get(name), b.get(name)
        if x is None or y is None:
            return name, ()
        x, y = np.asarray(x[s]), np.asarray(y[s])
        if not np.array_equal(x, y, equal_nan=x.dtype.kind == "f" and y.dtype.kind == "f"):
            where = np.argwhere(np.asarray(x != y))
            return name, tuple(int(i) for i in where[0]) if where.size else ()
    return None


def _value(record: dict[str, np.ndarray], name: str, s: int, index: tuple) -> str:
    x = record.get(name)
    if x is None:
        return "none"
    row = np.asarray(x[s])
    if name in ("initial allocation", "reallocation") and index:
        triple = row[index[0]]
        return f"(robot {triple[0]}, navigator {triple[1]}, classifier {triple[2]})" \
            if triple[0] != np.iinfo(np.int64).min else "none"
    return str(row[index] if index else row)


def _first_change(base: Trace, other: Trace, ids: list[int]) -> tuple | None:
    """The first decision (epoch, scenario, what, index) that differs between two runs while
    what the decision-makers observed had not yet differed; None when there is none."""
    found = []
    for s in range(len(ids)):
        for k in range(min(len(base.seen), len(other.seen))):
            if _difference(base.seen[k], other.seen[k], s) is not None:
                break                           # from here on it may decide otherwise
            diff = _difference(base.decided[k], other.decided[k], s)
            if diff is not None:
                found.append((k, s, *diff))
                break
    return min(found, key=lambda f: (f[0], f[1])) if found else None


def _where(what: str, index: tuple) -> str:
    return f" for POI {index[0]}" if what.endswith("allocation") and index else \
        (f" at row {index[0]}" if index else "")


def _nondeterminism(kind: str, name: str, base: Trace, again: Trace, ids: list[int]) -> None:
    """Raise AssertionError when two runs with nothing redrawn decide differently on the same
    observations: the component draws from something that is not ctx.rng."""
    change = _first_change(base, again, ids)
    if change is None:
        return
    k, s, what, index = change
    raise AssertionError(
        f"{kind} {name!r} is not deterministic: run twice on the same scenarios, with nothing "
        f"redrawn, in scenario {ids[s]} at epoch {k} its {what}{_where(what, index)} was "
        f"{_value(base.decided[k], what, s, index)} in one run and "
        f"{_value(again.decided[k], what, s, index)} in the other, on the same observations. "
        "It draws from a generator other than ctx.rng (numpy's global np.random, the random "
        "module, torch's global generator) or from the clock: draw every random number from "
        "ctx.rng streams (docs/hooks.md, 'Random numbers')")


def _integrity(kind: str, name: str, base: Trace, mission: Mission, registry: Any,
               ids: list[int], salt: int) -> None:
    """For each world stream the base run drew, run again with it alone redrawn (in fresh
    processes); raise AssertionError at the first decision that changed while what the
    decision-makers observed had not. A stream I shows is skipped: I differs from the start."""
    streams = list(base.drawn)
    others = _in_fresh_processes([
        (lambda st=st: _run(mission, registry, ids, redraw=(st,), salt=salt, base=base))
        for st in streams])
    for stream, other in zip(streams, others):
        if other.shown_in_inherent:
            continue
        change = _first_change(base, other, ids)
        if change is None:
            continue
        k, s, what, index = change
        seen_until = next((j for j in range(min(len(base.seen), len(other.seen)))
                           if _difference(base.seen[j], other.seen[j], s) is not None), None)
        until = "throughout" if seen_until is None else f"before epoch {seen_until}"
        raise AssertionError(
            f"{kind} {name!r} decides from what it cannot observe: in scenario {ids[s]}, at "
            f"epoch {k}, its {what}{_where(what, index)} was "
            f"{_value(base.decided[k], what, s, index)} as the world drew it and "
            f"{_value(other.decided[k], what, s, index)} with the unseen draws ({stream}) "
            f"drawn again; what it observed was the same in both runs {until}. A "
            "decision-maker decides from I, the observed S, the allocation in force, its "
            "settings and ctx.rng alone (docs/decisions.md, 'Submitting a method')")


def check_component(kind: str, factory: Callable[..., Any], *, name: str = "under_test",
                    settings: dict | None = None, mission: dict | None = None,
                    reference: bool = False, seed: int | None = None) -> None:
    """Run the contract checks on one component factory; raise AssertionError on a breach.

    :param kind: one of ``ata.core.registry.KINDS``.
    :param settings: the component's settings table, as it would stand in a mission file.
    :param mission: extra ``[mission]`` keys for the small test mission.
    :param reference: the factory is a reference reconstructor (``reference = True``, it reads
        the true state): say so to run every check but the integrity check, which a reference
        fails by design. Without it, a reference is refused.
    :param seed: the check mission's root seed; None (the default) draws one, and a salt, at
        random for each check. A failure's message names the seed it ran under.
    """
    if is_reference(factory) != reference:
        raise AssertionError(
            f"{kind} {name!r} is a reference: it reads the true state, so it is no method and "
            "the integrity check does not apply; check the rest of its contract with "
            "check_component(..., reference=True)" if reference is False else
            f"{kind} {name!r} is not a reference (its class does not declare reference = "
            "True): check it as a method, without reference=True")
    seed = secrets.randbelow(2**31) if seed is None else int(seed)
    salt = 1 + secrets.randbelow(2**62)
    m, registry = _mission(kind, name, factory, settings, mission, seed)
    patched = fingerprint.against_sources()
    if patched:
        raise AssertionError(f"{kind} {name!r}: {', '.join(patched[:5])} of ata.core or "
                             "ata.model is not what ata's sources make (changed by the "
                             "component's code, or by other code loaded with it)")
    ids = list(range(m.settings.scenarios))
    try:
        try:
            base, again, alone = _in_fresh_processes([
                lambda: _run(m, registry, ids), lambda: _run(m, registry, ids),
                lambda: _run(m, registry, ids[-1:])])
            if kind in DECISION_KINDS:
                _nondeterminism(kind, name, base, again, ids)
            if kind in DECISION_KINDS and not reference:
                _integrity(kind, name, base, m, registry, ids, salt)
        except ContractError as exc:   # the kernel's contract checks
            raise AssertionError(f"{kind} {name!r} broke the kernel's contract: {exc}") from exc
        except (AssertionError, MissionError):
            raise
        except Exception as exc:       # noqa: BLE001 - the component's own error, in a line
            text = " ".join(str(exc).split())[:2000]
            raise AssertionError(f"{kind} {name!r} raised {type(exc).__name__}: "
                                 f"{text}") from exc
        _same_runs(base, again, alone, ids)
    except AssertionError as exc:
        raise AssertionError(f"{exc} [check_component(..., seed={seed})]") from exc.__cause__


def _same_runs(base: Trace, again: Trace, alone: Trace, ids: list[int]) -> None:
    """The world's side of determinism: finite rewards, whole tables, the same numbers twice,
    and a scenario's numbers whatever its batch."""
    r_perf, observations = base.r_perf, base.observations
    assert np.isfinite(r_perf).all(), "r_perf has non-finite values"
    for k, obs in enumerate(observations):
        for group, feats in obs.items():
            assert feats.shape[0] == len(ids), f"epoch {k}: table {group!r} lost scenarios"
    assert np.array_equal(r_perf, again.r_perf), "two runs with the same seed differ"
    # the last scenario alone must reproduce its row of the batch
    assert np.array_equal(alone.r_perf[0], r_perf[-1]), (
        "a scenario's results depend on the batch it runs in: draw random numbers from "
        "sim.rng / ctx.rng streams, never from a generator shared by the batch")
    for k, (a, b) in enumerate(zip(alone.observations, observations)):
        for group in a:
            assert np.array_equal(a[group][0], b[group][-1]), (
                f"epoch {k}: observed {group!r} of a scenario depends on its batch")


def check_reference(kind: str, target: str, overrides: list[str] = (),
                    plugins: list[str] = (), seed: int | None = None) -> str:
    """`ata check --component KIND TARGET`: `check_component` on a component named by reference
    (``PATH.py:Class``, ``module:Class``) or by its registered name; ``--set`` texts give its
    settings (``NAME.KEY=V``) and the small mission's keys (``mission.KEY=V``). Returns the
    component's name; raises AssertionError on a breach, MissionError on bad input."""

    if kind not in KINDS:
        raise MissionError("--component", None, f"unknown kind {kind!r}; kinds: "
                           + ", ".join(KINDS))
    if references.is_reference(target):
        factory, _, _ = references.load(target, "--component")
        name = references.component_name(factory)
    else:
        registry = collect_components(get_plugin_manager(optional=list(plugins)))
        factory, name = registry.get(kind, target, "--component").factory, target
    tables: dict[str, dict] = {"mission": {}, name: {}}
    for text in overrides:
        path, value = parse_override(text)
        if path[0] not in tables or len(path) != 2:
            raise MissionError("--set", text, f"sets [{name}] (the component's settings) or "
                               "[mission] keys here")
        tables[path[0]][path[1]] = value
    check_component(kind, factory, name=name, settings=tables[name] or None,
                    mission=tables["mission"] or None, reference=is_reference(factory),
                    seed=seed)
    return name


def check_published_rows(spec: str = "published", per_cell: int = 2,
                         methods: list[str] | None = None,
                         cells: dict[str, list[str]] | None = None) -> None:
    """Rerun a sample of a set of published rows (`ata.experiment.reproduce.rerun_sample`: the
    first and the last scenario of every method's cell, then evenly between; `cells`: method
    -> the cells to rerun of it) and raise AssertionError naming every value that is not
    identical to the published one."""
    from ata.experiment.reproduce import rerun_sample   # on use: the run path, for this check alone
    lines = [x for x in rerun_sample(spec, per_cell, methods, cells=cells)
             if not x.endswith("not rerun")]
    if lines:
        raise AssertionError(f"{len(lines)} rerun value(s) differ from the published rows of "
                             f"{spec}:\n" + "\n".join(lines))
