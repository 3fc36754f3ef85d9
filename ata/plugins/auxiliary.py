"""Auxiliary state reconstruction of ATA-HRL (optional plugin ``aux``), the reconstructor
``aux``.

Each epoch it writes, into the reconstructed-state dict the policies read:
``aux_fatigue`` (B, H), the conditional VAE's fatigue estimate from the noisy observation
conditioned on working hours and cognitive ability; and ``aux_robots`` (B, R, 5),
``aux_tasks`` (B, P, 7), the stacked-GRU estimates of the current robot and task rows (in the
feature space of ``ata.learn.features.state_features``) from each entity's sequence of observed
rows, which latency may have left stale. Without it the ``identity`` reconstructor leaves the
raw state (the w/o.AUX ablation).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from ata import hookimpl
from ata.core.settings import param
from ata.core.state import Observation, SimState
from ata.learn import nets
from ata.learn.features import state_features
from ata.learn.runtime import load_net


class AuxReconstructor:
    """cVAE for fatigue, three stacked GRUs plus a feed-forward layer for delayed states."""

    @dataclass
    class Settings:
        checkpoint: str = param("builtin:ata_hrl_a", help="trained weights: a path or "
                                "builtin:NAME")

    def __init__(self, settings: "AuxReconstructor.Settings", mission,
                 net: nets.ATAHRLNet | None = None):
        self.net = net if net is not None else load_net(settings.checkpoint)
        self.hidden: dict[str, torch.Tensor | None] = {"robots": None, "tasks": None}

    @hookimpl
    def ata_reconstruct(self, sim: SimState, obs: Observation, inherent: Observation,
                        out: dict[str, np.ndarray]) -> None:
        feats = state_features(obs)
        with torch.no_grad():
            f_obs = torch.as_tensor(obs["humans"].col("fatigue"), dtype=torch.float32)
            hours = torch.as_tensor(obs["humans"].col("working_time"), dtype=torch.float32)
            cog = torch.as_tensor(inherent["humans"].col("cognitive"), dtype=torch.float32)
            recon, _, _ = self.net.fatigue(f_obs, hours, cog)
            out["aux_fatigue"] = recon.numpy().astype(np.float64)
            for group in ("robots", "tasks"):
                x = torch.as_tensor(feats[group], dtype=torch.float32)
                B, N, F = x.shape
                est, self.hidden[group] = self.net.latency[group](x.reshape(B * N, 1, F),
                                                                  self.hidden[group])
                out[f"aux_{group}"] = est.reshape(B, N, F).numpy().astype(np.float64)


@hookimpl
def ata_register_components(register) -> None:
    register("reconstructor", "aux", AuxReconstructor)
