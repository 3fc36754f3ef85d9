"""Optional extras (tensorboard, ray, matplotlib), loaded on use. An extra installed but broken
(one whose import raises anything: a protobuf mismatch's TypeError, a missing shared library's
OSError) is handled like a missing one: an extra the command can do without is one warning line
(`ExtraWarning`) and the command goes on; one it needs is one error line naming the fix."""

from __future__ import annotations

import warnings
from typing import Callable, TypeVar

from ata.core.errors import MissionError

T = TypeVar("T")


class ExtraWarning(UserWarning):
    """An optional extra failed and the command goes on without it; the CLI prints it as one
    ``warning:`` line."""


def reason(exc: BaseException) -> str:
    """'TypeError: the first line of its message', at most 200 characters."""
    lines = str(exc).strip().splitlines()
    text = f"{type(exc).__name__}: {lines[0]}" if lines else type(exc).__name__
    return text if len(text) <= 200 else text[:199] + "…"


def without(extra: str, exc: BaseException, doing: str = "loading it") -> None:
    """Warn once that the optional `extra` failed (`doing`) and is left out from now on."""
    warnings.warn(f"{extra} failed {doing} ({reason(exc)}); going on without it",
                  ExtraWarning, stacklevel=2)


def optional(extra: str, load: Callable[[], T]) -> T | None:
    """`load()` (which imports the extra); None when it is not installed (an ImportError: the
    caller says how to install it) or broken (any other exception: one `ExtraWarning`)."""
    try:
        return load()
    except ImportError:
        return None
    except Exception as exc:      # a broken install raises anything on import
        without(extra, exc)
        return None


def required(extra: str, load: Callable[[], T], need: str) -> T:
    """`load()`; a MissionError saying what `need`s it and how to install it when it is not
    installed, or naming the failure when it is installed but broken."""
    try:
        return load()
    except ImportError:
        raise MissionError("", None, f"{need}: pip install 'ata[{extra}]'") from None
    except Exception as exc:      # a broken install raises anything on import
        raise MissionError("", None, f"{need}, and the {extra} installed fails to load "
                           f"({reason(exc)}): reinstall it (pip install --force-reinstall "
                           f"'ata[{extra}]')") from None
