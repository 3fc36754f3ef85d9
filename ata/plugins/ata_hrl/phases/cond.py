"""The cond phase (``cond_scenarios`` > 0, before ctr): pi_C's logistic rule, fitted to labels
from counterfactual rollouts.

Each of ``cond_scenarios`` training scenarios per team setting and level of ``cond_levels`` is
run once as the policy decides (every decision by its mode), recording pi_C's inputs, and then,
on the same random streams, once per labelled epoch with pi_C's decision there turned over. The
difference of the two runs' expected points from that epoch on says which choice was better and
by how much. The rule is a weighted, L2-penalised (``cond_l2``) logistic regression of
"re-planning did better" on pi_C's ten condition features at the labelled event epochs (the
features standardised over them, each epoch weighted by its difference), solved by Newton's
method; once fitted, it decides pi_C's event epochs in the network's place (quiet epochs stay
the network's). One step of classification-based policy iteration.

Each round of ``cond_rounds`` is one step of the phase, checkpointed and validated. The first
labels the epochs where the policy re-plans, with the rule off; each later round labels every
event epoch with the rule of the round before deciding (re-planned or skipped, turned over
either way) and fits the rule to those labels alone (approximate policy iteration).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import torch

from ata.core.kernel import Simulation
from ata.core.settings import param
from ata.plugins.ata_hrl import decode as D
from ata.plugins.ata_hrl.components import Recorder
from ata.plugins.ata_hrl.features import GROUPS
from ata.plugins.ata_hrl.network import to_tensors
from ata.plugins.ata_hrl.phases import FIRST_ID
from ata.plugins.ata_hrl.phases.ctr import tr_from_ita
from ata.plugins.ata_hrl.rewards import to_go
from ata.training import Phase
from ata.plugins.ata_hrl.phases.host import Host



@dataclass
class Settings:
    """The cond phase's keys of ``[ata_hrl]``."""

    cond_scenarios: int = param(0, min=0, help="cond: training scenarios per team setting and "
                                "level of cond_levels whose labels pi_C's rule is fitted to "
                                "(0: no cond phase)")
    cond_levels: list[str] = param(["high"], choices=("none", "low", "medium", "high"),
                                   help="cond: uncertainty levels of the labelling rollouts")
    cond_rounds: int = param(1, min=1, help="cond: rounds of labels and fit; from the second "
                             "on, the labels are collected with the rule of the round before "
                             "deciding, at every event epoch, and the rule is fitted to them "
                             "alone (approximate policy iteration)")
    cond_l2: float = param(1e-2, min=0.0, help="cond: the L2 penalty of the rule's logistic "
                           "regression, on its standardised features")


