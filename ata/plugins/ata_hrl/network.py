"""The networks of ATA-HRL: an attention encoder over the team and the POIs, and the scorers of
the capacity-aware decoder (POI, robot, navigator, classifier), each a learned residual on top
of the greedy heuristic's score.

Encoder (the paper's ITA network): per member type an embedding of its inherent features (and,
when reallocating, of its observed or reconstructed state), plus a type embedding and a
positional embedding, then self-attention over all humans, robots and POIs together.

Scorer of one sub-decision: for each candidate, a two-layer perceptron of the decoder's features
for that candidate, the candidate's embedding and the embeddings of the choices made before it
in this step, plus ``scale * prior`` where ``prior`` is greedy's score and ``scale`` a learned
positive number. The perceptron's last layer starts at zero, so an untrained network decodes as
the prior does; ``residual = False`` switches the learned part off.
"""

from __future__ import annotations

import math

import numpy as np
import torch
from torch import nn
from torch.nn import functional as F

from ata.plugins.ata_hrl.arch import (COND_FEATURES, FEATURES, I_DIMS, KINDS,  # noqa: F401
                                      LATENCY_LAYERS, NEG, PRIOR_SCALE, S_DIMS, NetConfig)
from ata.plugins.ata_hrl.features import GROUPS, equal_runs
from ata.plugins.ata_hrl.inputs import KEEP_FEATURES
from ata.plugins.ata_hrl.status import STATUS_FEATURES

