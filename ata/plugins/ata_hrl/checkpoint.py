"""ATA-HRL's checkpoints: the network a checkpoint describes, cached once per process: the
torch module a trainer goes on from (`load_net`), or the numpy twin that decides
(`load_infer`, read without torch).

Reading is ``ata.training.read_checkpoint`` (``torch.load(..., weights_only=True)``, or its
torch-free reader of the same files): a file that is missing, truncated, not a checkpoint, of
another method (a TR-POMDP checkpoint), of another format or of another architecture is refused
with a message naming it.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from ata.plugins.ata_hrl.arch import NetConfig, expected_shapes
from ata.plugins.ata_hrl.infer import InferenceNet
from ata.training import (CheckpointError, load_cached, read_checkpoint, resolve, trained_on,
                          trained_parts)

KIND = "ata_hrl"
"""The ``kind`` an ATA-HRL checkpoint carries."""
FORMAT = 3
"""The layout of the checkpoints this version writes and reads: pi_C's fitted rule is part of
every network (``cond.rule.weight``, ``.bias`` and ``.on``: zero and off where none was
fitted), and the config holds the architecture alone."""

__all__ = ["KIND", "FORMAT", "CheckpointError", "read_checkpoint", "check_format",
           "net_from_checkpoint", "load_net", "infer_from_checkpoint", "load_infer",
           "trained_ranges"]


def check_format(data: dict[str, Any], path: str | Path) -> None:
    """A CheckpointError unless `data` has this version's layout."""
    if data.get("format") != FORMAT:
        raise CheckpointError(path, f"is an ATA-HRL checkpoint of format {data.get('format')}; "
                                    f"this version reads format {FORMAT} (retrain it with "
                                    "`ata train`)")


def _config(data: dict[str, Any], path: str | Path, expect=None) -> NetConfig:
    """The architecture a checkpoint records, checked."""
    if "model" not in data or "config" not in data:
        raise CheckpointError(path, "holds no ATA-HRL network (no model or config)")
    check_format(data, path)
    try:
        cfg = NetConfig(**data["config"])
    except TypeError as exc:
        raise CheckpointError(path, f"has an unknown architecture ({exc})") from None
    if expect is not None and cfg != expect:
        raise CheckpointError(path, f"architecture {cfg.as_dict()} does not match the "
                                    f"training's {expect.as_dict()}")
    return cfg


def net_from_checkpoint(data: dict[str, Any], path: str | Path, expect=None):
    """Build the ATA-HRL network (torch) a checkpoint describes and load its weights."""
    from ata.plugins.ata_hrl.network import ATAHRLNet   # on use: torch
    cfg = _config(data, path, expect)
    net = ATAHRLNet(cfg)
    try:
        net.load_state_dict(data["model"])
    except RuntimeError as exc:
        raise CheckpointError(path, "weights do not fit the architecture: "
                                    f"{str(exc).splitlines()[0][:200]}") from None
    return net


def infer_from_checkpoint(data: dict[str, Any], path: str | Path) -> InferenceNet:
    """The numpy twin of the network a checkpoint describes (`data` read with
    ``arrays=True``); its weights must be those of the architecture, entry by entry."""
    cfg = _config(data, path)
    state, want = data["model"], expected_shapes(cfg)
    missing = [k for k in want if k not in state]
    extra = [k for k in state if k not in want]
    wrong = [f"{k} {tuple(state[k].shape)} for {want[k]}" for k in want
             if k in state and tuple(state[k].shape) != want[k]]
    for what, names in (("missing", missing), ("unexpected", extra), ("size mismatch", wrong)):
        if names:
            raise CheckpointError(path, f"weights do not fit the architecture: {what}: "
                                        f"{', '.join(names[:3])}"[:300])
    return InferenceNet(state, cfg)


def load_net(spec: str):
    """The ATA-HRL network of a checkpoint (torch), in evaluation mode, cached per process."""
    return load_cached(spec, net_from_checkpoint, KIND)


def load_infer(spec: str) -> InferenceNet:
    """The numpy twin of a checkpoint's network (read without torch), cached per process:
    what the components decide with."""
    return load_cached(spec, infer_from_checkpoint, KIND, arrays=True)


def trained_ranges(spec: str) -> list[tuple[int, int, int]]:
    """The scenario ranges the checkpoint's training used."""
    return trained_on(spec, KIND)


def require_trained(spec: str, part: str, who: str) -> None:
    """Refuse a checkpoint whose training never trained `part` (``aux``: w/o.AUX's files carry
    an untrained reconstruction module, which would run silently on its initial weights)."""
    if part not in trained_parts(spec, KIND):
        raise CheckpointError(resolve(spec), f"trained no {part} module ({who} needs one that "
                                             "did; an ablation's file without it does not)")
