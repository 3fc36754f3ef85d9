"""ATA-HRL's networks as they decide, in numpy: the forward passes of ``network``'s modules
from their weights (a state dict of arrays), without torch and without autograd.

Every decision of the components (``components``) is made here, at evaluation (the weights read
from a checkpoint without torch, ``checkpoint.load_infer``) and in a trainer's rollouts alike
(the live network's weights copied once per rollout, `InferenceNet.of`); torch computes only a
training update's log-probabilities and losses. The passes are those of the torch modules, in
float32, up to the rounding of sums taken in another order: tests/test_infer.py holds each within
1e-5 of its module.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from ata.plugins.ata_hrl import scorer_loop
from ata.plugins.ata_hrl.arch import KINDS, LATENCY_LAYERS, NEG, NetConfig
from ata.plugins.ata_hrl.features import GROUPS, equal_runs

F32 = np.float32


def _relu(x: np.ndarray) -> np.ndarray:
    return np.maximum(x, F32(0.0))


class _Weights:
    """A state dict's arrays, each linear layer's weight transposed once (inputs, outputs)."""

    def __init__(self, state: dict[str, np.ndarray]):
        self.p = {k: np.asarray(v, dtype=F32, order="C") if v.dtype.kind == "f" else v
                  for k, v in state.items()}
        self._t: dict[str, np.ndarray] = {}

    def __contains__(self, name: str) -> bool:
        return name in self.p

    def __getitem__(self, name: str) -> np.ndarray:
        return self.p[name]

    def t(self, name: str) -> np.ndarray:
        """Entry `name` transposed, contiguous (made once)."""
        w = self._t.get(name)
        if w is None:
            w = self._t[name] = np.ascontiguousarray(self.p[name].T)
        return w

    def linear(self, name: str, x: np.ndarray) -> np.ndarray:
        """Linear layer `name` (its weight, and its bias where it has one) on x (..., in)."""
        y = x @ self.t(f"{name}.weight")
        bias = self.p.get(f"{name}.bias")
        return y if bias is None else y + bias


def sinusoid(n: int, d: int) -> np.ndarray:
    """`network.sinusoid` in numpy: positional embeddings (n, d) float32."""
    pos = np.arange(n, dtype=F32)[:, None]
    i = np.arange(0, d, 2, dtype=F32)
    angle = pos / np.power(F32(10000.0), i / F32(d))
    out = np.zeros((n, d), F32)
    out[:, 0::2] = np.sin(angle)
    out[:, 1::2] = np.cos(angle[:, : d // 2])
    return out


def _layer_norm(x: np.ndarray, w: np.ndarray, b: np.ndarray, eps: float = 1e-5) -> np.ndarray:
    mean = x.mean(-1, keepdims=True)
    var = ((x - mean) ** 2).mean(-1, keepdims=True)
    return (x - mean) / np.sqrt(var + F32(eps)) * w + b


class AllocationPart:
    """`network.AllocationNet` (``ita`` or ``tr``): the encoder, the scorers' weights as the
    compiled decode reads them, the candidates' tokens, and (pi_TR) the state embedding and the
    keep step."""

    def __init__(self, w: _Weights, prefix: str, cfg: NetConfig):
        self.w, self.prefix, self.cfg = w, prefix, cfg
        self.scorers = {k: scorer_loop.weights(w.p, f"{prefix}.scorers.{k}") for k in KINDS}
        self.with_state = f"{prefix}.keep.log_scale" in w

    def _encoder(self, feats: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        """`network.Encoder.forward`: embeddings, type and position, then the post-norm
        self-attention layers (ReLU feed-forward), every token of an episode together."""
        w, pre, d = self.w, f"{self.prefix}.encoder", self.cfg.d_model
        tokens = []
        for i, g in enumerate(GROUPS):
            x = np.asarray(feats[g], dtype=F32)
            tokens.append(w.linear(f"{pre}.lin.{g}", x) + w[f"{pre}.type_emb.weight"][i]
                          + sinusoid(x.shape[1], d))
        sizes = np.cumsum([t.shape[1] for t in tokens])[:-1]
        x = np.concatenate(tokens, 1)
        for k in range(self.cfg.layers):
            lay = f"{pre}.net.layers.{k}"
            x = _layer_norm(x + self._attention(x, lay), w[f"{lay}.norm1.weight"],
                            w[f"{lay}.norm1.bias"])
            ff = w.linear(f"{lay}.linear2", _relu(w.linear(f"{lay}.linear1", x)))
            x = _layer_norm(x + ff, w[f"{lay}.norm2.weight"], w[f"{lay}.norm2.bias"])
        return dict(zip(GROUPS, np.split(x, sizes, axis=1)))

    def _attention(self, x: np.ndarray, lay: str) -> np.ndarray:
        E, T, d = x.shape
        heads = self.cfg.heads
        hd = d // heads
        w = self.w
        qkv = x @ w[f"{lay}.self_attn.in_proj_weight"].T + w[f"{lay}.self_attn.in_proj_bias"]
        q, k, v = (qkv[..., i * d:(i + 1) * d].reshape(E, T, heads, hd).transpose(0, 2, 1, 3)
                   for i in range(3))
        q *= F32(1.0 / math.sqrt(hd))
        att = q @ np.ascontiguousarray(k.transpose(0, 1, 3, 2))
        att -= att.max(-1, keepdims=True)            # the softmax, in place
        np.exp(att, out=att)
        att /= att.sum(-1, keepdims=True)
        out = (att @ v).transpose(0, 2, 1, 3).reshape(E, T, d)
        return w.linear(f"{lay}.self_attn.out_proj", out)

    def encode(self, feats: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        """The encoder on the I features, each run of equal consecutive episodes read once
        (`network.encode_once`)."""
        starts = equal_runs(feats)
        if starts is None:
            return self._encoder(feats)
        E = feats["tasks"].shape[0]
        counts = np.diff(np.append(starts, E))
        emb = self._encoder({g: v[starts] for g, v in feats.items()})
        return {g: np.repeat(v, counts, 0) for g, v in emb.items()}

    def embed(self, inherent: dict[str, np.ndarray], raw: dict[str, np.ndarray],
              seen: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        """`AllocationNet.embed`: the encoder's of I plus the state's, per token."""
        return {g: inherent[g] + self.w.linear(
                    f"{self.prefix}.state.{g}",
                    np.concatenate([raw[g], seen[g]], -1).astype(F32)) for g in GROUPS}

    def candidates(self, kind: str, emb: dict[str, np.ndarray]) -> np.ndarray:
        """`AllocationNet.candidates`: the candidate tokens (B, N, d) of a sub-decision."""
        if kind == "poi":
            return emb["tasks"]
        if kind == "robot":
            return emb["robots"]
        B = emb["tasks"].shape[0]
        first = self.w[f"{self.prefix}.{'auto' if kind == 'nav' else 'onboard'}"]
        return np.concatenate([np.broadcast_to(first, (B, 1, first.shape[-1])),
                               emb["humans"]], 1)

    def keep(self, feats: np.ndarray, tasks: np.ndarray, prior: np.ndarray, mask: np.ndarray,
             residual: bool = True) -> np.ndarray:
        """`KeepScorer.forward`: (..., P, 3) logits of decoding again, keeping, greedy's."""
        w, pre = self.w, f"{self.prefix}.keep"
        logit = np.exp(w[f"{pre}.log_scale"]) * prior.astype(F32)
        if residual:
            hid = w.linear(f"{pre}.feat", feats) + w.linear(f"{pre}.cand", tasks)
            out = w.linear(f"{pre}.out.3", _relu(w.linear(f"{pre}.out.1", _relu(hid))))
            logit = logit + out + w.linear(f"{pre}.linear", feats)
        return np.where(mask, logit, F32(NEG)).astype(F32)


