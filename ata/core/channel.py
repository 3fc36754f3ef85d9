"""What components publish for each other, and the read-only copies that keep it from changing:
a typed channel of values (a team model's constants) and the checks on what it may hold."""

from __future__ import annotations

import dataclasses
import enum
from typing import Any, TypeVar

import numpy as np

from ata.core.errors import ContractError


def read_only(values: Any) -> np.ndarray:
    """A read-only copy of `values`: what the kernel hands a decision-maker, and what a
    published value holds, so that no edit reaches the array it came from."""
    out = np.array(values, copy=True)
    out.flags.writeable = False
    return out


T = TypeVar("T")

_SCALARS = (type(None), bool, int, float, complex, str, bytes, np.generic, enum.Enum)


def check_published(value: Any) -> None:
    """Raise a ``ContractError`` unless `value` holds nothing that can change after it is
    published: a dataclass (or a scalar or tuple) whose fields are scalars, tuples of them, or
    read-only arrays that own their data (`read_only`). A live array would let every policy read
    the true state through ``ctx.published``; a list or another object could be changed."""
    def walk(x: Any, where: str) -> None:
        if isinstance(x, _SCALARS):
            return
        if isinstance(x, np.ndarray):
            if x.flags.writeable or x.base is not None:
                raise ContractError(
                    f"published {type(value).__name__}: {where} is a live array (writeable or "
                    "a view of another array); publish a read-only copy taken at publication, "
                    "ata.core.state.read_only(array), so that it cannot show the true state as "
                    "it changes")
            if x.dtype.hasobject:
                raise ContractError(f"published {type(value).__name__}: {where} is an array "
                                    "of objects; publish numbers")
            return
        if isinstance(x, (tuple, frozenset)):
            for i, item in enumerate(x):
                walk(item, f"{where}[{i}]")
            return
        if dataclasses.is_dataclass(x) and not isinstance(x, type):
            for f in dataclasses.fields(x):
                walk(getattr(x, f.name), f"{where}.{f.name}" if where else f.name)
            return
        raise ContractError(
            f"published {type(value).__name__}: {where or 'the value'} is a "
            f"{type(x).__name__}, which can change after publication; a published value is a "
            "dataclass of scalars, tuples and read-only arrays (ata.core.state.read_only)")
    walk(value, "")


class Channel:
    """Typed values that components publish for each other, one per type: a team model's
    constants that policies assume, say. The kernel knows none of the types; a type names who
    publishes it in a class attribute ``published_by`` (used in the error when it is missing).
    """

    def __init__(self) -> None:
        self._values: dict[type, Any] = {}

    def publish(self, value: Any) -> None:
        """Publish `value` under its type; a second value of one type raises ``ValueError``,
        a value that holds live state a ``ContractError`` (`check_published`)."""
        check_published(value)
        kind = type(value)
        if kind in self._values:
            raise ValueError(f"{kind.__name__} is published already: one value per type")
        self._values[kind] = value

    def get(self, kind: type[T]) -> T:
        """The value published as `kind` (or the one published as a subclass of it); a
        ``ContractError`` naming the type and its publisher when there is none."""
        if kind in self._values:
            return self._values[kind]
        found = [v for v in self._values.values() if isinstance(v, kind)]
        if len(found) == 1:
            return found[0]
        if found:
            raise ContractError(f"{len(found)} published values are a {kind.__name__}: "
                                "publish one")
        who = getattr(kind, "published_by", "the component that provides it")
        held = ", ".join(sorted(t.__name__ for t in self._values)) or "nothing"
        raise ContractError(f"no {kind.__name__} was published: {who} publishes it "
                            f"(sim.publish in ata_setup); published: {held}")
