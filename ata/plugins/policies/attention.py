"""The attention-based initial task allocation of ATA-HRL (optional plugin ``ita``).

Per-type embeddings of humans, robots and tasks with positional embeddings, a self-attention
encoder over all of them, and per-task logits over robots, navigators and classifiers with
action masks (only highly skilled humans navigate; robots observed down are not chosen). Any
team size works, so one network serves settings (a) and (b).
"""

from __future__ import annotations

import numpy as np
import torch

from ata import hookimpl
from ata.core.state import Allocation, DecisionContext
from ata.learn import nets
from ata.learn.features import inherent_features, masks_for, to_tensors
from ata.learn.runtime import LearnedComponent


def scenario_uniforms(ctx: DecisionContext, stream: str,
                      logits: dict[str, torch.Tensor]) -> dict[str, np.ndarray]:
    """Per-scenario uniforms for sampling a choice at this epoch (batch-independent)."""
    return {key: ctx.rng.uniform(f"{stream}.{key}", ctx.epoch, tuple(lg.shape[1:]))
            for key, lg in logits.items()}


class AttentionITA(LearnedComponent):
    """Initial allocation from the attention network; as a reallocation policy it keeps the
    allocation (an ITA-only method)."""

    @hookimpl
    def ata_initial_allocation(self, ctx: DecisionContext) -> Allocation:
        training = self.training
        with torch.set_grad_enabled(training):
            feats = to_tensors(inherent_features(ctx.inherent))
            masks = masks_for(ctx.inherent, None)
            logits = self.net.ita_logits(feats, masks)
            triples = nets.choose(logits, self.settings.sample or training, self.generator,
                                  None if training else scenario_uniforms(ctx, "attention",
                                                                          logits))
            if training:
                self.recorder.ita_logp = nets.log_prob(logits, triples).sum(1)
                self.recorder.ita_entropy = nets.entropy(logits).mean(1)
        return Allocation.from_stack(triples.detach().numpy())

    @hookimpl
    def ata_reallocate(self, ctx: DecisionContext, active: np.ndarray) -> Allocation:
        return ctx.previous


@hookimpl
def ata_register_components(register) -> None:
    register("policy", "attention", AttentionITA)
