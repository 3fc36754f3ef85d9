"""The errors the CLI reports as one message and exit 2: bad input (``MissionError``) and a
component that breaks the kernel's contract (``ContractError``). Both cross a process boundary
as plain data (their arguments and attributes), whatever a subclass's ``__init__`` takes, so a
refusal raised in a worker arrives as the same refusal."""

from __future__ import annotations

from typing import Any


def _rebuilt(cls: type, args: tuple, state: dict[str, Any]) -> BaseException:
    """An error of `cls` with these args and attributes, without calling its ``__init__``."""
    error = cls.__new__(cls)
    error.args = args
    error.__dict__.update(state)
    return error


class _Plain:
    """Pickled as its class, args and attributes: the default pickles ``args`` alone and calls
    ``__init__(*args)`` again, which fails for an ``__init__`` of other arguments (a worker's
    refusal became a ``BrokenProcessPool``)."""

    def __reduce__(self):
        return _rebuilt, (type(self), self.args, dict(self.__dict__))


class MissionError(_Plain, Exception):
    """Bad input in a mission file or on the command line; the CLI prints it and exits 2."""

    def __init__(self, where: str, key: str | None, message: str, file: str | None = None):
        self.where = where
        self.key = key
        self.message = message
        self.file = file
        super().__init__(str(self))

    def with_file(self, file: str) -> "MissionError":
        if self.file is None:
            self.file = file
        return self

    def __str__(self) -> str:
        place = self.where
        if self.key:
            place = f"{self.where} key {self.key!r}" if self.where else f"key {self.key!r}"
        prefix = f"{self.file}: " if self.file else ""
        return f"{prefix}{place}: {self.message}" if place else f"{prefix}{self.message}"


class ContractError(_Plain, ValueError):
    """A component broke the kernel's contract (a wrong type, shape or dtype, a value out of
    range): a bug in that component, not in the user's input. The message names the slot and
    the component; the CLI prints it and exits 2."""
