"""A trainer's update scores the legal candidates of the decisions that have a choice alone
(`decode.trace_log_prob` through `StepScorer.rows`): its log-probabilities, entropies and their
gradients are those of the dense forward pass over every padded (step, episode, candidate),
up to float32 rounding."""

from __future__ import annotations

import copy

import numpy as np
import pytest
import torch

from ata.plugins.ata_hrl import decode as D
from ata.plugins.ata_hrl import logprob
from ata.plugins.ata_hrl.checkpoint import load_net
from ata.plugins.ata_hrl.inputs import StepInputs
from ata.plugins.ata_hrl.network import FEATURES, KINDS, ATAHRLNet, step_context


def _dense(net, emb, trace, residual):
    """The log-probabilities and entropies by the dense forward pass (`StepScorer.forward` on
    (S, E, N) with the illegal candidates masked), decisions without a choice weighing 0."""
    E = emb["tasks"].shape[0]
    logp, ent = torch.zeros(E), torch.zeros(E)
    for kind in KINDS:
        st = trace.stacked(kind)
        mask = torch.from_numpy(st["mask"])
        n = mask.shape[-1]
        ctx = step_context(kind, emb, {"robot": torch.from_numpy(st["robot"]),
                                       "task": torch.from_numpy(st["task"])})
        logits = net.scorers[kind](torch.from_numpy(st["features"]),
                                   net.candidates(kind, emb)[:, :n], ctx,
                                   torch.from_numpy(st["prior"]), mask, residual)
        lsm = torch.log_softmax(logits, -1)
        chosen = lsm.gather(-1, torch.from_numpy(st["choice"]).long()[..., None])[..., 0]
        free = (mask.sum(-1) > 1) & torch.from_numpy(st["active"])
        logp = logp + torch.where(free, chosen, 0.0).sum(0)
        ent = ent + torch.where(free, -(lsm.exp() * lsm.clamp(min=-30)).sum(-1), 0.0).sum(0)
    return logp, ent


def _trace(net, rng: np.random.Generator, S=9, E=6, P=13, R=5, H=4):
    """A decode's trace of random steps: some decisions with one legal candidate or none,
    some episodes done."""
    d = net.auto.shape[0]
    emb = {g: torch.as_tensor(rng.normal(0, 1, (E, n, d)), dtype=torch.float32)
           for g, n in (("tasks", P), ("robots", R), ("humans", H))}
    sizes = {"poi": P, "robot": R, "nav": H + 1, "cls": H + 1}
    trace = D.DecodeTrace()
    for _ in range(S):
        for kind in KINDS:
            N = sizes[kind]
            mask = rng.uniform(size=(E, N)) < 0.6
            mask[0] = False
            mask[1] = np.arange(N) == 2                       # one choice: no mass
            mask[2, 0] = True
            active = rng.uniform(size=E) < 0.85
            choice = np.array([rng.choice(np.nonzero(m)[0]) if m.any() else 0 for m in mask])
            inp = StepInputs(rng.normal(0, 1, (E, N, FEATURES[kind])).astype(np.float32),
                             mask, rng.normal(0, 0.05, (E, N)), active)
            trace.add(kind, inp, mask, choice, active, rng.integers(0, R, E),
                      rng.integers(0, P, E))
    return emb, trace


def _grads(net) -> torch.Tensor:
    return torch.cat([p.grad.reshape(-1) for p in net.parameters() if p.grad is not None])


@pytest.mark.parametrize("residual", [True, False])
@pytest.mark.parametrize("weights", ["shipped", "drawn"])
def test_the_update_scores_the_rows_that_count_as_the_dense_forward_does(residual, weights):
    rng = np.random.default_rng(5)
    if weights == "shipped":
        net = copy.deepcopy(load_net("builtin:ata_hrl_a"))  # the cached one keeps no grads
    else:
        torch.manual_seed(11)
        net = ATAHRLNet()
        for scorer in net.ita.scorers.values():       # the output layers start at zero
            torch.nn.init.normal_(scorer.out[3].weight, std=0.3)
            torch.nn.init.normal_(scorer.linear.weight, std=0.3)
    net = net.ita
    emb, trace = _trace(net, rng)
    got, want = [], []
    for fn, out in ((lambda: logprob.trace_log_prob(net, emb, trace, residual), got),
                    (lambda: _dense(net, emb, trace, residual), want)):
        net.zero_grad()
        logp, ent = fn()
        (logp.sum() + 0.1 * ent.sum()).backward()
        out += [logp.detach(), ent.detach(), _grads(net)]
    for a, b in zip(got, want):
        assert a.shape == b.shape
        torch.testing.assert_close(a, b, rtol=1e-5, atol=1e-4)
    # the learned part and the prior both reach the result: not a trivially equal zero
    assert (want[0][:2] == 0).all() and (want[1][:2] == 0).all()   # no choice, no mass
    assert want[0][2:].abs().min() > 0.1 and want[1][2:].abs().min() > 0.1
    assert (want[2] != 0).sum() > (100 if residual else 2)