def _gru_cell(w: _Weights, x: np.ndarray, h: np.ndarray, ih: str, hh: str, b_ih: str,
              b_hh: str) -> np.ndarray:
    """torch's GRU cell: r = sigmoid(gi_r + gh_r), z = sigmoid(gi_z + gh_z),
    n = tanh(gi_n + r gh_n), h' = n + z (h - n), the gates in the weights' order (in place on
    the products' arrays: the cell runs on thousands of rows every epoch)."""
    gi = x @ w.t(ih)
    gi += w.p[b_ih]
    gh = h @ w.t(hh)
    gh += w.p[b_hh]
    H = h.shape[-1]
    rz = gi[..., :2 * H]
    rz += gh[..., :2 * H]
    rz *= F32(0.5)                       # sigmoid(x) = (1 + tanh(x / 2)) / 2
    np.tanh(rz, out=rz)
    rz += F32(1.0)
    rz *= F32(0.5)
    n = gi[..., 2 * H:]
    ghn = gh[..., 2 * H:]
    ghn *= rz[..., :H]
    n += ghn
    np.tanh(n, out=n)
    out = h - n
    out *= rz[..., H:]
    out += n
    return out


class InferenceNet:
    """`network.ATAHRLNet` in numpy: ``ita`` and ``tr`` (`AllocationPart`), pi_C (`cond`),
    the cVAE's fatigue estimate (`fatigue`), the stacked GRUs (`latency`) and the status head
    (`status`, where the network has one)."""

    def __init__(self, state: dict[str, np.ndarray], cfg: NetConfig):
        self.cfg = cfg
        self.w = _Weights(state)
        self.ita = AllocationPart(self.w, "ita", cfg)
        self.tr = AllocationPart(self.w, "tr", cfg)
        self.has_status = "status.mlp.0.weight" in self.w

    @classmethod
    def of(cls, net: Any) -> "InferenceNet":
        """The numpy twin of a torch `ATAHRLNet` as its weights are now."""
        return cls({k: v.detach().cpu().numpy() for k, v in net.state_dict().items()}, net.cfg)

    def cond(self, pooled: np.ndarray, feats: np.ndarray, prior: np.ndarray,
             hidden: np.ndarray, residual: bool = True) -> tuple[np.ndarray, np.ndarray]:
        """`ConditionNet.forward`: pi_C's logit (B,) and its GRU's next hidden state."""
        w = self.w
        x = np.concatenate([pooled, feats], -1).astype(F32)
        hidden = _gru_cell(w, x, hidden, "cond.gru.weight_ih", "cond.gru.weight_hh",
                           "cond.gru.bias_ih", "cond.gru.bias_hh")
        logit = np.exp(w["cond.log_scale"]) * prior
        if residual:
            head = w.linear("cond.head.2", _relu(w.linear(
                "cond.head.0", np.concatenate([hidden, feats], -1))))[..., 0]
            logit = logit + head
            if float(w["cond.rule.on"]) > 0:
                logit = np.where(prior > 0, w.linear("cond.rule", feats)[..., 0], logit)
        return logit.astype(F32), hidden

    def fatigue(self, fatigue_obs: np.ndarray, hours: np.ndarray,
                cognitive: np.ndarray) -> np.ndarray:
        """`FatigueCVAE.forward` by its mean (no sampling): the fatigue estimate."""
        w = self.w
        cond = np.stack([hours, cognitive], -1).astype(F32)
        x = np.concatenate([fatigue_obs.astype(F32)[..., None], cond], -1)
        mu = w.linear("fatigue.enc.2", _relu(w.linear("fatigue.enc.0", x)))[..., :self.cfg.z_dim]
        z = np.concatenate([mu, cond], -1)
        return w.linear("fatigue.dec.2", _relu(w.linear("fatigue.dec.0", z)))[..., 0]

    def latency(self, group: str, x: np.ndarray, hidden: np.ndarray | None
                ) -> tuple[np.ndarray, np.ndarray]:
        """`LatencyGRU.forward` on one step: x (N, F) the observed rows, hidden (layers, N, h)
        or None -> the estimates (N, F) and the next hidden state."""
        w, pre = self.w, f"latency.{group}"
        x = x.astype(F32)
        if hidden is None:
            hidden = np.zeros((LATENCY_LAYERS, x.shape[0], self.cfg.recon_hidden), F32)
        out, new = x, []
        for k in range(LATENCY_LAYERS):
            out = _gru_cell(w, out, hidden[k], f"{pre}.gru.weight_ih_l{k}",
                            f"{pre}.gru.weight_hh_l{k}", f"{pre}.gru.bias_ih_l{k}",
                            f"{pre}.gru.bias_hh_l{k}")
            new.append(out)
        return x + w.linear(f"{pre}.ff", out), np.stack(new)

    def status(self, feats: np.ndarray) -> np.ndarray:
        """`StatusHead.forward`: the logits (..., 3) of the POI's true flags."""
        w = self.w
        h = _relu(w.linear("status.mlp.0", feats.astype(F32)))
        return w.linear("status.mlp.4", _relu(w.linear("status.mlp.2", h)))
