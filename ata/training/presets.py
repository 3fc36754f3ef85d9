"""Named recipes of a trainer (``ata train --preset NAME``): a trainer class lists them in its
``presets`` attribute, ``{name: {key: value}}`` of its own table, and they apply as ``--set``
overrides before the user's own (which win)."""

from __future__ import annotations

from typing import Any

import tomli_w

from ata.core.errors import MissionError


def toml_value(value: Any) -> str:
    """`value` as the right-hand side of a ``--set KEY=VALUE``."""
    return tomli_w.dumps({"v": value}).split("=", 1)[1].strip()


def preset_overrides(trainer: str, factory: Any, name: str) -> list[str]:
    """The ``--set`` overrides of preset `name` of the trainer `trainer` (its class `factory`)."""
    presets = getattr(factory, "presets", {}) or {}
    if name not in presets:
        raise MissionError("--preset", None, f"trainer {trainer!r} has no preset {name!r}"
                           + (f"; it has: {', '.join(presets)}" if presets else ""))
    return [f"{trainer}.{key}={toml_value(value)}" for key, value in presets[name].items()]


def weights_overrides(trainer: Any, best: Any) -> list[str]:
    """``--set`` overrides that point the checkpoint key of every component the trainer trains
    (its ``trained_components()``) at the run's `best` weights, so that the run folder's
    resolved mission evaluates what it trained."""
    names = trainer.trained_components() if hasattr(trainer, "trained_components") else []
    return [f"{name}.checkpoint={toml_value(str(best))}" for name in names]