class CondPhase:
    """The cond phase of a trainer (see the module's doc)."""

    name = "cond"

    def __init__(self, trainer: Host):
        self.tr = trainer
        self.last: dict[str, float] = {}

    def phase(self) -> Phase:
        return Phase(self.name, self.tr.phases()[self.name], self.step, checkpoint_every=1,
                     eval_every=1, validate=lambda: self.tr.validate(self.name),
                     validate_first=True, fresh_best=True, start=self.start,
                     end=lambda: self.last)

    def start(self) -> None:
        if self.tr.trains_ita and self.tr.counters["ctr"] == 0:
            tr_from_ita(self.tr.net)       # pi_TR as the CTR phase's step 0 has it

    def pairs(self) -> list[str]:
        s = self.tr.s
        return [f"{t}/{lv}" for lv in s.cond_levels for t in s.team_settings]

    def step(self, k: int) -> tuple[dict[str, Any], int]:
        """Round k: labels, the rule fitted to them, and the rule's loss on them."""
        pairs = self.pairs()
        batches = self.labels(pairs)
        fit_rule(self.tr.net.cond.rule, batches, self.tr.s.cond_l2)
        with torch.no_grad():
            loss = self.loss(batches)
        gain = np.concatenate([b["weight"][b["labelled"]] for b in batches])
        better = np.concatenate([(b["target"] != b["taken"])[b["labelled"]] for b in batches])
        self.last = {"cond_turned_over": int(gain.size),
                     "cond_other_better": float(better.mean()) if better.size else 0.0,
                     "cond_mean_abs_gain": float(gain.mean()) if gain.size else 0.0}
        return {"setting": ",".join(pairs), "loss": f"{loss.item():.4f}"}, \
            sum(b["episodes"] for b in batches)

    def labels(self, pairs: list[str]) -> list[dict[str, Any]]:
        """`batch` over the phase's training scenarios of every pair, batch_size at a time."""
        s, run = self.tr.s, self.tr.loop.run
        batches = []
        for j, pair in enumerate(pairs):
            mission = self.tr.mission_of(pair, s.seed)
            first = FIRST_ID["cond"] + j * s.cond_scenarios
            for lo in range(0, s.cond_scenarios, s.batch_size):
                ids = first + np.arange(lo, min(lo + s.batch_size, s.cond_scenarios))
                batches.append(self.batch(mission, ids))
                if run is not None:
                    done = j * s.cond_scenarios + lo + ids.size
                    run.tell({"phase": "cond", "step": f"rollouts of {done} of "
                              f"{len(pairs) * s.cond_scenarios} scenarios"})
        return batches

    def batch(self, mission, ids: np.ndarray) -> dict[str, Any]:
        """Counterfactual labels of pi_C's decisions on scenarios `ids`: the policy as it
        decides, recording pi_C's inputs; then, on the same random streams, one run per
        scenario and labelled epoch with the decision there turned over. Each labelled epoch's
        target is the choice that did better from that epoch on, its weight by how much."""
        tr = self.tr
        rec = Recorder()
        with torch.no_grad():
            base = Simulation(mission, tr.registry, ids, overrides=tr.overrides(
                mission, "ctr", rec, D.argmax_chooser)).run()
        taken = np.stack(rec.cond_choice, 1)                      # (B, T-1): epochs 1..T-1
        B, E1 = taken.shape
        if tr.net.cond.rule_on():   # the rule decides event epochs: each of them, either way
            labelled = np.stack(rec.cond_prior, 1) > 0
        else:                       # where the policy re-planned
            labelled = taken
        sb, se = np.nonzero(labelled)
        gain = np.zeros((B, E1))
        if sb.size:
            overrides = tr.overrides(mission, "ctr", None, None)
            overrides["condition"].flip_at = se + 1
            with torch.no_grad():
                flipped = Simulation(mission, tr.registry, ids[sb], overrides=overrides).run()
            go_b, go_f = to_go(base.r_expected), to_go(flipped.r_expected)
            gain[sb, se] = go_f[np.arange(sb.size), se + 1] - go_b[sb, se + 1]
        with torch.no_grad():
            emb_i = tr.net.tr.encoder(to_tensors(rec.inherent))
            pooled = torch.stack([torch.cat([e[g] for g in GROUPS], 1).mean(1) for e in (
                tr.net.tr.embed(emb_i, to_tensors(raw), to_tensors(seen))
                for raw, seen in rec.cond_state)], 1)              # (B, T-1, d)
        return {"pooled": pooled, "feats": torch.as_tensor(np.stack(rec.cond_feats, 1)),
                "prior": torch.as_tensor(np.stack(rec.cond_prior, 1)), "taken": taken,
                "labelled": labelled, "target": taken ^ (gain > 0), "weight": np.abs(gain),
                "episodes": B + sb.size}

    def loss(self, batches: list[dict[str, Any]]) -> torch.Tensor:
        """pi_C's cross-entropy against the better choices at the labelled epochs, weighted by
        how much better (how well pi_C, with its rule, fits the labels)."""
        net = self.tr.net
        total, weight = torch.zeros(()), 0.0
        for b in batches:
            E, E1, _ = b["pooled"].shape
            hidden = torch.zeros(E, net.cfg.d_model)
            logits = []
            for k in range(E1):
                logit, hidden = net.cond(b["pooled"][:, k], b["feats"][:, k], b["prior"][:, k],
                                         hidden)
                logits.append(logit)
            w = torch.as_tensor(b["weight"] * b["labelled"], dtype=torch.float32)
            bce = torch.nn.functional.binary_cross_entropy_with_logits(
                torch.stack(logits, 1), torch.as_tensor(b["target"], dtype=torch.float32),
                reduction="none")
            total = total + (w * bce).sum()
            weight += float(w.sum())
        return total / max(weight, 1e-9)


def logistic_newton(X: np.ndarray, t: np.ndarray, w: np.ndarray, l2: float,
                    iters: int = 100) -> np.ndarray:
    """The weights (last: the bias) minimising the w-weighted mean cross-entropy of a logistic
    regression of t on X, plus l2/2 times their squared norm, by Newton's method."""
    Xb = np.c_[X, np.ones(len(X))]
    wn = w / max(float(w.sum()), 1e-12)
    b = np.zeros(Xb.shape[1])
    for _ in range(iters):
        p = 1.0 / (1.0 + np.exp(-(Xb @ b)))
        grad = Xb.T @ ((p - t) * wn) + l2 * b
        hess = (Xb * (wn * p * (1 - p))[:, None]).T @ Xb + l2 * np.eye(len(b))
        step = np.linalg.solve(hess + 1e-12 * np.eye(len(b)), grad)
        b -= step
        if np.abs(step).max() < 1e-10:
            break
    return b


def fit_rule(rule: torch.nn.Linear, batches: list[dict[str, Any]], l2: float) -> None:
    """`rule` becomes the logit of "re-planning does better" at the labelled event epochs, a
    logistic regression on the condition features (standardised over those epochs, the
    standardisation folded into the layer), each epoch weighted by how much better the better
    choice was; it is switched on."""
    F, t, w = [], [], []
    for b in batches:
        m = b["labelled"] & (b["prior"].numpy() > 0)
        F.append(b["feats"].numpy()[m])
        t.append(b["target"][m])
        w.append(b["weight"][m])
    F, t, w = (np.concatenate(x).astype(np.float64) for x in (F, t, w))
    if len(F) == 0 or w.sum() <= 0:
        raise RuntimeError("the cond phase labelled no event epoch: nothing to fit a rule on "
                           "(more cond_scenarios, or a level with events)")
    mu, sd = F.mean(0), F.std(0) + 1e-9
    beta = logistic_newton((F - mu) / sd, t, w, l2)
    with torch.no_grad():
        rule.weight.copy_(torch.as_tensor(beta[:-1] / sd)[None])
        rule.bias.copy_(torch.as_tensor([beta[-1] - float(np.sum(beta[:-1] * mu / sd))]))
        rule.on.fill_(1.0)
