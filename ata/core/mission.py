"""Mission files: TOML in, validated and fully resolved mission out.

Layout: ``[mission]`` (team, seed, scenarios, clock, uncertainty), ``[components]`` (the slot
table naming one component per slot), and one table per chosen component, named after it, for
its settings. ``--set table.key=value`` overrides any key before validation.
"""

from __future__ import annotations

import copy
import dataclasses
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import tomli_w

from ata.core import references as refs_mod
from ata.core.components import SLOTS, Components, Slot  # noqa: F401  (Slot: named here too)
from ata.core.errors import MissionError
from ata.core.seeds import seed_hash, secret_seed  # noqa: F401  (seed_hash: a test reads it here)
from ata.core.settings import build_settings, for_team, param, settings_dict
from ata.core.state import Clock, TeamSize

TEAM_SETTINGS = {"a": TeamSize(humans=6, robots=8, tasks=60),
                 "b": TeamSize(humans=12, robots=16, tasks=130)}
"""The paper's two team settings."""

UNCERTAINTY_LEVELS = {"none": (0.0, 0.0), "low": (0.05, 0.1), "medium": (0.1, 0.2),
                      "high": (0.2, 0.4)}
"""(fatigue noise variance, event probability) per level; docs/model.md, "Uncertainty"."""


@dataclass
class MissionSettings:
    """The ``[mission]`` table."""

    name: str = param("mission", help="a short label for the run (its folder's name)")
    title: str = param("", help="the method's display name in summaries (default: its "
                       "components)")
    setting: str = param("a", choices=("a", "b", "custom"),
                         help="team setting: a (6/8/60), b (12/16/130) or custom")
    humans: int | None = param(None, min=1, max=1000, help="number of humans, at most 1000 "
                               "(arrays grow with the team); other than the setting's: custom")
    robots: int | None = param(None, min=1, max=1000, help="number of robots, at most 1000 "
                               "(arrays grow with the team); other than the setting's: custom")
    tasks: int | None = param(None, min=1, max=10000, help="number of POIs, at most 10000 "
                              "(arrays grow with them); other than the setting's: custom")
    seed: int = param(0, min=0, max=2**63 - 1, help="root seed: fixes every scenario")
    scenarios: int = param(100, min=1, max=10_000_000, help="scenarios to run (a row each)")
    first_scenario: int = param(0, min=0, help="index of the first scenario (held-out ranges)")
    batch_size: int = param(500, min=1, max=100_000, help="scenarios stepped together (memory)")
    workers: int = param(1, min=1, max=256, help="worker processes for `ata run` (~330 MB each)")
    horizon_s: float = param(1800.0, min=1.0, max=86_400.0,
                             help="mission length in seconds, at most a day (86400): the "
                             "kernel records every decision epoch of every scenario, and "
                             "steps every tick")
    epoch_s: float = param(60.0, min=1.0, help="decision epoch in seconds")
    tick_s: float = param(10.0, min=0.1, help="kernel tick in seconds")
    uncertainty: str = param("medium", choices=tuple(UNCERTAINTY_LEVELS) + ("custom",),
                             help="uncertainty level: none, low, medium, high, or custom")
    fatigue_variance: float | None = param(None, min=0.0, max=10.0,
                                           help="fatigue noise variance (overrides the level)")
    event_probability: float | None = param(None, min=0.0, max=1.0,
                                            help="event probability p (overrides the level)")
    plugins: list[str] = param([], help="optional plugins to load (e.g. ctr, aux); not "
                               "needed for the components named in [components], which load "
                               "their plugin")


@dataclass
class ComponentSlots:
    """The ``[components]`` table: which component fills each slot."""

    task_model: str = param("poi", help="POIs: positions, kinds, difficulties, scoring")
    human_model: str = param("human", help="human performance, fatigue, workload, SA")
    robot_model: str = param("robot", help="robot motion, image quality, capture, onboard P_rc")
    perturbations: list[str] = param(["attribute_change", "robot_failure"],
                                     help="events drawn at set-up that change the true state "
                                     "(task attribute changes, robot failures)")
    injectors: list[str] = param(["fatigue_noise", "latency"],
                                 help="uncertainty injectors: they corrupt the observation, in "
                                 "order")
    reconstructors: list[str] = param(["identity"], help="state reconstructors")
    initial: str = param("greedy", help="initial allocation policy (t = 0)")
    condition: str = param("on_event", help="condition policy: when to reallocate")
    reallocation: str = param("greedy", help="reallocation policy: how to reallocate")
    trainer: str = param("none", help="what `ata train` trains the learned components with "
                         "(none: nothing to train)")


