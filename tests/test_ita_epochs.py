"""Several updates on one ITA rollout (``[ata_hrl] ita_epochs``): each decision's log-probability
as the update scores it, and the clipped-ratio updates after the first (phases/ita.py)."""

from __future__ import annotations

import numpy as np
import torch

from _support import hrl_session as session
from ata.plugins.ata_hrl import logprob
from ata.plugins.ata_hrl.network import encode_once
from ata.plugins.ata_hrl.phases.policy import rewards
from ata.session import build_trainer


def _rollout(*extra: str):
    tr = build_trainer(session("ata_hrl.batch_size=4", "ata_hrl.threads=1", *extra))
    tr.ita.start()
    record, rec = tr.rollout(tr.mission_of("custom", 7), np.repeat(np.arange(4), 2), "ita",
                             train=True)
    return tr, rec, rewards(record)


def _gradient(tr, parts) -> list[torch.Tensor]:
    tr.opt.zero_grad()
    for part in parts:
        part().backward()
    return [p.grad.clone() if p.grad is not None else torch.zeros_like(p)
            for p in tr.net.ita.parameters()]


def test_each_decision_s_log_probability_adds_up_to_its_episode_s():
    tr, rec, _ = _rollout()
    emb = encode_once(tr.net.ita.encoder, rec.inherent, tr.device)
    decisions: list = []
    with torch.no_grad():
        logp, _ = logprob.trace_log_prob(tr.net.ita, emb, rec.ita, decisions=decisions)
        alone, _ = logprob.trace_log_prob(tr.net.ita, emb, rec.ita)
    assert torch.equal(logp, alone)                  # asking for the decisions changes nothing
    values = torch.cat([d for d, _ in decisions])
    episodes = torch.cat([e for _, e in decisions])
    assert values.numel() > logp.numel()             # several decisions an episode
    assert (values <= 0).all() and (values < -1e-6).any()
    by_episode = torch.zeros_like(logp).index_add(0, episodes, values)
    torch.testing.assert_close(by_episode, logp, rtol=1e-5, atol=1e-4)


def test_a_clipped_update_at_the_sampled_weights_has_the_first_update_s_gradient():
    tr, rec, R = _rollout("ata_hrl.ita_epochs=2")
    tr.ita._sampled = {}
    first = _gradient(tr, list(tr.ita.parts(rec, R)))
    assert tr.ita._sampled, "the first update keeps the sampled probabilities"
    again = _gradient(tr, list(tr.ita.parts(rec, R)))         # ratio 1 everywhere
    assert any(g.abs().sum() > 0 for g in first)
    for a, b in zip(first, again):
        torch.testing.assert_close(a, b, rtol=1e-4, atol=1e-7)
    # with the weights moved, the clipped objective is PPO's pessimistic bound: a decision
    # counts at its clipped ratio where that lowers the objective, so the loss rises as the
    # clip narrows, and with no clip at all (ratios within 0 and 2) it is the plain ratio's
    with torch.no_grad():
        for p in tr.net.ita.parameters():
            p.add_(0.05 * torch.randn(p.shape, generator=torch.Generator().manual_seed(1)))
    losses = {}
    for clip in (0.0, 0.01, 1.0):
        tr.s.ita_clip = clip
        with torch.no_grad():
            losses[clip] = sum(part().item() for part in tr.ita.parts(rec, R))
    assert losses[0.0] >= losses[0.01] >= losses[1.0] and losses[0.0] > losses[1.0]


def test_two_updates_a_rollout_move_the_weights_on_from_one():
    states = []
    for epochs in (1, 2):
        tr, rec, R = _rollout(f"ata_hrl.ita_epochs={epochs}")
        loss = tr.ita.learn(rec, R)
        states.append((loss, {k: v.clone() for k, v in tr.net.ita.state_dict().items()},
                       tr.opt.state_dict()["state"][0]["step"]))
    (loss1, one, steps1), (loss2, two, steps2) = states
    assert loss1 == loss2                            # the first update's loss is reported
    assert float(steps2) == 2 * float(steps1)        # two Adam steps on the rollout
    assert any(not torch.equal(one[k], two[k]) for k in one)
    assert tr.ita._sampled is None                   # nothing kept past the step
