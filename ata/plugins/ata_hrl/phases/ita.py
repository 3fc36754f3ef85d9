"""The ITA phase: the attention ITA policy alone, by shared-baseline policy gradient on R_ITA.

Nothing is reallocated and nothing is reconstructed during this phase (the ITA reads I alone), so
R_ITA is the episode's total team performance. ``ita_from`` takes the ITA of another run instead
and skips the phase: the full method, its ablations and AtRL-TR can share one ITA trained alone.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import partial
from typing import Callable, Iterator

import numpy as np
import torch

from ata.core.settings import param
from ata.plugins.ata_hrl import logprob
from ata.plugins.ata_hrl.components import Recorder
from ata.plugins.ata_hrl.network import encode_once
from ata.plugins.ata_hrl.phases.policy import PolicyPhase, scaled, shared_baseline_advantage


UPDATE_GROUPS = 4
"""An ITA update takes its gradient in this many parts of whole scenarios: a step's rows
(about 350,000 scored candidates in setting (a)) in parts whose tensors stay in the caches.
The same gradient up to float rounding, and faster than one pass (docs/training.md,
"Training throughput")."""


@dataclass
class Settings:
    """The ITA phase's keys of ``[ata_hrl]``."""

    ita_steps: int = param(300, min=0, help="ita: steps of the ITA phase")
    lr: float = param(1e-3, min=0.0, max=1.0, help="ita: Adam learning rate of the ITA phase")
    lr_end: float = param(1.0, min=0.0, max=1.0, help="ita: the learning rate at the ITA "
                          "phase's last step, a fraction of lr: from step 0 it falls along a "
                          "half cosine to lr * lr_end (1: constant)")
    ita_epochs: int = param(1, min=1, max=16, help="ita: updates on each rollout; each after "
                            "the first a clipped-ratio (PPO) step on the same decisions, against "
                            "the probabilities they were sampled with")
    ita_clip: float = param(0.2, min=0.0, max=1.0, help="ita: the ratio clip of the updates "
                            "after the first on a rollout (ita_epochs)")
    ita_from: str = param("", help="ita: take the ITA policy from this checkpoint (a path or "
                          "builtin:NAME) and skip the ITA phase: the full method and its "
                          "ablations can share one ITA, trained alone")


class ItaPhase(PolicyPhase):
    """The ITA phase of a trainer (see the module's doc)."""

    name = "ita"
    rewards_logged = ("R_ITA",)        # nothing is reallocated: R_C and R_TR do not apply
    reallocates = False
    _sampled: dict[int, torch.Tensor] | None = None
    """While a step updates more than once: each part's decisions' log-probabilities at the
    sampled weights, kept by the first update (keyed by the part's first row)."""

    def lr(self) -> float:
        return self.tr.s.lr

    def lr_at(self, k: int) -> float:
        """Step k's learning rate: lr at step 0, falling along a half cosine to lr * lr_end at
        the phase's last step (a function of k alone, so a resumed run takes the same)."""
        s, last = self.tr.s, self.tr.phases()[self.name] - 1
        if last <= 0:
            return s.lr
        return s.lr * (s.lr_end + (1 - s.lr_end) * 0.5 * (1 + math.cos(math.pi * k / last)))

    def learn(self, rec: Recorder, R: dict[str, np.ndarray]) -> float:
        """The policy-gradient update on the rollout, then, with ``ita_epochs`` above 1, the
        clipped-ratio updates on the same decisions; returns the first update's loss."""
        self._sampled = {} if self.tr.s.ita_epochs > 1 else None
        loss = super().learn(rec, R)
        for _ in range(1, self.tr.s.ita_epochs):
            super().learn(rec, R)
        self._sampled = None
        return loss

    def parts(self, rec: Recorder, R: dict[str, np.ndarray]
              ) -> Iterator[Callable[[], torch.Tensor]]:
        """-(advantage * log-probability of the sample's decisions), averaged over decisions,
        in parts of whole scenarios (`UPDATE_GROUPS` at most); each scenario's samples are
        encoded once. Once the rollout's own probabilities are kept (the first update with
        ``ita_epochs`` above 1), each decision's term is PPO's clipped-ratio objective against
        them: -min(r A, clip(r, 1 - ita_clip, 1 + ita_clip) A), r the ratio of its probability
        now to the sampled one (at r = 1 the first update's gradient)."""
        net, K, dev, s = self.tr.net, self.tr.s.samples, self.tr.device, self.tr.s
        E = R["R_ITA"].size
        adv = scaled(shared_baseline_advantage(R["R_ITA"], K), dev)
        sampled = self._sampled
        again = bool(sampled)

        def part(rows: slice) -> torch.Tensor:
            feats = {g: v[rows] for g, v in rec.inherent.items()}
            emb = encode_once(net.ita.encoder, feats, dev)
            decisions: list | None = [] if sampled is not None else None
            logp, _ = logprob.trace_log_prob(net.ita, emb, rec.ita.take(rows),
                                             decisions=decisions)
            if decisions is None:
                return -(adv[rows] * logp).sum() / E
            now = torch.cat([d for d, _ in decisions])
            episode = torch.cat([e for _, e in decisions])
            if not again:
                sampled[rows.start] = now.detach()
                return -(adv[rows] * logp).sum() / E
            a = adv[rows][episode]
            ratio = torch.exp(now - sampled[rows.start])
            clipped = torch.clamp(ratio, 1 - s.ita_clip, 1 + s.ita_clip)
            return -torch.minimum(ratio * a, clipped * a).sum() / E
        for group in np.array_split(np.arange(E // K), min(UPDATE_GROUPS, E // K)):
            yield partial(part, slice(group[0] * K, (group[-1] + 1) * K))
