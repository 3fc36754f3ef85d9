"""Conditional task reallocation of ATA-HRL (optional plugin ``ctr``).

One component, ``ctr``, fills two slots: as the condition policy pi_C it decides at each epoch
whether to reallocate; as the reallocation policy pi_TR it gives the new triples of the POIs not
yet committed. Both are heads on one GRU that reads, each epoch, the state representation (raw
and reconstructed S, mean-pooled), the inherent information and the previous allocation. In the
options framework: pi_C's option starts at every epoch t >= 1 and terminates after its one
decision; pi_TR's option starts only when pi_C says yes, and terminates once it has reallocated.
With ``condition = "always"`` pi_TR runs every epoch (the w/o.C ablation).
"""

from __future__ import annotations

import numpy as np
import torch

from ata import hookimpl
from ata.core.state import Allocation, DecisionContext
from ata.learn import nets
from ata.learn.features import inherent_features, masks_for, state_features, to_tensors
from ata.learn.runtime import LearnedComponent
from ata.plugins.policies.attention import scenario_uniforms


def reconstructed_features(ctx: DecisionContext) -> dict[str, np.ndarray]:
    """S as the reconstructors estimate it: the aux outputs where present, else the raw S."""
    rec = ctx.reconstructed
    feats = state_features(ctx.observed, fatigue=rec.get("aux_fatigue"))
    for group in ("robots", "tasks"):
        if f"aux_{group}" in rec:
            feats[group] = rec[f"aux_{group}"]
    return feats


class CTRPolicy(LearnedComponent):
    """pi_C and pi_TR on one GRU state; the state advances once per epoch."""

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self.hidden: torch.Tensor | None = None
        self.epoch = -1
        self.out = None

    def _step(self, ctx: DecisionContext):
        """Advance the GRU to this epoch (once), caching the heads' outputs."""
        if self.epoch == ctx.epoch:
            return self.out
        B = ctx.reallocatable.shape[0]
        if self.hidden is None:
            self.hidden = self.net.initial_hidden(B)
        with torch.set_grad_enabled(self.training):
            self.out = self.net.ctr_step(
                to_tensors(inherent_features(ctx.inherent)),
                to_tensors(state_features(ctx.observed)),
                to_tensors(reconstructed_features(ctx)),
                torch.as_tensor(ctx.previous.stack()), self.hidden,
                masks_for(ctx.inherent, ctx.observed))
        self.hidden = self.out[2]
        self.epoch = ctx.epoch
        return self.out

    @hookimpl
    def ata_should_reallocate(self, ctx: DecisionContext) -> np.ndarray:
        cond, _, _ = self._step(ctx)
        with torch.set_grad_enabled(self.training):
            decide, logp = nets.bernoulli(
                cond, self.settings.sample or self.training, self.generator,
                None if self.training else ctx.rng.uniform("ctr.condition", ctx.epoch))
            if self.training:
                p = torch.sigmoid(cond)
                ent = -(p * torch.log(p + 1e-9) + (1 - p) * torch.log(1 - p + 1e-9))
                self.recorder.cond_logp.append(logp)
                self.recorder.cond_entropy.append(ent)
        return decide.numpy().copy()

    @hookimpl
    def ata_reallocate(self, ctx: DecisionContext, active: np.ndarray) -> Allocation:
        _, logits, _ = self._step(ctx)
        with torch.set_grad_enabled(self.training):
            triples = nets.choose(logits, self.settings.sample or self.training, self.generator,
                                  None if self.training else scenario_uniforms(ctx, "ctr",
                                                                               logits))
            if self.training:
                movable = torch.as_tensor(ctx.reallocatable & active[:, None])
                lp = nets.log_prob(logits, triples)
                self.recorder.tr_logp.append((lp * movable).sum(1))
                self.recorder.tr_entropy.append((nets.entropy(logits) * movable).sum(1)
                                                / movable.sum(1).clamp(min=1))
        return Allocation.from_stack(triples.detach().numpy())


@hookimpl
def ata_register_components(register) -> None:
    register("condition", "ctr", CTRPolicy)
    register("policy", "ctr", CTRPolicy)
