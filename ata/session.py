"""A session: a mission read, its plugins loaded, validated against the registry its backend
gives (`ata.backend`). What `ata run`, `ata eval`, `ata train`, the gym environments and the
tests load a mission with, below every layer that runs one.

A mission argument is a file, ``builtin:NAME`` (ata/missions/NAME.toml), an `ata train` run
folder (its resolved mission, which names its best.pt) or nothing (the built-in default)."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ata.backend import IN_PROCESS, Backend
from ata.core import mission as mission_mod
from ata.core.errors import MissionError
from ata.core.mission import Mission
from ata.core.references import code_digest
from ata.core.registry import OPTIONAL_PLUGINS, Register, providers, requires
from ata.runtime.heldout import EVAL_FIRST_SCENARIO
from ata.runtime.inputs import file_digest
from ata.training.folders import trained_mission
from ata.training.protocol import Trainer

BUILTIN_MISSION = Path(__file__).resolve().parent / "missions" / "default.toml"
"""`ata run`'s default: the full ATA-HRL method with its shipped weights."""
BASELINE_MISSION = BUILTIN_MISSION.with_name("greedy.toml")
"""The greedy reference mission, the base that tests and benchmarks override."""
TRAINING_MISSIONS = sorted(BUILTIN_MISSION.parent.glob("train_*.toml"))
"""The built-in training missions; `ata train --plugins X` takes the one whose components come
from the optional plugins X."""


@dataclass
class Session:
    """A plugin manager, its component registry, and one validated mission."""

    mission: Mission
    registry: Register
    pm: Any
    backend: Backend = field(default=IN_PROCESS)
    """Where its batches' decisions run (`ata.backend`)."""

    def versions(self) -> dict[str, str]:
        """'kind name' -> 'distribution version' of every chosen component."""
        return {f"{kind} {name}": self.registry.get(kind, name, "").dist
                for kind, name in self.mission.chosen()}

    def code(self) -> dict[str, str]:
        """'kind name' -> the digest of the code of every chosen component (its plugin's
        source files; for a component named by reference, its file): the plan keys hold them,
        so results made with other code are never resumed as current."""
        out = {}
        for kind, name in self.mission.chosen():
            info = self.registry.get(kind, name, "")
            # a method run apart (--isolate) brings the digest of its code, never imported
            out[f"{kind} {name}"] = getattr(info.factory, "code", None) or \
                code_digest(info.factory, info.plugin)
        return out

    def inputs(self) -> dict[str, str]:
        """'component.setting' -> content digest of every file a component setting names (a
        checkpoint, ``builtin:NAME`` or a path): the plan keys hold them, so results made with
        one set of weights are never resumed with another under the same name."""
        return inputs_of({comp: {f.name: getattr(settings, f.name)
                                 for f in dataclasses.fields(settings)}
                          for comp, settings in self.mission.component_settings.items()
                          if settings is not None and dataclasses.is_dataclass(settings)})


def inputs_of(tables: dict[str, dict[str, Any]]) -> dict[str, str]:
    """'component.setting' -> content digest of every file a setting value of `tables`
    (component -> its settings as values) names: `Session.inputs`, or a resolved mission's
    component tables read back."""
    out = {}
    for comp, table in tables.items():
        for name, value in table.items():
            digest = file_digest(value) if isinstance(value, str) and value else None
            if digest is not None:
                out[f"{comp}.{name}"] = digest
    return out


def mission_file(spec: str | Path | None) -> str:
    """The file of a mission argument: ``builtin:NAME`` is ata/missions/NAME.toml (as in
    suites), nothing the built-in default mission, an `ata train` run folder its resolved
    mission (which names its best.pt), anything else a path."""
    if not spec:
        return str(BUILTIN_MISSION)
    spec = str(spec)
    if Path(spec).is_dir():            # an `ata train` run folder: its trained weights
        return trained_mission(spec)
    if spec.startswith("builtin:"):
        name = spec.split(":", 1)[1]
        path = BUILTIN_MISSION.parent / f"{name}.toml"
        if not name or "/" in name or not path.is_file():
            known = ", ".join(f"builtin:{p.stem}" for p in sorted(BUILTIN_MISSION.parent.glob(
                "*.toml")))
            raise MissionError("", None, f"no built-in mission {name!r}; there are: {known}",
                               file=spec)
        return str(path)
    return spec


