"""The networks of ATA-HRL (paper, section III): embeddings per member type with positional
embeddings, an attention encoder with an allocation head for the initial allocation, GRU-based
condition and reallocation policies, and the auxiliary state reconstruction (a conditional VAE
for fatigue, three stacked GRUs plus a feed-forward layer for delayed robot and task states).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np

import torch
from torch import nn
from torch.nn import functional as F

from ata.learn.features import GROUPS, I_DIMS, S_DIMS, Masks

NEG = -1e9


@dataclass
class NetConfig:
    """Architecture; a checkpoint must match it."""

    d_model: int = 32
    heads: int = 4
    layers: int = 2
    z_dim: int = 4
    recon_hidden: int = 32

    def as_dict(self) -> dict:
        return asdict(self)


def sinusoid(n: int, d: int) -> torch.Tensor:
    """Positional embeddings for indices 0..n-1 (any team size)."""
    pos = torch.arange(n, dtype=torch.float32)[:, None]
    i = torch.arange(0, d, 2, dtype=torch.float32)
    angle = pos / torch.pow(10000.0, i / d)
    out = torch.zeros(n, d)
    out[:, 0::2] = torch.sin(angle)
    out[:, 1::2] = torch.cos(angle[:, : d // 2])
    return out


class Embedder(nn.Module):
    """f_emb per member type, plus a type embedding and the positional embedding."""

    def __init__(self, dims: dict[str, int], d: int):
        super().__init__()
        self.lin = nn.ModuleDict({g: nn.Linear(dims[g], d) for g in GROUPS})
        self.type_emb = nn.Embedding(len(GROUPS), d)
        self.d = d

    def forward(self, feats: dict[str, torch.Tensor]) -> dict[str, torch.Tensor]:
        out = {}
        for i, g in enumerate(GROUPS):
            x = feats[g]
            out[g] = self.lin[g](x) + self.type_emb.weight[i] + sinusoid(x.shape[1], self.d)
        return out


class Encoder(nn.Module):
    """Self-attention over all humans, robots and tasks together."""

    def __init__(self, cfg: NetConfig):
        super().__init__()
        layer = nn.TransformerEncoderLayer(cfg.d_model, cfg.heads, 2 * cfg.d_model,
                                           dropout=0.0, batch_first=True)
        self.net = nn.TransformerEncoder(layer, cfg.layers, enable_nested_tensor=False)

    def forward(self, tokens: dict[str, torch.Tensor]) -> dict[str, torch.Tensor]:
        sizes = [tokens[g].shape[1] for g in GROUPS]
        out = self.net(torch.cat([tokens[g] for g in GROUPS], dim=1))
        return dict(zip(GROUPS, torch.split(out, sizes, dim=1)))


class AllocationHead(nn.Module):
    """Per task: logits over robots, navigators (auto + humans), classifiers (onboard +
    humans), by scaled dot products between task queries and member keys."""

    def __init__(self, d: int):
        super().__init__()
        self.q = nn.Linear(d, 3 * d)
        self.k_robot = nn.Linear(d, d)
        self.k_human = nn.Linear(d, 2 * d)
        self.auto = nn.Parameter(torch.randn(d) / math.sqrt(d))
        self.onboard = nn.Parameter(torch.randn(d) / math.sqrt(d))
        self.d = d

    def forward(self, enc: dict[str, torch.Tensor], masks: Masks) -> dict[str, torch.Tensor]:
        q_r, q_n, q_c = self.q(enc["tasks"]).chunk(3, dim=-1)
        k_r = self.k_robot(enc["robots"])
        k_n, k_c = self.k_human(enc["humans"]).chunk(2, dim=-1)
        B = k_r.shape[0]
        k_n = torch.cat([self.auto.expand(B, 1, self.d), k_n], dim=1)
        k_c = torch.cat([self.onboard.expand(B, 1, self.d), k_c], dim=1)
        scale = 1.0 / math.sqrt(self.d)
        robot = torch.einsum("bpd,brd->bpr", q_r, k_r) * scale
        nav = torch.einsum("bpd,bhd->bph", q_n, k_n) * scale
        cls = torch.einsum("bpd,bhd->bph", q_c, k_c) * scale
        ones = torch.ones(B, 1, dtype=torch.bool)
        robot = robot.masked_fill(~masks.robot[:, None, :], NEG)
        nav = nav.masked_fill(~torch.cat([ones, masks.navigator], 1)[:, None, :], NEG)
        cls = cls.masked_fill(~torch.cat([ones, masks.human], 1)[:, None, :], NEG)
        return {"robot": robot, "navigator": nav, "classifier": cls}


def choose(logits: dict[str, torch.Tensor], sample: bool,
           generator: torch.Generator | None = None,
           uniforms: dict[str, np.ndarray] | None = None) -> torch.Tensor:
    """(B, P, 3) triples: robot index, navigator (-1 auto), classifier (-1 onboard).

    With `uniforms` (one array in [0, 1) per choice, shaped like its logits) the sample is
    drawn by the Gumbel-max trick from those numbers, so that it depends on each scenario's own
    random stream alone (evaluation); otherwise torch's generator draws it (training).
    """
    picks = []
    for key in ("robot", "navigator", "classifier"):
        lg = logits[key]
        if sample and uniforms is not None:
            u = torch.as_tensor(uniforms[key], dtype=lg.dtype).clamp(1e-12, 1 - 1e-12)
            idx = (lg - torch.log(-torch.log(u))).argmax(dim=-1)
        elif sample:
            probs = torch.softmax(lg, dim=-1)
            flat = torch.multinomial(probs.reshape(-1, probs.shape[-1]), 1, generator=generator)
            idx = flat.reshape(lg.shape[:-1])
        else:
            idx = lg.argmax(dim=-1)
        picks.append(idx if key == "robot" else idx - 1)
    return torch.stack(picks, dim=-1)


def log_prob(logits: dict[str, torch.Tensor], triples: torch.Tensor) -> torch.Tensor:
    """(B, P) log-probabilities of the given triples."""
    total = 0.0
    for j, key in enumerate(("robot", "navigator", "classifier")):
        idx = triples[..., j] + (0 if key == "robot" else 1)
        total = total + torch.log_softmax(logits[key], -1).gather(-1, idx[..., None])[..., 0]
    return total


def legal(logits: dict[str, torch.Tensor], triples: torch.Tensor) -> torch.Tensor:
    """(B, P) bool: every choice of the triple is allowed by the masks (a teacher's target may
    name, say, a robot the policy may not choose, such as a failed robot kept on a captured POI)."""
    ok = torch.ones(triples.shape[:-1], dtype=torch.bool)
    for j, key in enumerate(("robot", "navigator", "classifier")):
        idx = triples[..., j] + (0 if key == "robot" else 1)
        ok &= logits[key].gather(-1, idx[..., None])[..., 0] > NEG / 2
    return ok


def entropy(logits: dict[str, torch.Tensor]) -> torch.Tensor:
    """(B, P) summed entropy of the three choices."""
    total = 0.0
    for key in ("robot", "navigator", "classifier"):
        logp = torch.log_softmax(logits[key], -1)
        total = total - (logp.exp() * logp).sum(-1)
    return total


class FatigueCVAE(nn.Module):
    """Conditional VAE: encodes the observed fatigue with its conditions (working hours,
    cognitive ability) and decodes a fatigue estimate from the latent and the conditions."""

    def __init__(self, cfg: NetConfig):
        super().__init__()
        h = cfg.recon_hidden
        self.enc = nn.Sequential(nn.Linear(3, h), nn.ReLU(), nn.Linear(h, 2 * cfg.z_dim))
        self.dec = nn.Sequential(nn.Linear(cfg.z_dim + 2, h), nn.ReLU(), nn.Linear(h, 1))

    def forward(self, fatigue_obs: torch.Tensor, hours: torch.Tensor, cognitive: torch.Tensor,
                sample: bool = False) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        cond = torch.stack([hours, cognitive], -1)
        mu, logvar = self.enc(torch.cat([fatigue_obs[..., None], cond], -1)).chunk(2, -1)
        z = mu + torch.randn_like(mu) * torch.exp(0.5 * logvar) if sample else mu
        return self.dec(torch.cat([z, cond], -1))[..., 0], mu, logvar

    @staticmethod
    def loss(recon: torch.Tensor, target: torch.Tensor, mu: torch.Tensor,
             logvar: torch.Tensor) -> torch.Tensor:
        """||x - x_hat||^2 + 0.1 KL (the paper's L_cVAE), averaged over humans."""
        kl = -0.5 * (1 + logvar - mu.pow(2) - logvar.exp()).sum(-1)
        return ((recon - target) ** 2 + 0.1 * kl).mean()


class LatencyGRU(nn.Module):
    """Three stacked GRUs and a feed-forward layer: from an entity's sequence of observed rows,
    its current true row."""

    def __init__(self, features: int, cfg: NetConfig):
        super().__init__()
        self.gru = nn.GRU(features, cfg.recon_hidden, num_layers=3, batch_first=True)
        self.ff = nn.Linear(cfg.recon_hidden, features)

    def forward(self, seq: torch.Tensor, hidden: torch.Tensor | None = None
                ) -> tuple[torch.Tensor, torch.Tensor]:
        """seq (N, T, F) -> (N, T, F) estimates (residual on the observed row), hidden."""
        out, hidden = self.gru(seq, hidden)
        return seq + self.ff(out), hidden


class ATAHRLNet(nn.Module):
    """All learned parts of ATA-HRL in one module, so one checkpoint holds them."""

    def __init__(self, cfg: NetConfig | None = None):
        super().__init__()
        self.cfg = cfg or NetConfig()
        d = self.cfg.d_model
        self.embed_i = Embedder(I_DIMS, d)
        self.embed_s = Embedder(S_DIMS, d)
        self.ita_encoder = Encoder(self.cfg)
        self.ita_head = AllocationHead(d)
        self.alloc_proj = nn.Linear(3 * d, d)
        self.auto = nn.Parameter(torch.zeros(d))
        self.onboard = nn.Parameter(torch.zeros(d))
        self.ctr_encoder = Encoder(self.cfg)
        self.gru = nn.GRUCell(2 * d, d)
        self.cond_head = nn.Sequential(nn.Linear(2 * d, d), nn.ReLU(), nn.Linear(d, 1))
        self.tr_context = nn.Linear(d, d)
        self.tr_head = AllocationHead(d)
        self.fatigue = FatigueCVAE(self.cfg)
        self.latency = nn.ModuleDict({"robots": LatencyGRU(S_DIMS["robots"], self.cfg),
                                      "tasks": LatencyGRU(S_DIMS["tasks"], self.cfg)})

    # -- initial task allocation ----------------------------------------------------------------
    def ita_logits(self, inherent: dict[str, torch.Tensor], masks: Masks
                   ) -> dict[str, torch.Tensor]:
        return self.ita_head(self.ita_encoder(self.embed_i(inherent)), masks)

    # -- conditional task reallocation --------------------------------------------------------------
    def ctr_step(self, inherent: dict[str, torch.Tensor], state: dict[str, torch.Tensor],
                 recon: dict[str, torch.Tensor], previous: torch.Tensor, hidden: torch.Tensor,
                 masks: Masks) -> tuple[torch.Tensor, dict[str, torch.Tensor], torch.Tensor]:
        """One epoch: (condition logit (B,), reallocation logits, new GRU hidden (B, D)).

        `state` is the raw observed S, `recon` the reconstructed one (the same for w/o.AUX);
        their embeddings are mean-pooled, then added to I's. `previous` (B, P, 3) is the
        allocation in force, embedded on each task token.
        """
        e_i = self.embed_i(inherent)
        e_raw, e_rec = self.embed_s(state), self.embed_s(recon)
        tokens = {g: e_i[g] + 0.5 * (e_raw[g] + e_rec[g]) for g in GROUPS}
        B = previous.shape[0]
        d = self.cfg.d_model
        robots = torch.gather(tokens["robots"], 1,
                              previous[..., 0:1].clamp(min=0).expand(-1, -1, d))
        humans = torch.cat([self.auto.expand(B, 1, d), tokens["humans"]], 1)
        nav = torch.gather(humans, 1, (previous[..., 1:2] + 1).expand(-1, -1, d))
        humans_c = torch.cat([self.onboard.expand(B, 1, d), tokens["humans"]], 1)
        cls = torch.gather(humans_c, 1, (previous[..., 2:3] + 1).expand(-1, -1, d))
        tokens["tasks"] = tokens["tasks"] + self.alloc_proj(torch.cat([robots, nav, cls], -1))
        enc = self.ctr_encoder(tokens)
        pooled = torch.cat([enc[g] for g in GROUPS], 1).mean(1)
        task_pool = enc["tasks"].mean(1)
        hidden = self.gru(torch.cat([pooled, task_pool], -1), hidden)
        cond = self.cond_head(torch.cat([hidden, pooled], -1))[:, 0]
        ctx = self.tr_context(hidden)[:, None, :]
        logits = self.tr_head({"tasks": enc["tasks"] + ctx, "robots": enc["robots"],
                               "humans": enc["humans"]}, masks)
        return cond, logits, hidden

    def initial_hidden(self, batch: int) -> torch.Tensor:
        return torch.zeros(batch, self.cfg.d_model)


def bernoulli(logit: torch.Tensor, sample: bool,
              generator: torch.Generator | None = None,
              uniform: np.ndarray | None = None) -> tuple[torch.Tensor, torch.Tensor]:
    """(decision (B,) bool, its log-probability (B,)); `uniform` as in `choose`."""
    p = torch.sigmoid(logit)
    if sample and uniform is not None:
        decide = torch.as_tensor(uniform, dtype=p.dtype) < p
    elif sample:
        decide = torch.rand(p.shape, generator=generator) < p
    else:
        decide = p > 0.5
    logp = torch.where(decide, F.logsigmoid(logit), F.logsigmoid(-logit))
    return decide, logp