def sinusoid(n: int, d: int, device: torch.device | None = None) -> torch.Tensor:
    """Positional embeddings for indices 0..n-1 (any team size)."""
    pos = torch.arange(n, dtype=torch.float32, device=device)[:, None]
    i = torch.arange(0, d, 2, dtype=torch.float32, device=device)
    angle = pos / torch.pow(10000.0, i / d)
    out = torch.zeros(n, d, device=device)
    out[:, 0::2] = torch.sin(angle)
    out[:, 1::2] = torch.cos(angle[:, : d // 2])
    return out


class Encoder(nn.Module):
    """Embeddings per member type of the inherent features, a type and a positional embedding,
    then self-attention over every token."""

    def __init__(self, cfg: NetConfig):
        super().__init__()
        d = cfg.d_model
        self.lin = nn.ModuleDict({g: nn.Linear(I_DIMS[g], d) for g in GROUPS})
        self.type_emb = nn.Embedding(len(GROUPS), d)
        layer = nn.TransformerEncoderLayer(d, cfg.heads, 2 * d, dropout=0.0, batch_first=True)
        self.net = nn.TransformerEncoder(layer, cfg.layers, enable_nested_tensor=False)
        self.d = d

    def forward(self, feats: dict[str, torch.Tensor]) -> dict[str, torch.Tensor]:
        tokens = []
        for i, g in enumerate(GROUPS):
            x = feats[g]
            tokens.append(self.lin[g](x) + self.type_emb.weight[i]
                          + sinusoid(x.shape[1], self.d, x.device))
        sizes = [t.shape[1] for t in tokens]
        out = self.net(torch.cat(tokens, 1))
        return dict(zip(GROUPS, torch.split(out, sizes, dim=1)))


def to_tensors(feats: dict[str, np.ndarray], device: torch.device | None = None
               ) -> dict[str, torch.Tensor]:
    """Features as float32 tensors (copies: the context's arrays are read-only, which
    torch.as_tensor warns of)."""
    return {k: torch.tensor(v, dtype=torch.float32, device=device) for k, v in feats.items()}


def encode_once(encoder: Encoder, feats: dict[str, np.ndarray],
                device: torch.device | None = None) -> dict[str, torch.Tensor]:
    """`encoder` on the I features `feats` (numpy, on `device`), reading each run of equal
    consecutive episodes once (`features.equal_runs`): the run's embeddings are repeated for its
    episodes, and their gradients add up into the one pass. Where no two consecutive episodes
    are equal (an evaluation's batch), this is `encoder(feats)` itself."""
    E = feats["tasks"].shape[0]
    starts = equal_runs(feats)
    if starts is None:
        return encoder(to_tensors(feats, device))
    counts = torch.as_tensor(np.diff(np.append(starts, E)), device=device)
    emb = encoder(to_tensors({g: v[starts] for g, v in feats.items()}, device))
    return {g: v.repeat_interleave(counts, 0, output_size=E) for g, v in emb.items()}


def _linear(layer: nn.Linear, x: torch.Tensor) -> torch.Tensor:
    """`layer(x)` by `F.linear` (its weight and its bias, None where it has none): the same op
    without the module's per-call machinery."""
    return F.linear(x, layer.weight, layer.bias)


class StepScorer(nn.Module):
    """Logits of one sub-decision: MLP(features, candidate, context) + scale * prior."""

    def __init__(self, kind: str, cfg: NetConfig):
        super().__init__()
        h, d = cfg.hidden, cfg.d_model
        self.feat = nn.Linear(FEATURES[kind], h)
        self.cand = nn.Linear(d, h, bias=False)
        self.ctx = nn.Linear(d, h, bias=False)
        self.out = nn.Sequential(nn.ReLU(), nn.Linear(h, h), nn.ReLU(), nn.Linear(h, 1))
        self.linear = nn.Linear(FEATURES[kind], 1)     # a direct path from the features
        for layer in (self.out[-1], self.linear):
            nn.init.zeros_(layer.weight)
            nn.init.zeros_(layer.bias)
        self.log_scale = nn.Parameter(torch.tensor(math.log(PRIOR_SCALE[kind])))

    def forward(self, feats: torch.Tensor, cand: torch.Tensor, ctx: torch.Tensor,
                prior: torch.Tensor, mask: torch.Tensor, residual: bool = True) -> torch.Tensor:
        """feats (..., N, F), cand (..., N, d), ctx (..., d), prior and mask (..., N). A
        decode computes these logits, up to float32 rounding, with its compiled loop
        (`scorer_loop`), and a trainer's update with `rows` on the rows that count."""
        logit = self.log_scale.exp() * prior
        if residual:
            # the layers' own functions (`_linear`, torch.relu) without the modules' per-call
            # machinery: the same ops
            hid = self._hidden(_linear(self.feat, feats) + _linear(self.cand, cand)
                               + _linear(self.ctx, ctx)[..., None, :])
            logit = self._tail(logit, hid, feats)
        return logit.masked_fill(~mask, NEG)

    def rows(self, feats: torch.Tensor, cand: torch.Tensor, ctx: torch.Tensor,
             prior: torch.Tensor, row_cand: torch.Tensor, row_ctx: torch.Tensor,
             residual: bool = True) -> torch.Tensor:
        """`forward`'s logits of M candidate rows alone, without the padding a dense forward
        computes (a trainer's update scores the legal candidates of the decisions with a
        choice): feats (M, F) and prior (M,) the rows', cand (C, d) and ctx (K, d) the tokens,
        row_cand and row_ctx (M,) each row's index into them; each token is projected once."""
        logit = self.log_scale.exp() * prior
        if residual:
            # the rows gathered by index_select (whose backward adds into the tokens' rows,
            # cheaper than an indexing's) and summed in place: the same values as forward's
            x = _linear(self.feat, feats)
            x.add_(_linear(self.cand, cand).index_select(0, row_cand))
            x.add_(_linear(self.ctx, ctx).index_select(0, row_ctx))
            hid = torch.relu(_linear(self.out[1], torch.relu_(x)))
            logit = self._tail(logit, hid, feats)
        return logit

    def _hidden(self, x: torch.Tensor) -> torch.Tensor:
        """`out` but its output layer: activation, hidden layer, activation."""
        return torch.relu(_linear(self.out[1], torch.relu(x)))

    def _tail(self, logit: torch.Tensor, hid: torch.Tensor, feats: torch.Tensor) -> torch.Tensor:
        """`logit` plus the residual: `out`'s output layer on `hid` and the direct path from
        the features."""
        return logit + _linear(self.out[3], hid)[..., 0] + _linear(self.linear, feats)[..., 0]


class KeepScorer(nn.Module):
    """pi_TR's first step: for every POI, the logits of decoding it again, keeping its triple,
    and taking the greedy heuristic's: learned residuals on ``scale * prior`` from the POI's
    features and embedding."""

    def __init__(self, cfg: NetConfig):
        super().__init__()
        h, d = cfg.hidden, cfg.d_model
        self.feat = nn.Linear(KEEP_FEATURES, h)
        self.cand = nn.Linear(d, h, bias=False)
        self.out = nn.Sequential(nn.ReLU(), nn.Linear(h, h), nn.ReLU(), nn.Linear(h, 3))
        self.linear = nn.Linear(KEEP_FEATURES, 3)
        for layer in (self.out[-1], self.linear):
            nn.init.zeros_(layer.weight)
            nn.init.zeros_(layer.bias)
        self.log_scale = nn.Parameter(torch.tensor(math.log(PRIOR_SCALE["keep"])))

    def forward(self, feats: torch.Tensor, tasks: torch.Tensor, prior: torch.Tensor,
                mask: torch.Tensor, residual: bool = True) -> torch.Tensor:
        """feats (..., P, F), tasks (..., P, d), prior and mask (..., P, 3) -> logits
        (..., P, 3): decode again, keep, greedy's."""
        logit = self.log_scale.exp() * prior
        if residual:
            hid = self.feat(feats) + self.cand(tasks)
            logit = logit + self.out(hid) + self.linear(feats)
        return logit.masked_fill(~mask, NEG)


class AllocationNet(nn.Module):
    """The encoder and the scorers of one allocation policy: the four sub-decisions of the
    decoder, and (pi_TR) the keep step."""

    def __init__(self, cfg: NetConfig, with_state: bool):
        super().__init__()
        d = cfg.d_model
        self.encoder = Encoder(cfg)
        self.scorers = nn.ModuleDict({k: StepScorer(k, cfg) for k in KINDS})
        self.auto = nn.Parameter(torch.zeros(d))      # the 'autonomous' navigator's token
        self.onboard = nn.Parameter(torch.zeros(d))   # the 'onboard' classifier's token
        self.keep = KeepScorer(cfg) if with_state else None
        # the state representation: the raw S and S as seen (reconstructed) side by side,
        # embedded per token (the same for w/o.AUX, whose two halves are the raw S)
        self.state = nn.ModuleDict({g: nn.Linear(2 * S_DIMS[g], d) for g in GROUPS}) \
            if with_state else None

    def embed(self, inherent: dict[str, torch.Tensor], raw: dict[str, torch.Tensor],
              seen: dict[str, torch.Tensor]) -> dict[str, torch.Tensor]:
        """Per-token embeddings at an epoch: the encoder's of I plus the state's."""
        return {g: inherent[g] + self.state[g](torch.cat([raw[g], seen[g]], -1))
                for g in GROUPS}

    def candidates(self, kind: str, emb: dict[str, torch.Tensor]) -> torch.Tensor:
        """Candidate tokens (B, N, d) of a sub-decision."""
        B = emb["tasks"].shape[0]
        if kind == "poi":
            return emb["tasks"]
        if kind == "robot":
            return emb["robots"]
        first = self.auto if kind == "nav" else self.onboard
        return torch.cat([first.expand(B, 1, -1), emb["humans"]], 1)


def gather_rows(x: torch.Tensor, idx: torch.Tensor) -> torch.Tensor:
    """x (B, N, d), idx (..., B) -> (..., B, d): row idx[..., b] of x[b]."""
    B = x.shape[0]
    flat = idx.reshape(-1, B)
    out = x[torch.arange(B, device=x.device)[None, :], flat.clamp(min=0)]
    return out.reshape(*idx.shape, x.shape[-1])


def step_context(kind: str, emb: dict[str, torch.Tensor], ctx_idx: dict[str, torch.Tensor]
                 ) -> torch.Tensor:
    """The context token of a sub-decision: the robot free first (POI step); the POI chosen
    (robot step); the POI and robot chosen (navigator, classifier steps)."""
    if kind == "poi":
        return gather_rows(emb["robots"], ctx_idx["robot"])
    if kind == "robot":
        return gather_rows(emb["tasks"], ctx_idx["task"])
    return gather_rows(emb["tasks"], ctx_idx["task"]) + gather_rows(emb["robots"],
                                                                    ctx_idx["robot"])


class ConditionNet(nn.Module):
    """pi_C: a GRU over the epochs, reading the pooled state embedding and the condition
    features; its logit is a learned residual on the event prior (+1 when the observation shows
    a new robot failure or attribute change, -1 otherwise). At event epochs a fitted logistic
    rule on the condition features (``rule``, fitted by the trainer's cond phase) decides in its
    place once it is switched on (its ``on`` buffer); until then it is zero and off."""

    def __init__(self, cfg: NetConfig):
        super().__init__()
        d, h = cfg.d_model, cfg.hidden
        self.gru = nn.GRUCell(d + COND_FEATURES, d)
        self.head = nn.Sequential(nn.Linear(d + COND_FEATURES, h), nn.ReLU(), nn.Linear(h, 1))
        nn.init.zeros_(self.head[-1].weight)
        nn.init.zeros_(self.head[-1].bias)
        self.log_scale = nn.Parameter(torch.tensor(math.log(1.5)))
        # made at zero, torch's generator put back as it was after its draw, so that every
        # other weight of the network starts from a seed as it would without the rule (the
        # CPU generator alone: nothing here draws on a GPU's)
        with torch.random.fork_rng(devices=[]):
            self.rule = nn.Linear(COND_FEATURES, 1)
        nn.init.zeros_(self.rule.weight)
        nn.init.zeros_(self.rule.bias)
        self.rule.register_buffer("on", torch.zeros(()))

    def forward(self, pooled: torch.Tensor, feats: torch.Tensor, prior: torch.Tensor,
                hidden: torch.Tensor, residual: bool = True) -> tuple[torch.Tensor, torch.Tensor]:
        x = torch.cat([pooled, feats], -1)
        hidden = self.gru(x, hidden)
        logit = self.log_scale.exp() * prior
        if residual:
            logit = logit + self.head(torch.cat([hidden, feats], -1))[..., 0]
            if self.rule_on():               # at event epochs (prior +1): the rule alone
                logit = torch.where(prior > 0, self.rule(feats)[..., 0], logit)
        return logit, hidden

    def rule_on(self) -> bool:
        """Whether the fitted rule decides pi_C's event epochs."""
        return bool(self.rule.on > 0)


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
        self.gru = nn.GRU(features, cfg.recon_hidden, num_layers=LATENCY_LAYERS,
                          batch_first=True)
        self.ff = nn.Linear(cfg.recon_hidden, features)

    def forward(self, seq: torch.Tensor, hidden: torch.Tensor | None = None
                ) -> tuple[torch.Tensor, torch.Tensor]:
        """seq (N, T, F) -> (N, T, F) estimates (residual on the observed row), hidden."""
        out, hidden = self.gru(seq, hidden)
        return seq + self.ff(out), hidden


class StatusHead(nn.Module):
    """Per POI, from its status features (``ata.plugins.ata_hrl.status``), the logits of its
    true unvisited, classified and reallocatable flags."""

    def __init__(self, features: int, cfg: NetConfig):
        super().__init__()
        h = cfg.status_hidden
        self.mlp = nn.Sequential(nn.Linear(features, h), nn.ReLU(), nn.Linear(h, h), nn.ReLU(),
                                 nn.Linear(h, 3))

    def forward(self, feats: torch.Tensor) -> torch.Tensor:
        return self.mlp(feats)


class ATAHRLNet(nn.Module):
    """Every learned part of ATA-HRL in one module, so one checkpoint holds them: the ITA
    policy, pi_C, pi_TR, and the auxiliary reconstruction."""

    def __init__(self, cfg: NetConfig | None = None):
        super().__init__()
        self.cfg = cfg or NetConfig()
        self.ita = AllocationNet(self.cfg, with_state=False)
        self.tr = AllocationNet(self.cfg, with_state=True)
        self.cond = ConditionNet(self.cfg)
        self.fatigue = FatigueCVAE(self.cfg)
        self.latency = nn.ModuleDict({"robots": LatencyGRU(S_DIMS["robots"], self.cfg),
                                      "tasks": LatencyGRU(S_DIMS["tasks"], self.cfg)})
        if self.cfg.status_hidden > 0:
            # initialised from a generator of its own: the parts above start from a seed as
            # they would without the head, whatever the global torch state
            with torch.random.fork_rng():
                torch.manual_seed(7919)
                self.status = StatusHead(STATUS_FEATURES, self.cfg)
