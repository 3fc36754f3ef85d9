"""Loading trained networks for the learned components, and what they record while training.

A component names its checkpoint as a path or as ``builtin:NAME`` (a file shipped in
``ata/weights/NAME.pt``). Each checkpoint is loaded once per process, with
``torch.load(..., weights_only=True)``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

import torch

from ata.core.errors import MissionError
from ata.core.settings import param
from ata.learn.nets import ATAHRLNet, NetConfig

WEIGHTS = Path(__file__).resolve().parent.parent / "weights"
_CACHE: dict[tuple[str, str], torch.nn.Module] = {}


def resolve(spec: str) -> Path:
    if spec.startswith("builtin:"):
        return WEIGHTS / f"{spec.split(':', 1)[1]}.pt"
    return Path(spec)


class CheckpointError(MissionError):
    """A checkpoint that is missing, corrupted, or does not match the mission."""

    def __init__(self, path: str | Path, message: str):
        super().__init__("checkpoint", None, message, file=str(path))


def read_checkpoint(path: str | Path) -> dict[str, Any]:
    """Load a checkpoint dict safely; any failure is a CheckpointError naming the file."""
    p = Path(path)
    if not p.exists():
        raise CheckpointError(p, "no such checkpoint (train one with `ata train`)")
    try:
        data = torch.load(p, map_location="cpu", weights_only=True)
    except Exception as exc:   # truncated, corrupted, or not a torch file at all
        raise CheckpointError(p, f"cannot be read as a checkpoint ({type(exc).__name__}: "
                                 f"{str(exc).splitlines()[0][:200]})") from None
    if not isinstance(data, dict) or "model" not in data or "config" not in data:
        raise CheckpointError(p, "is not an ata checkpoint (no model or config)")
    return data


def net_from_checkpoint(data: dict[str, Any], path: str | Path,
                        expect: NetConfig | None = None) -> ATAHRLNet:
    """Build the network a checkpoint describes and load its weights."""
    try:
        cfg = NetConfig(**data["config"])
    except TypeError as exc:
        raise CheckpointError(path, f"has an unknown architecture ({exc})") from None
    if expect is not None and cfg != expect:
        raise CheckpointError(path, f"architecture {cfg.as_dict()} does not match the "
                                    f"mission's {expect.as_dict()}")
    net = ATAHRLNet(cfg)
    try:
        net.load_state_dict(data["model"])
    except RuntimeError as exc:
        raise CheckpointError(path, "weights do not fit the architecture: "
                                    f"{str(exc).splitlines()[0][:200]}") from None
    return net


def load_cached(spec: str, build: Callable[[dict[str, Any], Path], torch.nn.Module],
                kind: str = "net") -> Any:
    """What `build(checkpoint data, path)` makes of a checkpoint, in evaluation mode, built once
    per process for each (kind, file)."""
    path = resolve(spec)
    key = (kind, str(path.resolve()) if path.exists() else str(path))
    if key not in _CACHE:
        module = build(read_checkpoint(path), path)
        module.eval()
        _CACHE[key] = module
    return _CACHE[key]


def load_net(spec: str) -> ATAHRLNet:
    """The network of a checkpoint, in evaluation mode, cached per process."""
    return load_cached(spec, net_from_checkpoint)


@dataclass
class Recorder:
    """What the learned components record in a training rollout (tensors keep their graph)."""

    ita_logp: torch.Tensor | None = None                  # (B,)
    ita_entropy: torch.Tensor | None = None               # (B,)
    cond_logp: list[torch.Tensor] = field(default_factory=list)     # per epoch (B,)
    cond_entropy: list[torch.Tensor] = field(default_factory=list)
    tr_logp: list[torch.Tensor] = field(default_factory=list)       # per epoch (B,)
    tr_entropy: list[torch.Tensor] = field(default_factory=list)


class LearnedComponent:
    """Base of the components that decide with the network: its settings, and the live network,
    recorder and sampler a trainer hands in (a recorder switches on training mode)."""

    @dataclass
    class Settings:
        checkpoint: str = param("builtin:ata_hrl_a", help="trained weights: a path or "
                                "builtin:NAME")
        sample: bool = param(False, help="sample decisions (each scenario from its own random "
                             "stream) instead of taking the mode")

    def __init__(self, settings: "LearnedComponent.Settings", mission: Any,
                 net: ATAHRLNet | None = None, recorder: Recorder | None = None,
                 generator: torch.Generator | None = None):
        self.settings = settings
        self.net = net if net is not None else load_net(settings.checkpoint)
        self.recorder = recorder
        self.generator = generator

    @property
    def training(self) -> bool:
        return self.recorder is not None
