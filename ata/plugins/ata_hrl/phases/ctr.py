"""The CTR phase: pi_C and pi_TR after the ITA (frozen, decoding by its mode), by shared-baseline
policy gradient, each decision at epoch t credited with the paper's R_C (pi_C) or R_TR (pi_TR)
from epoch t on (both are sums of per-epoch terms, and a decision cannot change the terms of the
epochs before it).

pi_TR starts as a copy of the trained ITA (``tr_from_ita``): at the phase's step 0 it decodes as
the ITA learned to, with greedy's keep-or-repair prior.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Iterator

import numpy as np
import torch

from ata.core.settings import param
from ata.plugins.ata_hrl import logprob
from ata.plugins.ata_hrl.components import Recorder
from ata.plugins.ata_hrl.features import GROUPS
from ata.plugins.ata_hrl.network import encode_once, to_tensors
from ata.plugins.ata_hrl.phases.policy import PolicyPhase, per_epoch_advantage, scaled


@dataclass
class Settings:
    """The CTR phase's keys of ``[ata_hrl]``."""

    ctr_steps: int = param(200, min=0, help="ctr: steps of the pi_C / pi_TR phase")
    ctr_lr: float = param(1e-3, min=0.0, max=1.0, help="ctr: Adam learning rate of the pi_C / "
                          "pi_TR phase")


def tr_from_ita(net) -> None:
    """pi_TR's encoder and decoder scorers as the ITA's, its state embedding and keep step at
    zero: at the start of the CTR phase pi_TR decodes exactly as the trained ITA (a pure
    function of the ITA's weights, so a resumed run does the same)."""
    tr, ita = net.tr, net.ita
    with torch.no_grad():
        tr.encoder.load_state_dict(ita.encoder.state_dict())
        tr.scorers.load_state_dict(ita.scorers.state_dict())
        tr.auto.copy_(ita.auto)
        tr.onboard.copy_(ita.onboard)
        for layer in [*tr.state.values(), tr.keep.out[-1], tr.keep.linear]:
            torch.nn.init.zeros_(layer.weight)
            torch.nn.init.zeros_(layer.bias)


class CtrPhase(PolicyPhase):
    """The CTR phase of a trainer (see the module's doc)."""

    name = "ctr"

    def lr(self) -> float:
        return self.tr.s.ctr_lr

    def fresh_best(self) -> bool:
        # the first phase that reallocates starts best.pt afresh (the ITA's validation never
        # reallocated); with a cond phase, that phase is the first
        return self.tr.phases()["cond"] == 0

    def start(self) -> None:
        super().start()
        if self.tr.counters["ctr"] == 0 and self.tr.trains_ita:
            tr_from_ita(self.tr.net)

    def parts(self, rec: Recorder, R: dict[str, np.ndarray]
              ) -> Iterator[Callable[[], torch.Tensor]]:
        """One part: pi_C's and pi_TR's terms (each scenario's samples encoded once)."""
        yield lambda: self.part(rec, R)

    def part(self, rec: Recorder, R: dict[str, np.ndarray]) -> torch.Tensor:
        """pi_C's and pi_TR's terms of the loss."""
        tr, K, dev = self.tr, self.tr.s.samples, self.tr.device
        net = tr.net
        loss = torch.zeros((), device=dev)
        emb_i = encode_once(net.tr.encoder, rec.inherent, dev)
        if tr.trains_cond and rec.cond_choice:
            # pi_C decides at epochs 1 .. T-1: each decision against R_C from its epoch on
            logp = condition_log_prob(net, rec, emb_i)                   # (E, T-1)
            adv = per_epoch_advantage(R["R_C_to_go"][:, 1:], K)
            loss = loss + -(scaled(adv, dev) * logp).sum() / adv.shape[0]
        if tr.trains_tr and rec.tr:
            adv_all = per_epoch_advantage(R["R_TR_to_go"], K)
            terms, advs = [], []
            for item in rec.tr:
                rows = torch.as_tensor(item["rows"], device=dev)
                emb = net.tr.embed({g: v[rows] for g, v in emb_i.items()},
                                   to_tensors(item["raw"], dev), to_tensors(item["seen"], dev))
                terms.append(logprob.trace_log_prob(net.tr, emb, item["trace"])[0])
                advs.append(adv_all[item["rows"], item["epoch"]])
            loss = loss - (scaled(np.concatenate(advs), dev) * torch.cat(terms)).sum() \
                / R["total"].size
        return loss


def condition_log_prob(net, rec: Recorder, emb_i: dict[str, torch.Tensor]) -> torch.Tensor:
    """pi_C's log-probabilities of its recorded decisions, (E, epochs decided)."""
    E, dev = rec.cond_feats[0].shape[0], emb_i["tasks"].device
    hidden = torch.zeros(E, net.cfg.d_model, device=dev)
    logps = []
    for k, (raw, seen) in enumerate(rec.cond_state):
        emb = net.tr.embed(emb_i, to_tensors(raw, dev), to_tensors(seen, dev))
        pooled = torch.cat([emb[g] for g in GROUPS], 1).mean(1)
        logit, hidden = net.cond(pooled, torch.as_tensor(rec.cond_feats[k], device=dev),
                                 torch.as_tensor(rec.cond_prior[k], device=dev), hidden)
        two = torch.log_softmax(torch.stack([torch.zeros_like(logit), logit], -1), -1)
        choice = torch.as_tensor(rec.cond_choice[k], device=dev).long()
        logps.append(two.gather(-1, choice[:, None])[:, 0])
    return torch.stack(logps, 1)
