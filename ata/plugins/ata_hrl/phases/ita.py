"""The ITA phase: the attention ITA policy alone, by shared-baseline policy gradient on R_ITA.

Nothing is reallocated and nothing is reconstructed during this phase (the ITA reads I alone), so
R_ITA is the episode's total team performance. ``ita_from`` takes the ITA of another run instead
and skips the phase: the full method, its ablations and AtRL-TR can share one ITA trained alone.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from ata.core.settings import param
from ata.plugins.ata_hrl import decode as D
from ata.plugins.ata_hrl.components import Recorder
from ata.plugins.ata_hrl.features import to_tensors
from ata.plugins.ata_hrl.phases.policy import PolicyPhase, scaled, shared_baseline_advantage


@dataclass
class Settings:
    """The ITA phase's keys of ``[ata_hrl]``."""

    ita_steps: int = param(300, min=0, help="ita: steps of the ITA phase")
    lr: float = param(1e-3, min=0.0, max=1.0, help="ita: Adam learning rate of the ITA phase")
    ita_from: str = param("", help="ita: take the ITA policy from this checkpoint (a path or "
                          "builtin:NAME) and skip the ITA phase: the full method and its "
                          "ablations can share one ITA, trained alone")


class ItaPhase(PolicyPhase):
    """The ITA phase of a trainer (see the module's doc)."""

    name = "ita"
    rewards_logged = ("R_ITA",)        # nothing is reallocated: R_C and R_TR do not apply
    reallocates = False

    def lr(self) -> float:
        return self.tr.s.lr

    def loss(self, rec: Recorder, R: dict[str, np.ndarray]) -> torch.Tensor:
        """-(advantage * log-probability of the sample's decisions), averaged over decisions."""
        net = self.tr.net
        emb = net.ita.encoder(to_tensors(rec.inherent, self.tr.device))
        logp, _ = D.trace_log_prob(net.ita, emb, rec.ita)
        adv = scaled(shared_baseline_advantage(R["R_ITA"], self.tr.s.samples), self.tr.device)
        return -(adv * logp).mean()
