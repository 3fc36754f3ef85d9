"""The errors the CLI reports as one message and exit 2: bad input (``MissionError``) and a
component that breaks the kernel's contract (``ContractError``)."""

from __future__ import annotations


class MissionError(Exception):
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


class ContractError(ValueError):
    """A component broke the kernel's contract (a wrong type, shape or dtype, a value out of
    range): a bug in that component, not in the user's input. The message names the slot and
    the component; the CLI prints it and exits 2."""