SLOT_KINDS = {s.name: s.kind for s in SLOTS}
"""Slot name -> the kind of component it takes."""
SLOT_HOOKS = {s.name: s.hook for s in SLOTS if s.hook}
"""Single-choice slots -> the hook called on the chosen component alone."""
TRAINER_SLOT = ("trainer", "trainer")
"""The slot `ata train` fills (slot, kind); "none" leaves it empty."""


@dataclass
class Mission:
    """A validated mission with every default filled in."""

    settings: MissionSettings
    slots: ComponentSlots
    component_settings: dict[str, Any]   # component name -> its Settings instance (or None)
    source: str = "<built-in>"
    secret_seed: bool = False            # the seed came from the environment: never written
    references: dict[str, Any] = field(default_factory=dict)   # name -> references.Reference
    swapped: dict[str, str] = field(default_factory=dict)   # [components] a --set changed

    def __getstate__(self) -> dict[str, Any]:
        # a referenced component's settings travel as plain values: its class is loaded again
        # from its file where the mission lands (a worker process), and checked unchanged
        state = dict(self.__dict__)
        if self.references:
            state["component_settings"] = {n: settings_dict(v) if n in self.references and v
                                           is not None else v
                                           for n, v in self.component_settings.items()}
        return state

    def __setstate__(self, state: dict[str, Any]) -> None:
        self.__dict__.update(state)
        for name, factory in refs_mod.restore(state.get("references") or {}).items():
            if isinstance(self.component_settings.get(name), dict):
                self.component_settings[name] = build_settings(factory.Settings,
                                                               self.component_settings[name],
                                                               f"[{name}]")

    @property
    def seed_label(self) -> int | str:
        """The root seed as results and resolved files show it: the seed, or for a secret one
        ``secret:`` and the start of its SHA-256 (a host who reveals the seed later can be
        checked against it)."""
        seed = self.settings.seed
        return seed_hash(seed) if self.secret_seed else seed

    def public(self) -> "Mission":
        """The mission as a decision-maker's factory gets it: a copy without the root seed
        (None), which would let it rebuild the world's random streams."""
        m = copy.deepcopy(self)
        m.settings.seed = None
        m.secret_seed = False
        return m

    @property
    def sizes(self) -> TeamSize:
        s = self.settings
        return TeamSize(humans=s.humans, robots=s.robots, tasks=s.tasks)

    def method_label(self) -> str:
        """The method as its components: initial / condition / reallocation, then the
        reconstructors other than identity (the reallocation is left out when the condition is
        ``never``: it never runs)."""
        s = self.slots
        parts = [s.initial, s.condition] + ([] if s.condition == "never" else [s.reallocation])
        label = " / ".join(parts)
        recon = [r for r in s.reconstructors if r != "identity"]
        return label + (f" + {', '.join(recon)}" if recon else "")

    def display_name(self) -> str:
        """The mission's ``title`` (with the components a ``--set`` swapped, as in "ATA-HRL
        [condition=always]"), else its method label."""
        swaps = ", ".join(f"{k}={v}" for k, v in self.swapped.items())
        return (self.settings.title + (f" [{swaps}]" if swaps else "")) if self.settings.title \
            else self.method_label()

    @property
    def clock(self) -> Clock:
        s = self.settings
        return Clock(tick_s=s.tick_s, epoch_s=s.epoch_s, horizon_s=s.horizon_s)

    @property
    def fatigue_variance(self) -> float:
        return float(self.settings.fatigue_variance)

    @property
    def event_probability(self) -> float:
        return float(self.settings.event_probability)

    def chosen(self) -> list[tuple[str, str]]:
        """(kind, name) of every chosen component, in mission (and hook-call) order."""
        out = []
        for slot, kind in SLOT_KINDS.items():
            value = getattr(self.slots, slot)
            for name in (value if isinstance(value, list) else [value]):
                if (kind, name) not in out:
                    out.append((kind, name))
        if self.slots.trainer != "none":
            out.append((TRAINER_SLOT[1], self.slots.trainer))
        return out

    def resolved(self) -> dict[str, Any]:
        """The full mission as a TOML-ready dict: every key, every default."""
        out: dict[str, Any] = {"mission": settings_dict(self.settings),
                               "components": settings_dict(self.slots)}
        out["mission"]["seed"] = self.seed_label
        for name, st in self.component_settings.items():
            out[name] = settings_dict(st) if st is not None else {}
        if self.references:
            out[refs_mod.TABLE] = {n: r.table() for n, r in self.references.items()}
        for name, st in self.component_settings.items():    # one run apart (--isolate)
            if getattr(st, "reference", None):
                out.setdefault(refs_mod.TABLE, {})[name] = dict(st.reference)
        return out

    def to_toml(self) -> str:
        return tomli_w.dumps(self.resolved())

    def replace(self, **mission_keys: Any) -> "Mission":
        """A copy with some ``[mission]`` keys changed (no re-validation of components), and what
        depends on them derived again as validation derives it (unless given too): a team
        setting's sizes, an uncertainty level's fatigue variance and event probability."""
        keys, team = dict(mission_keys), TEAM_SETTINGS.get(mission_keys.get("setting", ""))
        for k in ("humans", "robots", "tasks") if team is not None else ():
            keys.setdefault(k, getattr(team, k))
        level = UNCERTAINTY_LEVELS.get(keys.get("uncertainty", ""), (None, None))
        for k, v in zip(("fatigue_variance", "event_probability"), level):
            if v is not None:
                keys.setdefault(k, v)
        m = copy.deepcopy(self)
        m.settings = dataclasses.replace(m.settings, **keys)
        if "seed" in mission_keys:
            m.secret_seed = False
        return m


