"""The compiled scorer (ata.plugins.ata_hrl.scorer_loop) against the network's own
(`StepScorer.forward`, torch): the same logits up to float32 rounding for every sub-decision,
with the shipped weights and with freshly drawn ones, NEG where a candidate is not legal; and
each episode's logits the same bits whatever the other episodes of its batch."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from ata.plugins.ata_hrl import scorer_loop
from ata.plugins.ata_hrl.checkpoint import load_net
from ata.plugins.ata_hrl.network import FEATURES, KINDS, NEG, ATAHRLNet, step_context


def _inputs(kind: str, net, rng: np.random.Generator, E: int = 7, P: int = 11, R: int = 5,
            H: int = 4):
    d = net.auto.shape[0]
    emb = {"tasks": torch.as_tensor(rng.normal(0, 1, (E, P, d)), dtype=torch.float32),
           "robots": torch.as_tensor(rng.normal(0, 1, (E, R, d)), dtype=torch.float32),
           "humans": torch.as_tensor(rng.normal(0, 1, (E, H, d)), dtype=torch.float32)}
    cand = net.candidates(kind, emb)
    N = cand.shape[1]
    feats = rng.normal(0, 1, (E, N, FEATURES[kind])).astype(np.float32)
    prior = rng.normal(0, 0.05, (E, N))
    mask = rng.uniform(size=(E, N)) < 0.7
    mask[0] = False                                     # an episode with nothing legal
    robot, task = rng.integers(0, R, E), rng.integers(0, P, E)
    return emb, cand, feats, prior, mask, robot, task


def _both(kind: str, net, emb, cand, feats, prior, mask, robot, task, residual=True):
    scorer = net.scorers[kind]
    with torch.no_grad():
        ctx = step_context(kind, emb, {"robot": torch.as_tensor(robot),
                                       "task": torch.as_tensor(task)})
        want = scorer(torch.as_tensor(feats), cand, ctx,
                      torch.as_tensor(prior, dtype=torch.float32), torch.as_tensor(mask),
                      residual).numpy()
    w = scorer_loop.weights({f"s.{k}": v.detach().numpy()
                             for k, v in scorer.state_dict().items()}, "s")
    E, N, d = cand.shape
    hid = scorer_loop.project(np.ascontiguousarray(cand.detach().numpy()).reshape(E * N, d),
                              w.cand_w).reshape(E, N, -1)
    got = scorer_loop.logits(kind, w, feats, prior, mask, hid,
                             np.ascontiguousarray(emb["tasks"].numpy()),
                             np.ascontiguousarray(emb["robots"].numpy()), robot, task, residual)
    return got, want


@pytest.mark.parametrize("weights", ["shipped", "drawn"])
@pytest.mark.parametrize("kind", KINDS)
def test_the_compiled_logits_are_the_networks(kind, weights):
    if weights == "shipped":
        net = load_net("builtin:ata_hrl_b_ft").tr
    else:
        torch.manual_seed(5)
        net = ATAHRLNet().tr
        for scorer in net.scorers.values():        # learned residuals away from zero
            for p in scorer.parameters():
                torch.nn.init.normal_(p, 0.0, 0.3)
    rng = np.random.default_rng(len(kind))
    inputs = _inputs(kind, net, rng)
    mask = inputs[4]
    for residual in (True, False):
        got, want = _both(kind, net, *inputs, residual=residual)
        assert got.dtype == np.float32 and got.shape == want.shape
        assert np.all(got[~mask] == np.float32(NEG)) and np.all(want[~mask] == np.float32(NEG))
        assert np.allclose(got[mask], want[mask], rtol=1e-5, atol=1e-4), \
            np.abs(got[mask] - want[mask]).max()
        if residual:        # the learned part is there: it moves the logits off the prior's
            _, prior_only = _both(kind, net, *inputs, residual=False)
            assert np.abs(got[mask] - prior_only[mask]).max() > 1e-3


def test_an_episodes_logits_do_not_depend_on_its_batch():
    net = load_net("builtin:ata_hrl_b_ft").tr
    rng = np.random.default_rng(0)
    for kind in KINDS:
        emb, cand, feats, prior, mask, robot, task = _inputs(kind, net, rng, E=9)
        whole, _ = _both(kind, net, emb, cand, feats, prior, mask, robot, task)
        for rows in (np.array([4]), np.array([8, 1, 3])):
            part, _ = _both(kind, net, {g: v[rows] for g, v in emb.items()}, cand[rows],
                            feats[rows], prior[rows], mask[rows], robot[rows], task[rows])
            assert np.array_equal(part, whole[rows]), kind
