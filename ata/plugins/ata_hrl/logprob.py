"""What a training update needs of a decode, with torch: the sampler of a training rollout and
the log-probabilities of a recorded decode's choices, with their gradient (the rollout itself
decides in numpy, ``decode`` with ``infer``'s networks)."""

from __future__ import annotations

import numpy as np
import torch

from ata.plugins.ata_hrl.arch import KINDS, NEG
from ata.plugins.ata_hrl.decode import Chooser, DecodeTrace
from ata.plugins.ata_hrl.network import AllocationNet, step_context


def torch_sampler(generator: torch.Generator) -> Chooser:
    """Sample every choice from the softmax of its logits with torch's generator (training)."""

    def choose(kind: str, logits: np.ndarray) -> np.ndarray:
        u = torch.rand(logits.shape, generator=generator).clamp(1e-12, 1 - 1e-12)
        return (torch.from_numpy(logits) - torch.log(-torch.log(u))).argmax(-1).numpy()

    return choose


def trace_log_prob(net: AllocationNet, emb: dict[str, torch.Tensor], trace: DecodeTrace,
                   residual: bool = True, decisions: list | None = None
                   ) -> tuple[torch.Tensor, torch.Tensor]:
    """Sum over the decode's steps of each episode's log-probability of its choices, and of
    the entropies of the sub-decisions, both (E,), with gradient. With a list `decisions`,
    each choice's own log-probability is appended to it too, as (log-probabilities, their
    episodes) pairs of tensors, in an order fixed by the trace."""
    E, dev = emb["tasks"].shape[0], emb["tasks"].device

    def tensor(a: np.ndarray) -> torch.Tensor:             # on the network's device
        return torch.from_numpy(a).to(dev)

    logp = torch.zeros(E, device=dev)
    ent = torch.zeros(E, device=dev)
    if trace.keep is not None:
        k = trace.keep
        mask = tensor(k["mask"])
        logits = net.keep(tensor(k["features"]), emb["tasks"], tensor(k["prior"]), mask,
                          residual)
        lsm = torch.log_softmax(logits, -1)
        free = tensor(k["decided"]) & (mask.sum(-1) > 1)
        choice = tensor(k["choice"].astype(np.int64))
        chosen = torch.where(free, lsm.gather(-1, choice[..., None])[..., 0], 0.0)
        logp = logp + chosen.sum(-1)
        if decisions is not None:
            episodes = torch.arange(E, device=dev).view(-1, *[1] * (chosen.dim() - 1))
            decisions.append((chosen.reshape(-1), episodes.expand_as(chosen).reshape(-1)))
        ent = ent - torch.where(free, (lsm.exp() * lsm.clamp(min=-30)).sum(-1), 0.0).sum(-1)
    if trace.n_steps == 0:
        return logp, ent
    for kind in KINDS:
        st = trace.stacked(kind)                               # (S, E, ...) a step each
        mask = st["mask"]
        # a decision with one legal choice (or of an episode whose decoding is over) carries
        # no probability mass: scored are the legal candidates of the others alone
        ks, ke = np.nonzero((mask.sum(-1) > 1) & st["active"])
        if ks.size == 0:
            continue
        K, n = ks.size, mask.shape[-1]
        rk, rn = np.nonzero(mask[ks, ke])                      # the rows: (decision, candidate)
        cand = net.candidates(kind, emb)[:, :n]                  # (E, N, d)
        idx = {"robot": tensor(st["robot"]), "task": tensor(st["task"])}
        ctx = step_context(kind, emb, idx)[tensor(ks), tensor(ke)]     # (K, d)
        rows = net.scorers[kind].rows(
            tensor(st["features"][ks[rk], ke[rk], rn]), cand.reshape(-1, cand.shape[-1]), ctx,
            tensor(st["prior"][ks[rk], ke[rk], rn]), tensor(ke[rk] * n + rn), tensor(rk),
            residual)
        logits = torch.full((K, n), NEG, dtype=rows.dtype, device=dev).index_put(
            (tensor(rk), tensor(rn)), rows)
        lsm = torch.log_softmax(logits, -1)
        choice = tensor(st["choice"][ks, ke].astype(np.int64))
        episode = tensor(ke)
        chosen = lsm.gather(-1, choice[:, None])[:, 0]
        logp = logp.index_add(0, episode, chosen)
        if decisions is not None:
            decisions.append((chosen, episode))
        ent = ent.index_add(0, episode, -(lsm.exp() * lsm.clamp(min=-30)).sum(-1))
    return logp, ent