MAX_DEPTH = 16
"""Tables and arrays nested deeper than this are refused: no mission key needs more than two
levels, and a deeply nested value exhausts the parser's recursion (or the validator's)."""
MAX_INT_DIGITS = 20
"""Integers of more digits than this are refused (2**64 has 20): no setting takes more, and a
huge one costs quadratic time to convert, or exceeds Python's int-to-text limit."""


def _sane(value: Any, depth: int = 0) -> str | None:
    """Why a parsed TOML value is beyond sane bounds (None when it is not)."""
    if depth > MAX_DEPTH:
        return f"values nested more than {MAX_DEPTH} deep"
    if isinstance(value, bool):
        return None
    if isinstance(value, int) and abs(value) >= 10 ** MAX_INT_DIGITS:
        return f"an integer of more than {MAX_INT_DIGITS} digits"
    children = value.values() if isinstance(value, dict) else value \
        if isinstance(value, list) else ()
    return next((why for v in children if (why := _sane(v, depth + 1)) is not None), None)


class BeyondLimits(ValueError):
    """TOML that parses (or would) but holds values beyond `MAX_DEPTH` or `MAX_INT_DIGITS`."""


def loads_toml(text: str) -> dict[str, Any]:
    """tomllib.loads; `BeyondLimits` for what tomllib fails on otherwise (an integer beyond
    Python's int-to-text limit, nesting that exhausts its recursion) and for values beyond
    `MAX_DEPTH` or `MAX_INT_DIGITS`."""
    try:
        data = tomllib.loads(text)
    except RecursionError:
        raise BeyondLimits(f"values nested more than {MAX_DEPTH} deep") from None
    except ValueError as exc:
        if isinstance(exc, tomllib.TOMLDecodeError):
            raise
        raise BeyondLimits(f"an integer of more than {MAX_INT_DIGITS} digits") from None
    why = _sane(data, -1)
    if why is not None:
        raise BeyondLimits(why)
    return data


def read_toml(path: str | Path) -> dict[str, Any]:
    """Parse a mission file, turning a missing file or a syntax error into a MissionError."""
    p = Path(path)
    if not p.exists():
        raise MissionError("", None, "no such file", file=str(path))
    if p.is_dir():
        raise MissionError("", None, "is a directory, not a mission file", file=str(path))
    try:
        return loads_toml(p.read_text(encoding="utf-8"))
    except tomllib.TOMLDecodeError as exc:
        raise MissionError("", None, f"TOML syntax error: {exc}", file=str(path)) from None
    except BeyondLimits as exc:
        raise MissionError("", None, f"{exc}: refused", file=str(path)) from None
    except UnicodeDecodeError:
        raise MissionError("", None, "not a UTF-8 text file", file=str(path)) from None


def parse_override(text: str) -> tuple[list[str], Any]:
    """'table.key=value' -> (['table', 'key'], value parsed as a TOML value, else a string)."""
    if "=" not in text:
        raise MissionError("--set", None, f"{text!r} is not of the form table.key=value")
    key, raw = text.split("=", 1)
    path = [k.strip() for k in key.strip().split(".")]
    if len(path) < 2 or not all(path):
        raise MissionError("--set", None, f"{key!r} must name a table and a key, e.g. "
                           "mission.seed=3")
    try:
        value = loads_toml(f"v = {raw.strip()}")["v"]
    except BeyondLimits as exc:
        raise MissionError("--set", None, f"{key.strip()}: {exc}: refused") from None
    except tomllib.TOMLDecodeError:
        value = raw.strip()
    return path, value


