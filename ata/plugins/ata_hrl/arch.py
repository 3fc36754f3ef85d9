"""The architecture of ATA-HRL's networks, without torch: the sizes of their inputs, the
sub-decisions of the decoder, and `NetConfig` (what a checkpoint records). The torch modules
(``network``) and the numpy forward passes that decide (``infer``) both build on it."""

from __future__ import annotations

from dataclasses import asdict, dataclass

from ata.plugins.ata_hrl.inputs import (CLS_FEATURES, KEEP_FEATURES, NAV_FEATURES,
                                        POI_FEATURES, ROBOT_FEATURES)
from ata.plugins.ata_hrl.status import STATUS_FEATURES

NEG = -1e9
I_DIMS = {"humans": 5, "robots": 3, "tasks": 7}
S_DIMS = {"humans": 4, "robots": 5, "tasks": 7}
KINDS = ("poi", "robot", "nav", "cls")
FEATURES = {"poi": POI_FEATURES, "robot": ROBOT_FEATURES, "nav": NAV_FEATURES,
            "cls": CLS_FEATURES, "keep": KEEP_FEATURES}
PRIOR_SCALE = {"poi": 750.0, "robot": 6.0, "nav": 750.0, "cls": 1.5, "keep": 1.5}
"""Initial prior scales: sampled from the prior alone, decisions stay close to greedy's."""


@dataclass
class NetConfig:
    """The architecture; a checkpoint records it."""

    d_model: int = 32
    heads: int = 4
    layers: int = 2
    hidden: int = 64
    z_dim: int = 4
    recon_hidden: int = 32
    status_hidden: int = 0      # width of the aux module's status head (0: none)

    def as_dict(self) -> dict:
        return asdict(self)


LATENCY_LAYERS = 3
"""The stacked GRUs of the delayed-state reconstruction (``network.LatencyGRU``)."""
COND_FEATURES = 10
"""Inputs of pi_C beside the pooled state embedding (ata.plugins.ata_hrl.components)."""


def _linear(name: str, n_in: int, n_out: int, bias: bool = True) -> dict[str, tuple]:
    out = {f"{name}.weight": (n_out, n_in)}
    if bias:
        out[f"{name}.bias"] = (n_out,)
    return out


def _gru(name: str, n_in: int, h: int, suffix: str = "") -> dict[str, tuple]:
    return {f"{name}.weight_ih{suffix}": (3 * h, n_in), f"{name}.weight_hh{suffix}": (3 * h, h),
            f"{name}.bias_ih{suffix}": (3 * h,), f"{name}.bias_hh{suffix}": (3 * h,)}


def _mlp(name: str, sizes: list[int]) -> dict[str, tuple]:
    """nn.Sequential of Linear layers with an activation between each (indices 0, 2, 4...)."""
    out: dict[str, tuple] = {}
    for i, (a, b) in enumerate(zip(sizes[:-1], sizes[1:])):
        out.update(_linear(f"{name}.{2 * i}", a, b))
    return out


def expected_shapes(cfg: NetConfig) -> dict[str, tuple]:
    """The shape of every entry of `network.ATAHRLNet(cfg)`'s state dict, by name: what a
    checkpoint's weights must hold to be read without torch (tests/test_infer.py checks it
    against the torch module's own)."""
    d, h, r = cfg.d_model, cfg.hidden, cfg.recon_hidden
    out: dict[str, tuple] = {}
    for part in ("ita", "tr"):
        enc = f"{part}.encoder"
        for g in I_DIMS:
            out.update(_linear(f"{enc}.lin.{g}", I_DIMS[g], d))
        out[f"{enc}.type_emb.weight"] = (len(I_DIMS), d)
        for k in range(cfg.layers):
            lay = f"{enc}.net.layers.{k}"
            out.update({f"{lay}.self_attn.in_proj_weight": (3 * d, d),
                        f"{lay}.self_attn.in_proj_bias": (3 * d,)})
            out.update(_linear(f"{lay}.self_attn.out_proj", d, d))
            out.update(_linear(f"{lay}.linear1", d, 2 * d))
            out.update(_linear(f"{lay}.linear2", 2 * d, d))
            for norm in ("norm1", "norm2"):
                out.update({f"{lay}.{norm}.weight": (d,), f"{lay}.{norm}.bias": (d,)})
        for k in KINDS:
            sc = f"{part}.scorers.{k}"
            out.update(_linear(f"{sc}.feat", FEATURES[k], h))
            out.update(_linear(f"{sc}.cand", d, h, bias=False))
            out.update(_linear(f"{sc}.ctx", d, h, bias=False))
            out.update(_linear(f"{sc}.out.1", h, h))
            out.update(_linear(f"{sc}.out.3", h, 1))
            out.update(_linear(f"{sc}.linear", FEATURES[k], 1))
            out[f"{sc}.log_scale"] = ()
        out[f"{part}.auto"] = (d,)
        out[f"{part}.onboard"] = (d,)
    keep = "tr.keep"
    out.update(_linear(f"{keep}.feat", FEATURES["keep"], h))
    out.update(_linear(f"{keep}.cand", d, h, bias=False))
    out.update(_linear(f"{keep}.out.1", h, h))
    out.update(_linear(f"{keep}.out.3", h, 3))
    out.update(_linear(f"{keep}.linear", FEATURES["keep"], 3))
    out[f"{keep}.log_scale"] = ()
    for g in S_DIMS:
        out.update(_linear(f"tr.state.{g}", 2 * S_DIMS[g], d))
    out.update(_gru("cond.gru", d + COND_FEATURES, d))
    out.update(_mlp("cond.head", [d + COND_FEATURES, h, 1]))
    out["cond.log_scale"] = ()
    out.update(_linear("cond.rule", COND_FEATURES, 1))
    out["cond.rule.on"] = ()
    out.update(_mlp("fatigue.enc", [3, r, 2 * cfg.z_dim]))
    out.update(_mlp("fatigue.dec", [cfg.z_dim + 2, r, 1]))
    for g in ("robots", "tasks"):
        for k in range(LATENCY_LAYERS):
            out.update(_gru(f"latency.{g}.gru", S_DIMS[g] if k == 0 else r, r, f"_l{k}"))
        out.update(_linear(f"latency.{g}.ff", r, S_DIMS[g]))
    if cfg.status_hidden > 0:
        out.update(_mlp("status.mlp", [STATUS_FEATURES, cfg.status_hidden,
                                       cfg.status_hidden, 3]))
    return out
