"""Checkpoints of the learned components: reading them safely, caching what they build, and the
scenario ranges their training drew from."""

from __future__ import annotations

import warnings
from pathlib import Path
from typing import Any, Callable, Iterator

import numpy as np

from ata.core.errors import MissionError
from ata.runtime.heldout import EVAL_FIRST_SCENARIO
from ata.runtime.inputs import resolve, shipped_mismatch
from ata.training.tensorfile import ForeignGlobal, load as load_arrays

TRAINING_ID_LIMIT = EVAL_FIRST_SCENARIO
"""Training scenario ids lie below this; evaluation ids start there."""
VALIDATION_SEED_OFFSET = 1_000_003
"""A trainer's held-out validation scenarios have root seed ``seed + VALIDATION_SEED_OFFSET``
(the built-in trainers' convention; they list that range in ``scenario_ranges``)."""
_CACHE: dict[tuple, Any] = {}


class CheckpointError(MissionError):
    """A checkpoint that is missing, corrupted, or does not match what reads it."""

    def __init__(self, path: str | Path, message: str):
        super().__init__("checkpoint", None, message, file=str(path))


def read_checkpoint(path: str | Path, kind: str | None = None, *,
                    arrays: bool = False) -> dict[str, Any]:
    """Load a checkpoint dict with ``torch.load(..., weights_only=True)``; a missing, empty,
    truncated or foreign file is a CheckpointError naming it.

    :param kind: the method the checkpoint must be of (its ``kind`` entry), if any: a
        TR-POMDP checkpoint given where ATA-HRL's is expected is refused.
    :param arrays: read it without torch (``ata.training.tensorfile``): its tensors as numpy
        arrays, the same values; what evaluation reads, so that it never imports torch.
    """
    p = Path(path)
    if not p.exists():
        raise CheckpointError(p, "no such checkpoint (train one with `ata train`)")
    if p.is_dir():
        raise CheckpointError(p, "is a directory, not a checkpoint")
    mismatch = shipped_mismatch(p)   # before unpickling: a changed file may be any bytes
    if mismatch is not None:
        raise CheckpointError(p, mismatch)
    data = _load_arrays(p) if arrays else _load_torch(p)
    if not isinstance(data, dict) or "kind" not in data:
        raise CheckpointError(p, "is not an ata checkpoint (it names no method)")
    bad = next(non_finite(data), None)
    if bad is not None:
        raise CheckpointError(p, f"holds non-finite values (NaN or inf) in {bad}: the run "
                                 "that wrote it diverged; take an earlier checkpoint")
    return of_kind(data, p, kind)


FOREIGN = ("holds objects other than tensors and plain data, which ata does not load (an ata "
           "checkpoint holds only those)")


def _load_torch(p: Path) -> Any:
    import torch   # on use: the simulator needs no torch
    try:
        with warnings.catch_warnings():     # torch warns of a foreign file's pickle protocol
            warnings.simplefilter("ignore")   # before it refuses it: the refusal says it all
            return torch.load(p, map_location="cpu", weights_only=True)
    except Exception as exc:   # empty, truncated, corrupted, or not a torch file at all
        text = str(exc)
        if "weights only load failed" in text.lower():
            # PyTorch's message suggests weights_only=False, which runs the file's code: never
            # the advice for a file from elsewhere. Keep its diagnosis alone.
            if "unsupported global" in text.lower():
                raise CheckpointError(p, FOREIGN) from None
            cause = text.split("WeightsUnpickler error:", 1)[-1].strip().splitlines()
            text = f"not a file of tensors and plain data: {cause[0] if cause else '?'}"
        first = (text.splitlines() or [""])[0][:200]
        raise CheckpointError(p, f"cannot be read as a checkpoint ({type(exc).__name__}: "
                                 f"{first})") from None


def _load_arrays(p: Path) -> Any:
    try:
        return load_arrays(p)
    except ForeignGlobal:
        raise CheckpointError(p, FOREIGN) from None
    except Exception as exc:   # empty, truncated, corrupted, or not a torch file at all
        first = (str(exc).splitlines() or [""])[0][:200]
        raise CheckpointError(p, f"cannot be read as a checkpoint ({type(exc).__name__}: "
                                 f"{first})") from None


def non_finite(data: Any, where: str = "") -> Iterator[str]:
    """The names of the floating-point tensors (or arrays) in `data` (nested dicts and lists)
    that hold a NaN or an infinity."""
    if isinstance(data, np.ndarray):
        if data.dtype.kind == "f" and not np.isfinite(data).all():
            yield where or "the checkpoint"
    elif hasattr(data, "is_floating_point") and hasattr(data, "isfinite"):     # a tensor
        if data.is_floating_point() and not bool(data.isfinite().all()):
            yield where or "the checkpoint"
    elif isinstance(data, dict):
        for key, value in data.items():
            yield from non_finite(value, f"{where}.{key}" if where else str(key))
    elif isinstance(data, (list, tuple)):
        for i, value in enumerate(data):
            yield from non_finite(value, f"{where}[{i}]")


def of_kind(data: dict[str, Any], path: str | Path, kind: str | None) -> dict[str, Any]:
    """`data` if it is a checkpoint of method `kind` (any, if None); a CheckpointError if not."""
    if kind is not None and data.get("kind") != kind:
        raise CheckpointError(path, f"is a checkpoint of {data.get('kind')!r}, not of "
                                    f"{kind!r}: name a checkpoint that `ata train` wrote for "
                                    f"{kind}")
    return data


def load_cached(spec: str, build: Callable[[dict[str, Any], Path], Any], kind: str, *,
                arrays: bool = False) -> Any:
    """What `build(checkpoint data, path)` makes of a checkpoint of `kind` (a torch module in
    evaluation mode), built once per process for each (kind, file); with `arrays`, `build`
    reads the checkpoint as numpy arrays (``read_checkpoint(..., arrays=True)``: no torch)."""
    path = resolve(spec)
    key = (kind, arrays, str(path.resolve()) if path.exists() else str(path))
    if key not in _CACHE:
        built = build(read_checkpoint(path, kind, arrays=arrays), path)
        if hasattr(built, "eval"):
            built.eval()
        _CACHE[key] = built
    return _CACHE[key]


def trained_on(spec: str, kind: str) -> list[tuple[int, int, int]]:
    """The (root seed, first id, end id) ranges a checkpoint's training drew scenarios from,
    as its trainer recorded them (read once per process for each version of the file)."""
    path = resolve(spec)
    stat = path.stat() if path.is_file() else None
    key = ("ranges", kind, str(path.resolve()), stat and (stat.st_mtime_ns, stat.st_size))
    if stat is None or key not in _CACHE:
        data = read_checkpoint(path, kind, arrays=True)
        _CACHE[key] = [tuple(int(x) for x in r) for r in data.get("scenario_ranges", [])]
        _CACHE[("parts",) + key[1:]] = [str(part) for part in data.get("trained", [])]
    return list(_CACHE[key])


def trained_parts(spec: str, kind: str) -> list[str]:
    """The parts (networks) a checkpoint's training trained, as its trainer recorded them
    (its ``trained`` entry): a component that needs a trained part refuses a file without it."""
    trained_on(spec, kind)
    path = resolve(spec)
    stat = path.stat()
    return list(_CACHE[("parts", kind, str(path.resolve()), (stat.st_mtime_ns, stat.st_size))])