def apply_overrides(raw: dict[str, Any], overrides: list[str]) -> dict[str, Any]:
    """A copy of the raw mission dict with ``--set`` overrides applied."""
    out = copy.deepcopy(raw)
    for text in overrides:
        path, value = parse_override(text)
        node = out
        for part in path[:-1]:
            node = node.setdefault(part, {})
            if not isinstance(node, dict):
                raise MissionError("--set", text, f"{part!r} is not a table")
        node[path[-1]] = value
    return out


def requested_plugins(raw: dict[str, Any]) -> list[str]:
    """The optional plugins a raw mission asks for by name in ``[mission] plugins``, before
    full validation."""
    plugins = raw.get("mission", {}).get("plugins", []) if isinstance(raw.get("mission"), dict) \
        else []
    return [p for p in plugins if isinstance(p, str)] if isinstance(plugins, list) else []


def named_components(raw: dict[str, Any]) -> list[str]:
    """The component names a raw mission's ``[components]`` table gives, in order, before full
    validation."""
    table = raw.get("components")
    out: list[str] = []
    for value in table.values() if isinstance(table, dict) else ():
        out += [v for v in (value if isinstance(value, list) else [value]) if isinstance(v, str)]
    return list(dict.fromkeys(out))


def validate(raw: dict[str, Any], registry: Components, source: str = "<built-in>",
             overrides: list[str] = ()) -> Mission:
    """Check every table and key of a raw mission dict and resolve all defaults.

    :param overrides: the ``--set`` texts applied to `raw`: an error in a key one of them set
        names that ``--set``, not the file.
    """
    try:
        mission = _validate(raw, registry, source)
    except MissionError as exc:
        raise exc.with_file(_blamed(exc, overrides) or source) from None
    keys = [parse_override(text) for text in overrides]
    mission.swapped = {} if any(p[:2] == ["mission", "title"] for p, _ in keys) else {
        p[1]: ",".join(map(str, v)) if isinstance(v, list) else str(v)
        for p, v in keys if p[0] == "components" and len(p) == 2}
    return mission


def _blamed(exc: MissionError, overrides: list[str]) -> str | None:
    """'--set TABLE.KEY=VALUE' when the last override of the erring key (or table) is one."""
    place = f"{exc.where} key {exc.key!r}" if exc.key else exc.where
    for text in reversed(overrides):
        path, _ = parse_override(text)
        if place in (f"[{path[0]}] key {path[1]!r}", f"[{path[0]}]"):
            return f"--set {text}"
    return None


