"""A `StepScorer`'s logits at decode time, compiled: one numba loop over the episodes and their
legal candidates, each candidate's perceptron computed by itself (its context token, hidden
layers, output and direct path), in float32 as the network is.

Why: a decode takes thousands of sub-decisions, and torch pays some tens of microseconds for each
of the dozen small operations a sub-decision's scorer is, whatever the rows; here a sub-decision
is one call. And every candidate's logit is computed in one fixed order of its own, so it is the
same whatever the batch, the other episodes or the other candidates (no matrix product that
rounds a row by the matrix's shape).

The logits are those of `network.StepScorer.forward` (torch) up to float32 rounding (the sums
run in another order than torch's products): tests/test_scorer_loop.py holds them within 1e-4 of
each other. Training recomputes a decode's log-probabilities with torch (`logprob.trace_log_prob`),
for their gradient.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from ata.model.scalar import jit
from ata.plugins.ata_hrl.arch import NEG

CONTEXT = {"poi": 0, "robot": 1, "nav": 2, "cls": 2}
"""The context token of each sub-decision (`network.step_context`): the robot's (0), the POI's
(1), the POI's and the robot's summed (2)."""


class ScorerWeights(NamedTuple):
    """One scorer's parameters as float32 arrays, each matrix as (inputs, outputs)."""

    feat_w: np.ndarray      # (F, h)
    feat_b: np.ndarray      # (h,)
    ctx_w: np.ndarray       # (d, h)
    cand_w: np.ndarray      # (d, h)
    hid_w: np.ndarray       # (h, h)
    hid_b: np.ndarray       # (h,)
    out_w: np.ndarray       # (h,)
    out_b: np.float32
    lin_w: np.ndarray       # (F,)
    lin_b: np.float32
    scale: np.float32       # exp(log_scale)


def weights(params: dict[str, np.ndarray], prefix: str) -> ScorerWeights:
    """The parameters of the scorer `prefix` (``ita.scorers.poi``, say) of a network's state
    dict (numpy arrays, as a checkpoint holds them)."""
    def mat(name: str) -> np.ndarray:
        return np.ascontiguousarray(params[f"{prefix}.{name}.weight"].T, dtype=np.float32)

    def vec(name: str) -> np.ndarray:
        return np.ascontiguousarray(params[f"{prefix}.{name}"].reshape(-1), dtype=np.float32)

    return ScorerWeights(mat("feat"), vec("feat.bias"), mat("ctx"), mat("cand"), mat("out.1"),
                         vec("out.1.bias"), vec("out.3.weight"),
                         np.float32(params[f"{prefix}.out.3.bias"].reshape(())),
                         vec("linear.weight"),
                         np.float32(params[f"{prefix}.linear.bias"].reshape(())),
                         np.float32(np.exp(params[f"{prefix}.log_scale"].astype(np.float32))))


@jit
def _project_row(x, w, out):
    """out (h,) = x (d,) @ w (d, h), the inputs in order from zero."""
    out[:] = np.float32(0.0)
    for i in range(x.shape[0]):
        xi = x[i]
        for j in range(w.shape[1]):
            out[j] += xi * w[i, j]


@jit
def project(x, w):
    """x (M, d) @ w (d, h), row by row: (M, h) float32."""
    out = np.empty((x.shape[0], w.shape[1]), np.float32)
    for m in range(x.shape[0]):
        _project_row(x[m], w, out[m])
    return out


@jit
def _logits(context, feats, prior, mask, cand_h, tasks, robots, robot, task, residual,
            feat_w, feat_b, ctx_w, hid_w, hid_b, out_w, out_b, lin_w, lin_b, scale, out):
    d = tasks.shape[2]
    h = feat_b.shape[0]
    ctx = np.empty(d, np.float32)
    ctx_h = np.empty(h, np.float32)
    pre = np.empty(h, np.float32)
    hid = np.empty(h, np.float32)
    for e in range(feats.shape[0]):
        logits_row(context, feats[e], prior[e], mask[e], cand_h[e], tasks[e], robots[e],
                   robot[e], task[e], residual, feat_w, feat_b, ctx_w, hid_w, hid_b, out_w,
                   out_b, lin_w, lin_b, scale, out[e], ctx, ctx_h, pre, hid)


@jit
def logits_row(context, feats, prior, mask, cand_h, tasks, robots, robot, task, residual,
               feat_w, feat_b, ctx_w, hid_w, hid_b, out_w, out_b, lin_w, lin_b, scale, out,
               ctx, ctx_h, pre, hid):
    """One episode's logits: feats (N, F), prior (N,) float32, mask (N,), cand_h (N, h),
    tasks (P, d) and robots (R, d) its tokens, robot and task its context's indices, out (N,);
    ctx (d,), ctx_h, pre and hid (h,) working arrays."""
    N, F = feats.shape
    d = tasks.shape[1]
    h = feat_b.shape[0]
    zero = np.float32(0.0)
    neg = np.float32(NEG)
    ctx_done = False
    for n in range(N):
        if not mask[n]:
            out[n] = neg
            continue
        v = scale * prior[n]
        if residual:
            if not ctx_done:             # the episode's context token, projected
                for i in range(d):
                    if context == 0:
                        ctx[i] = robots[robot, i]
                    elif context == 1:
                        ctx[i] = tasks[task, i]
                    else:
                        ctx[i] = tasks[task, i] + robots[robot, i]
                _project_row(ctx, ctx_w, ctx_h)
                ctx_done = True
            f = feats[n]
            for j in range(h):
                pre[j] = feat_b[j]
            for i in range(F):
                fi = f[i]
                for j in range(h):
                    pre[j] += fi * feat_w[i, j]
            for j in range(h):
                x = pre[j] + cand_h[n, j] + ctx_h[j]
                pre[j] = x if x > zero else zero
            for j in range(h):
                hid[j] = hid_b[j]
            for i in range(h):
                pi = pre[i]
                if pi != zero:
                    for j in range(h):
                        hid[j] += pi * hid_w[i, j]
            o = out_b
            for j in range(h):
                if hid[j] > zero:
                    o += out_w[j] * hid[j]
            lin = lin_b
            for i in range(F):
                lin += lin_w[i] * f[i]
            v = v + o + lin
        out[n] = v


def logits(kind: str, w: ScorerWeights, feats: np.ndarray, prior: np.ndarray,
           mask: np.ndarray, cand_h: np.ndarray, tasks: np.ndarray, robots: np.ndarray,
           robot: np.ndarray, task: np.ndarray, residual: bool) -> np.ndarray:
    """(E, N) float32 logits of sub-decision `kind`: feats (E, N, F) float32, prior (E, N),
    mask (E, N), cand_h (E, N, h) the candidates' tokens projected (`project` by
    ``w.cand_w``), tasks (E, P, d) and robots (E, R, d) the tokens, robot and task (E,) the
    context's indices; NEG where `mask` is off."""
    out = np.empty(mask.shape, np.float32)
    _logits(CONTEXT[kind], feats, np.ascontiguousarray(prior, dtype=np.float32), mask, cand_h,
            tasks, robots, robot, task, residual, w.feat_w, w.feat_b, w.ctx_w, w.hid_w,
            w.hid_b, w.out_w, w.out_b, w.lin_w, w.lin_b, w.scale, out)
    return out
