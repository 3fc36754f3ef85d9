"""Typed, range-checked settings tables: a dataclass per table, validated from TOML values.

A component declares its mission-file keys as a dataclass named ``Settings``; a field's
``metadata`` may carry ``min``, ``max`` (inclusive), ``choices`` and ``help``. ``param()`` is
the short way to write such a field.
"""

from __future__ import annotations

import dataclasses
import math
import typing
from typing import Any

from ata.core.errors import MissionError


def param(default: Any, *, min: float | None = None, max: float | None = None,
          choices: tuple | None = None, help: str = "") -> Any:
    """A settings field with its default, allowed range or choices, and a help line."""
    meta = {"min": min, "max": max, "choices": choices, "help": help}
    if isinstance(default, (list, dict)):
        return dataclasses.field(default_factory=lambda: type(default)(default), metadata=meta)
    return dataclasses.field(default=default, metadata=meta)


def _type_name(tp: Any) -> str:
    origin = typing.get_origin(tp)
    if origin is typing.Union or str(origin) == "<class 'types.UnionType'>":
        return " or ".join(_type_name(a) for a in typing.get_args(tp))
    if origin is list:
        (arg,) = typing.get_args(tp) or (Any,)
        plural = {int: "integers", float: "numbers", bool: "true or false values",
                  str: "strings"}.get(arg, _type_name(arg))
        return f"a list of {plural}"
    return {int: "an integer", float: "a number", bool: "true or false", str: "a string",
            type(None): "nothing"}.get(tp, getattr(tp, "__name__", str(tp)))


def _coerce(value: Any, tp: Any) -> Any:
    """Return value as type tp, or raise TypeError."""
    origin = typing.get_origin(tp)
    if origin is typing.Union or str(origin) == "<class 'types.UnionType'>":
        for arg in typing.get_args(tp):
            try:
                return _coerce(value, arg)
            except TypeError:
                continue
        raise TypeError
    if origin is list:
        (arg,) = typing.get_args(tp) or (Any,)
        if not isinstance(value, list):
            raise TypeError
        return [_coerce(v, arg) for v in value]
    if tp is Any:
        return value
    if tp is type(None):
        if value is None:
            return None
        raise TypeError
    if tp is bool:
        if isinstance(value, bool):
            return value
        raise TypeError
    if tp is int:
        if isinstance(value, int) and not isinstance(value, bool):
            return value
        raise TypeError
    if tp is float:
        if isinstance(value, (int, float)) and not isinstance(value, bool):
            return float(value)
        raise TypeError
    if tp is str:
        if isinstance(value, str):
            return value
        raise TypeError
    raise TypeError


def _check_range(value: Any, meta: dict, where: str, key: str) -> None:
    lo, hi, choices = meta.get("min"), meta.get("max"), meta.get("choices")
    items = value if isinstance(value, list) else [value]
    for v in items:
        if isinstance(v, float) and not math.isfinite(v):
            raise MissionError(where, key, f"{v!r} is not allowed; a finite number is needed")
        if choices is not None and v not in choices:
            raise MissionError(where, key, f"{v!r} is not allowed; choose one of "
                               + ", ".join(repr(c) for c in choices))
        if isinstance(v, (int, float)) and not isinstance(v, bool):
            if lo is not None and v < lo:
                raise MissionError(where, key, f"{v!r} is below the minimum; allowed: "
                                   + _range_text(lo, hi))
            if hi is not None and v > hi:
                raise MissionError(where, key, f"{v!r} is above the maximum; allowed: "
                                   + _range_text(lo, hi))


def _range_text(lo: Any, hi: Any) -> str:
    if lo is not None and hi is not None:
        return f"{lo} to {hi}"
    return f"at least {lo}" if lo is not None else f"at most {hi}"


def allowed_text(meta: dict) -> str:
    """What a field accepts beyond its type: its choices or its range ("" when anything)."""
    if meta.get("choices") is not None:
        return "one of " + ", ".join(repr(c) for c in meta["choices"])
    if meta.get("min") is not None or meta.get("max") is not None:
        return _range_text(meta.get("min"), meta.get("max"))
    return ""


def for_team(settings: Any, team: Any) -> Any:
    """`settings` fitted to the mission's team (`MissionSettings`): its class's optional
    ``for_team(team)`` (a family of shipped weights becomes the member that suits the team's
    size, say), else `settings` as they are. Validation applies it to the settings a mission
    names, the kernel to a component's defaults."""
    fit = getattr(settings, "for_team", None)
    return fit(team) if callable(fit) else settings


@typing.runtime_checkable
class TableSettings(typing.Protocol):
    """A component's ``Settings`` that validates its table itself instead of being a dataclass
    whose fields are checked here (a component whose settings were validated in another
    process, say); its values then give ``as_dict()``."""

    def from_table(self, table: dict[str, Any] | None, where: str) -> Any: ...


@typing.runtime_checkable
class SettingsValues(typing.Protocol):
    """Settings values that are no dataclass: what a `TableSettings` gives."""

    def as_dict(self) -> dict[str, Any]: ...


def build_settings(cls: type, table: dict[str, Any] | None, where: str) -> Any:
    """Validate a TOML table against a settings dataclass and return the filled instance.

    :param where: the table's name in the mission file, for error messages ("[greedy]").
    """
    if isinstance(cls, TableSettings):
        return cls.from_table(table, where)
    table = dict(table or {})
    fields = {f.name: f for f in dataclasses.fields(cls)}
    unknown = sorted(set(table) - set(fields))
    if unknown:
        allowed = ", ".join(sorted(fields)) or "(none)"
        raise MissionError(where, unknown[0], f"unknown key; allowed keys: {allowed}")
    hints = typing.get_type_hints(cls)
    values = {}
    for name, value in table.items():
        tp = hints[name]
        try:
            values[name] = _coerce(value, tp)
        except TypeError:
            raise MissionError(where, name, f"{value!r} is not {_type_name(tp)}") from None
        _check_range(values[name], dict(fields[name].metadata), where, name)
    return cls(**values)


def settings_dict(obj: Any) -> dict[str, Any]:
    """The settings as a TOML-ready dict (None values left out: TOML has no null)."""
    if isinstance(obj, SettingsValues):
        return {k: v for k, v in obj.as_dict().items() if v is not None}
    return {k: v for k, v in dataclasses.asdict(obj).items() if v is not None}


def describe(cls: type) -> list[tuple[str, str, Any, str, str]]:
    """(key, type, default, allowed values, help) for every field, for `ata plugins --verbose`
    and the docs."""
    hints = typing.get_type_hints(cls)
    rows = []
    for f in dataclasses.fields(cls):
        default = f.default if f.default is not dataclasses.MISSING else f.default_factory()
        rows.append((f.name, _type_name(hints[f.name]), default, allowed_text(dict(f.metadata)),
                     f.metadata.get("help", "")))
    return rows