def load_session(path: str | None = None, overrides: list[str] | None = None,
                 plugins: list[str] | None = None, extra: tuple = (),
                 backend: Backend = IN_PROCESS) -> Session:
    """Read (or take the built-in) mission, load the plugins it needs, and validate it against
    the registry `backend` gives (an isolated one imports no third-party method here: a
    sandboxed process validates it)."""
    source = mission_file(path)
    raw = mission_mod.read_toml(source)
    raw = mission_mod.apply_overrides(raw, overrides or [])   # its errors name --set
    # a component named in [components] loads its plugin (lazy registration); these are the
    # optional plugins asked for by name
    optional = list(dict.fromkeys((plugins or []) + mission_mod.requested_plugins(raw)))
    if plugins:
        raw.setdefault("mission", {})["plugins"] = optional
    registry, raw = backend.registry(raw, optional, source, extra)
    mission = mission_mod.validate(raw, registry, source=source, overrides=overrides or [])
    return Session(mission=mission, registry=registry, pm=registry.pm, backend=backend)


def closure(plugins: list[str]) -> frozenset[str]:
    """A set of optional plugins with those they bring along (ctr and aux bring ita)."""
    out = set(plugins)
    for name in plugins:
        if name in OPTIONAL_PLUGINS:
            out |= set(requires(name))
    return frozenset(out)


def training_mission_for(plugins: list[str]) -> Path:
    """The built-in training mission whose optional plugins (those it names and those that
    provide its components) are `plugins` (with what they bring along): ctr,aux the full
    ATA-HRL; ctr w/o.AUX; ita the ITA alone; trp TR-POMDP; ita,trp AtRL-TR."""
    wanted = closure(plugins)
    found = {}
    for path in TRAINING_MISSIONS:
        raw = mission_mod.read_toml(path)
        # what --plugins can name: the optional plugins (a trainer's own plugin, which the
        # mission's trainer loads, is none of them)
        named = mission_mod.requested_plugins(raw) + providers(mission_mod.named_components(raw))
        found[closure([p for p in named if p in OPTIONAL_PLUGINS])] = path
    if wanted not in found:
        known = "; ".join(",".join(sorted(k)) for k in found)
        raise MissionError("--plugins", None, f"no built-in training mission for "
                           f"{','.join(sorted(wanted)) or '(none)'}; there are: {known} (or "
                           "give a training mission file)")
    return found[wanted]


def build_trainer(session: Session) -> Trainer:
    """The trainer component the mission names in [components] trainer, built from its table;
    its scenario ranges are checked to stay below the evaluation ids."""
    m = session.mission
    name = m.slots.trainer
    if name == "none":
        raise MissionError("[components]", "trainer", "names no trainer: nothing to train "
                           "(ata_hrl trains ATA-HRL's parts, tr_pomdp the TR-POMDP agents)",
                           file=m.source)
    info = session.registry.get("trainer", name, "[components] key 'trainer'")
    try:
        trainer = info.factory(m.component_settings.get(name), m, session.registry)
    except MissionError as exc:
        raise exc.with_file(m.source) from None
    if not isinstance(trainer, Trainer):
        missing = [m for m in ("log_fields", "scenario_ranges", "total_steps", "done_steps",
                               "run") if not hasattr(trainer, m)]
        raise MissionError("[components]", "trainer", f"{name!r} is no trainer: it lacks "
                           f"{', '.join(missing)} (ata.training.Trainer)", file=m.source)
    trainer.component_name = name
    for seed, lo, hi in trainer.scenario_ranges():
        if hi > EVAL_FIRST_SCENARIO:
            raise MissionError(f"[{name}]", None, f"trains on scenario ids up to {hi - 1}, "
                               f"which reach the evaluation ids (from {EVAL_FIRST_SCENARIO})",
                               file=m.source)
    return trainer