def _validate(raw: dict[str, Any], registry: Components, source: str) -> Mission:
    if "train" in raw:
        trainers = ", ".join(registry.names("trainer")) or "none registered"
        raise MissionError("[train]", None, "the training settings moved to the trainer's own "
                           f"table: name the trainer in [components] trainer ({trainers}) and "
                           "put its keys in the table of that name (see docs/training.md)")
    for table in ("mission", "components"):
        if table in raw and not isinstance(raw[table], dict):
            raise MissionError(f"[{table}]", None, "must be a table")
    raw, references = refs_mod.resolve(raw, registry, source, dict([*SLOT_KINDS.items(),
                                                                    TRAINER_SLOT]))
    head = raw.get("mission")
    secret = secret_seed(head.get("seed")) if isinstance(head, dict) else None
    if secret is not None:
        head = {**head, "seed": secret}
    settings = build_settings(MissionSettings, head, "[mission]")
    base = TEAM_SETTINGS.get(settings.setting)
    if base is not None and any(getattr(settings, k) not in (None, getattr(base, k))
                                for k in ("humans", "robots", "tasks")):
        # a size other than the setting's: the team is no longer the paper's (a) or (b), and
        # the summaries, the resolved mission and the trainer's team settings must not say so
        for k in ("humans", "robots", "tasks"):
            if getattr(settings, k) is None:
                setattr(settings, k, getattr(base, k))
        settings.setting = "custom"
    if settings.setting == "custom":
        missing = [k for k in ("humans", "robots", "tasks") if getattr(settings, k) is None]
        if missing:
            raise MissionError("[mission]", missing[0], "is required when setting = 'custom'")
    base = TEAM_SETTINGS.get(settings.setting)
    for k in ("humans", "robots", "tasks"):
        if getattr(settings, k) is None:
            setattr(settings, k, getattr(base, k))
    level = UNCERTAINTY_LEVELS.get(settings.uncertainty)
    if level is None and (settings.fatigue_variance is None or settings.event_probability is None):
        raise MissionError("[mission]", "uncertainty", "'custom' needs fatigue_variance and "
                           "event_probability in [mission]")
    if settings.fatigue_variance is None:
        settings.fatigue_variance = level[0]
    if settings.event_probability is None:
        settings.event_probability = level[1]
    _check_clock(settings)

    if isinstance(raw.get("components"), dict) and "routing" in raw["components"]:
        raise MissionError("[components]", "routing", "routing is a setting of the robot model: "
                           "write it as [robot] routing (see: ata plugins --verbose)")
    slots = build_settings(ComponentSlots, raw.get("components"), "[components]")
    chosen: dict[str, Any] = {}
    for slot, kind in SLOT_KINDS.items():
        value = getattr(slots, slot)
        names = value if isinstance(value, list) else [value]
        if len(set(names)) != len(names):
            raise MissionError("[components]", slot, "lists a component twice")
        for name in names:
            info = registry.get(kind, name, f"[components] key {slot!r}")
            chosen.setdefault(name, info)
    if slots.trainer != "none":
        slot, kind = TRAINER_SLOT
        chosen.setdefault(slots.trainer, registry.get(kind, slots.trainer,
                                                      f"[components] key {slot!r}"))

    known_tables = {"mission", "components", *chosen}
    for table in raw:
        if table not in known_tables:
            raise MissionError(f"[{table}]", None, "names no chosen component; tables allowed: "
                               + ", ".join(f"[{t}]" for t in sorted(known_tables)))
    component_settings: dict[str, Any] = {}
    for name, info in chosen.items():
        table = raw.get(name)
        if table is not None and not isinstance(table, dict):
            raise MissionError(f"[{name}]", None, "must be a table")
        cls = getattr(info.factory, "Settings", None)
        if cls is None:
            if table:
                raise MissionError(f"[{name}]", next(iter(table)), "this component takes no "
                                   "settings")
            component_settings[name] = None
        else:
            built = build_settings(cls, table, f"[{name}]")
            # settings that depend on the team (a family of shipped weights, the member that
            # suits its size): the resolved mission records what they resolve to
            component_settings[name] = for_team(built, settings)
    # the optional plugins loaded because a component was named: the resolved mission then
    # names every plugin it needs (worker processes load them up front from it)
    settings.plugins = list(dict.fromkeys([*settings.plugins, *registry.loaded]))
    return Mission(settings=settings, slots=slots, component_settings=component_settings,
                   source=source, secret_seed=secret is not None, references=references)


MAX_EPOCHS = 10_000
"""Decision epochs per episode at most: the episode record holds an allocation per epoch, POI
and scenario (`EpisodeRecord`), so memory grows with them."""
MAX_TICKS = 1_000_000
"""Ticks per episode at most: the kernel steps each one in Python, one after the other."""


def _check_clock(s: MissionSettings) -> None:
    epochs, ticks = s.horizon_s / s.epoch_s, s.horizon_s / s.tick_s
    if epochs > MAX_EPOCHS:
        raise MissionError("[mission]", "horizon_s", f"{s.horizon_s:g} s is {epochs:.0f} "
                           f"epochs of {s.epoch_s:g} s, more than {MAX_EPOCHS:,} (the episode "
                           "record holds an allocation per epoch): a shorter horizon_s or a "
                           "longer epoch_s")
    if ticks > MAX_TICKS:
        raise MissionError("[mission]", "tick_s", f"{s.horizon_s:g} s is {ticks:.0f} ticks of "
                           f"{s.tick_s:g} s, more than {MAX_TICKS:,} (the kernel steps each "
                           "one): a longer tick_s or a shorter horizon_s")
    ratio = s.epoch_s / s.tick_s
    if abs(ratio - round(ratio)) > 1e-9:
        raise MissionError("[mission]", "epoch_s", f"{s.epoch_s} is not a whole number of "
                           f"ticks of {s.tick_s} s")
    ratio = s.horizon_s / s.epoch_s
    if abs(ratio - round(ratio)) > 1e-9 or round(ratio) < 1:
        raise MissionError("[mission]", "horizon_s", f"{s.horizon_s} is not a whole number "
                           f"of epochs of {s.epoch_s} s")
