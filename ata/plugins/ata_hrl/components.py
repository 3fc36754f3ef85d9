"""The components of ATA-HRL: the attention ITA policy (``attention``), conditional task
reallocation (``ctr``: pi_C and pi_TR), and the auxiliary state reconstruction (``aux``).

Each decides with the network of one checkpoint. At run time they take the mode of every
decision (or sample it from each scenario's own random stream, ``sample = true``); a trainer
hands them its live network, a sampler and a recorder instead, and they record what the update
needs to recompute each decision's log-probability. ``learned = false`` switches the learned
part off: the policy then decides by the greedy prior alone (the 'learned part off' rows of the
docs).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from ata import hookimpl
from ata.core.settings import param
from ata.core.state import Allocation, DecisionContext, Observation, SimState
from ata.plugins.ata_hrl import decode as D
from ata.plugins.ata_hrl.arch import COND_FEATURES
from ata.plugins.ata_hrl.checkpoint import load_infer, require_trained, trained_ranges
from ata.training import weights_for
from ata.plugins.ata_hrl.decoder import Decoder
from ata.plugins.ata_hrl.inputs import DecodeSettings
from ata.plugins.ata_hrl.features import (GROUPS, inherent_features, seen_state, state_column,
                                          state_features)
from ata.plugins.ata_hrl.infer import InferenceNet
from ata.plugins.ata_hrl.status import StatusTracker, guesses as status_guesses
from ata.model.fatigue import FatigueBelief
from ata.model.events import EventWatch
from ata.model.greedy_planner import GreedyPlanner, GreedySettings
from ata.model.plan import PlanStart, as_seen, plan_start, project, task_attributes
from ata.model.retask import retask_cost, worth_many
from ata.model.team import HumanConstants


# -- what a training rollout records --------------------------------------------------------------

@dataclass
class Recorder:
    """What the components record in a training rollout (numpy; the update recomputes)."""

    inherent: dict[str, np.ndarray] | None = None           # I features (E, N, F)
    ita: D.DecodeTrace | None = None
    cond_state: list[tuple] = field(default_factory=list)   # (raw S, seen S) per epoch >= 1
    cond_feats: list[np.ndarray] = field(default_factory=list)              # (E, F_c)
    cond_prior: list[np.ndarray] = field(default_factory=list)              # (E,)
    cond_choice: list[np.ndarray] = field(default_factory=list)             # (E,) bool
    tr: list[dict[str, Any]] = field(default_factory=list)  # per reallocation: rows, k, trace


def decode_settings(ctx: DecisionContext) -> DecodeSettings:
    """The decoder's constants: the utilisation window and the re-brief the team models
    published, and the greedy planner's default prices (those of the priors the weights were
    trained with)."""
    greedy = GreedySettings()
    return DecodeSettings(window_s=ctx.published(HumanConstants).window_s,
                          human_time_cost=greedy.human_time_cost,
                          rate_offset_s=greedy.rate_offset_s,
                          rebrief_s=retask_cost(ctx).rebrief_s)


def decoder_start(ctx: DecisionContext, seen: dict[str, np.ndarray] | None
                  ) -> tuple[PlanStart, np.ndarray, np.ndarray]:
    """The decoder's start from I and S as the policy sees it: (plan start, fatigue now,
    utilisation now). The fatigue belief is plan_start's (a reconstructor's, else S's fatigue
    moved along the population line), or, where the ``aux`` reconstructor estimated fatigue
    (``aux_fatigue``), that estimate moved along the population line. Reconstructed robot rows
    move the robots and take down the ones they show down; a robot observed down stays
    down."""
    start = plan_start(ctx)
    aux_fatigue = ctx.reconstructed.get("aux_fatigue")
    if aux_fatigue is not None:
        start.belief = FatigueBelief.shifted(aux_fatigue, start.hours, start.fatigue_floor)
    if seen is None:
        # the initial allocation: the belief's fatigue now; nothing has been done yet, so no
        # utilisation
        return start, start.belief.at(start.hours), np.zeros_like(start.hours)
    if "aux_robots" in ctx.reconstructed:
        area = ctx.inherent.extras["area_m"][:, None]
        down = state_column(seen, "robots", "working") < 0.5
        start.robot_free = np.where(down, np.inf, start.robot_free)
        moving = start.robot_at >= 0
        xy = np.stack([state_column(seen, "robots", "x"), state_column(seen, "robots", "y")],
                      -1) * area[..., None]
        start.robot_xy = np.where(moving[..., None], start.robot_xy, xy)
    return (start, state_column(seen, "humans", "fatigue"),
            1.0 - state_column(seen, "humans", "idleness"))


WEIGHTS_FAMILY = "builtin:ata_hrl"
"""The default checkpoint: the family of shipped ATA-HRL weights, (a)'s or (b)'s, whichever
suits the mission's team (``ata.training.weights_for``)."""


class TeamWeights:
    """A settings class whose ``checkpoint`` may name a family of weights: for a mission's team
    it becomes the member that suits the team's size (``ata.core.settings.for_team``)."""

    checkpoint: str

    def for_team(self, team: Any) -> Any:
        return replace(self, checkpoint=weights_for(self.checkpoint, team))


class LearnedComponent:
    """Settings, the network and the way of deciding, shared by the ITA and CTR components."""

    @dataclass
    class Settings(TeamWeights):
        checkpoint: str = param(WEIGHTS_FAMILY, help="trained weights: a path, builtin:NAME, "
                                "or a family (builtin:ata_hrl: the shipped member that suits "
                                "the team's size)")
        sample: bool = param(False, help="sample decisions (each scenario from its own random "
                             "stream) instead of taking the mode")
        learned: bool = param(True, help="false: decide by the greedy prior alone (the learned "
                              "part switched off)")

    def __init__(self, settings: "LearnedComponent.Settings", mission: Any, net: Any = None):
        # settings made without a mission's validation (a notebook's) name a family alone
        self.settings = settings.for_team(mission.settings) if mission is not None else settings
        self.from_checkpoint = net is None
        # decisions in numpy: the checkpoint's weights read without torch, or a trainer's live
        # network (``network.ATAHRLNet``) as it is when the component is made
        self.net = InferenceNet.of(net) if net is not None else load_infer(settings.checkpoint)
        self.recorder: Recorder | None = None
        self.sampler: D.Chooser | None = None

    @hookimpl
    def ata_trained_on(self) -> list[tuple[int, int, int]]:
        return trained_ranges(self.settings.checkpoint) if self.from_checkpoint else []

    @hookimpl
    def ata_peak_bytes(self, mission: Any, batch: int) -> int:
        # the encoder's self-attention over every member and POI: scores and their softmax,
        # (batch, heads, tokens, tokens) float32 each, grow as the POIs squared; the
        # embeddings and the decoder's (batch, POIs, members) scores come next
        s, cfg = mission.sizes, self.net.cfg
        tokens = s.tasks + s.humans + s.robots
        return 4 * batch * (2 * cfg.heads * tokens * tokens + 8 * cfg.d_model * tokens
                            + 4 * s.tasks * (s.humans + s.robots + 1))

    def train_with(self, net: Any, recorder: Recorder, sampler: D.Chooser) -> None:
        """Decide with a trainer's live network (its weights as they are now), sampling with its
        sampler, and record."""
        self.net, self.recorder, self.sampler = InferenceNet.of(net), recorder, sampler

    def chooser(self, ctx: DecisionContext, stream: str) -> D.Chooser:
        if self.sampler is not None:
            return self.sampler
        if self.settings.sample:
            rng, epoch = ctx.rng, ctx.epoch
            return D.stream_sampler(lambda name, n, shape: rng.uniform(
                f"{stream}.{name}.{n}", epoch, shape))
        return D.argmax_chooser


class AttentionITA(LearnedComponent):
    """The initial allocation, decoded step by step with the ITA network (attention encoder of
    I, capacity-aware decoder). It fills the initial slot alone; the reallocation is another
    component's (``ctr``, ``keep``, ...)."""

    @hookimpl
    def ata_initial_allocation(self, ctx: DecisionContext) -> Allocation:
        feats = inherent_features(ctx.inherent)
        start, fatigue, util = decoder_start(ctx, None)
        dec = Decoder(start, np.ones(ctx.reallocatable.shape, bool), fatigue, util,
                      decode_settings(ctx))
        trace = None
        if self.recorder is not None:
            self.recorder.inherent = feats
            trace = self.recorder.ita = D.DecodeTrace()
        emb = self.net.ita.encode(feats)
        return D.decode(dec, self.net.ita, emb, self.chooser(ctx, "attention"),
                        residual=self.settings.learned, trace=trace)


class CTRPolicy(LearnedComponent):
    """pi_C and pi_TR. At every epoch t >= 1 the state encoder reads I and S as the policy sees
    it and the GRU of pi_C advances; pi_C decides whether to reallocate. Where it does, pi_TR
    first decides, for every reallocatable POI at once, whether to keep its triple or plan it
    again (from the POI's projected outcome if kept, who holds it and how loaded they are, and
    whether its robot is down or its attributes changed since it was planned); the kept POIs are
    booked as the robots will visit them, and the others are decoded step by step after them,
    the re-briefs and re-plans a change would cost among the decoder's features. In the options
    framework: pi_C's option starts at every epoch and ends after its decision; pi_TR's starts
    when pi_C says yes and ends once it has reallocated. With ``condition = "always"`` pi_TR
    runs every epoch (the w/o.C ablation).

    With ``replan_in_full`` pi_TR also decodes every reallocatable POI afresh (by the mode of
    its scorers) and takes that full re-plan where the model, in expectation on the observed
    state, gives it more points net of its re-tasking cost than its per-POI reallocation: the
    comparison greedy's reallocation makes between keeping, repairing and re-planning in
    full."""

    @dataclass
    class Settings(LearnedComponent.Settings):
        replan_in_full: bool = param(True, help="also decode a full re-plan and take it where "
                                     "the model expects it to be worth more, net of the "
                                     "re-tasking cost (as greedy weighs its own); false: the "
                                     "per-POI reallocation alone, about a third of the run "
                                     "time, fewer points (experiments/full_replan)")

    def __init__(self, settings: "CTRPolicy.Settings", mission: Any, net: Any = None):
        super().__init__(settings, mission, net)
        self.hidden: np.ndarray | None = None
        self.epoch = -1
        self.emb_i: dict[str, np.ndarray] | None = None     # the encoder's of I, once
        self.emb: dict[str, np.ndarray] | None = None
        self.raw: dict[str, np.ndarray] | None = None
        self.seen: dict[str, np.ndarray] | None = None
        self.events = EventWatch()     # robots newly down, POIs newly changed (pi_C's prior)
        self.last_realloc: np.ndarray | None = None
        self.planned_attrs: np.ndarray | None = None    # (B, P, 2) attributes planned with
        # greedy's reallocation, keeping or repairing (not re-planning in full, which would
        # replace the ITA's allocation by greedy's), whose choice is pi_TR's prior
        self.greedy = GreedyPlanner(GreedySettings(replan_in_full=False))
        self.greedy_attrs: np.ndarray | None = None    # greedy's own memory, as if alone
        self.flip_at: np.ndarray | None = None   # (B,) a trainer's counterfactual rollouts:
        # the epoch at which each scenario's pi_C decision is turned over (-1: none)

    def _observe(self, ctx: DecisionContext) -> None:
        """Once per epoch: encode the state and compute the condition features."""
        if self.epoch == ctx.epoch:
            return
        self.epoch = ctx.epoch
        if self.emb_i is None:
            inherent = inherent_features(ctx.inherent)
            if self.recorder is not None:
                self.recorder.inherent = inherent
            self.emb_i = self.net.tr.encode(inherent)
        self.raw = state_features(ctx.observed)
        self.seen = seen_state(ctx)
        self.emb = self.net.tr.embed(self.emb_i, self.raw, self.seen)
        self.cond_feats, self.cond_prior = self._condition_features(ctx)
        if self.recorder is not None:
            rec = self.recorder
            rec.cond_state.append((self.raw, self.seen))
            rec.cond_feats.append(self.cond_feats)
            rec.cond_prior.append(self.cond_prior)

    def _condition_features(self, ctx: DecisionContext) -> tuple[np.ndarray, np.ndarray]:
        """pi_C's inputs beside the state embedding, (B, COND_FEATURES), and its prior (B,): +1
        where the observation shows a robot newly down or a POI's kind or difficulty newly
        changed (the ``on_event`` rule), else -1. At the first epoch it also starts the
        memory of what each POI was planned with."""
        S, seen = ctx.observed, self.seen
        B, P = ctx.reallocatable.shape
        R = ctx.sizes.robots
        T = ctx.clock.n_epochs
        working = state_column(seen, "robots", "working") > 0.5
        if self.last_realloc is None:
            est = ctx.inherent["tasks"]
            self.planned_attrs = np.stack([est.col("kind"), est.col("difficulty")], -1)
            self.greedy_attrs = self.planned_attrs.copy()
            self.last_realloc = np.zeros(B)
        failed, changed = self.events.step(ctx, working)
        event = failed.any(1) | changed.any(1)
        prev = ctx.previous
        held_by_down = (ctx.reallocatable & ~np.take_along_axis(working, prev.robot, 1)).sum(1)
        util = 1.0 - state_column(seen, "humans", "idleness")
        unvisited = S["tasks"].col("unvisited")
        feats = np.stack([event.astype(float), failed.sum(1) / R, changed.sum(1) / P,
                          held_by_down / P, np.full(B, ctx.epoch / T),
                          (ctx.epoch - self.last_realloc) / T, util.mean(1), util.max(1),
                          util.min(1), unvisited.mean(1)], -1)
        assert feats.shape[1] == COND_FEATURES
        return feats.astype(np.float32), np.where(event, 1.0, -1.0).astype(np.float32)

    @hookimpl
    def ata_should_reallocate(self, ctx: DecisionContext) -> np.ndarray:
        ctx = as_seen(ctx)
        self._observe(ctx)
        B = ctx.reallocatable.shape[0]
        if self.hidden is None:
            self.hidden = np.zeros((B, self.net.cfg.d_model), np.float32)
        pooled = np.concatenate([self.emb[g] for g in GROUPS], 1).mean(1)
        logit, self.hidden = self.net.cond(pooled, self.cond_feats, self.cond_prior,
                                           self.hidden, residual=self.settings.learned)
        decide = self.chooser(ctx, "ctr.condition")("cond", np.stack(
            [np.zeros_like(logit), logit], -1)).astype(bool)
        if self.flip_at is not None:
            decide ^= self.flip_at == ctx.epoch
        if self.recorder is not None:
            self.recorder.cond_choice.append(decide.copy())
        self.last_realloc = np.where(decide, ctx.epoch, self.last_realloc)
        return decide

    @hookimpl
    def ata_reallocate(self, ctx: DecisionContext, active: np.ndarray) -> Allocation:
        ctx = as_seen(ctx)
        self._observe(ctx)
        rows = np.nonzero(active)[0]
        out = ctx.previous.copy()
        if rows.size == 0:
            return out
        sub = ctx.take(rows)
        seen = {g: v[rows] for g, v in self.seen.items()}
        start, fatigue, util = decoder_start(sub, seen)
        kept_proj = project(start, sub.previous)
        attrs = task_attributes(sub)
        changed = (attrs != self.planned_attrs[rows]).any(-1)
        emb = {g: v[rows] for g, v in self.emb.items()}
        trace = None
        if self.recorder is not None:
            trace = D.DecodeTrace()
            self.recorder.tr.append({"epoch": ctx.epoch, "rows": rows, "trace": trace,
                                     "raw": {g: v[rows] for g, v in self.raw.items()},
                                     "seen": seen})
        choose = self.chooser(sub, "ctr")      # the reallocating scenarios' own streams
        # taking the mode and recording nothing, the full re-plan is decoded in the same pass
        # as the per-POI reallocation: plans 0..E-1 are the reallocation's, E..2E-1 the re-plan's
        E = rows.size
        one_pass = self.settings.replan_in_full and trace is None and choose is D.argmax_chooser
        plans = np.tile(np.arange(E), 2 if one_pass else 1)
        mine = np.arange(E)
        dec = Decoder(start.take(plans), sub.reallocatable[plans], fatigue[plans], util[plans],
                      decode_settings(ctx), previous=sub.previous.take(plans))
        emb_plans = {g: v[plans] for g, v in emb.items()}
        # the heuristic's choice, the prior: greedy weighs keeping, repairing and re-planning
        self.greedy.planned_attrs = self.greedy_attrs[rows]
        heuristic = self.greedy.reallocate(sub, np.ones(rows.size, bool))
        self.greedy_attrs[rows] = self.greedy.planned_attrs
        keep_in = dec.keep_inputs(kept_proj.expected[plans], kept_proj.finish[plans],
                                  changed[plans], heuristic.take(plans)).take(mine)
        first = D.decide_keep(keep_in, self.net.tr, emb, choose,
                              residual=self.settings.learned, trace=trace)
        # booked first: the kept POIs with their triples, greedy's with greedy's; the rest are
        # decoded after them
        booked = heuristic.where(first == D.HEURISTIC, sub.previous)
        replanned = dec.left[mine] & (first != D.KEEP)
        kept = np.zeros_like(dec.left)
        kept[mine] = dec.left[mine] & (first >= D.KEEP)
        dec.replay(kept, booked.take(plans))
        decoded = D.decode(dec, self.net.tr, emb_plans, choose,
                           residual=self.settings.learned, trace=trace)
        # the decoder's allocation holds the decoded POIs; the booked ones take their triples
        alloc = booked.where(first >= D.KEEP, decoded.take(mine))
        if self.settings.replan_in_full:
            full = decoded.take(mine + E) if one_pass else D.decode(
                Decoder(start, sub.reallocatable, fatigue, util, decode_settings(ctx),
                        previous=sub.previous), self.net.tr, emb, D.argmax_chooser,
                residual=self.settings.learned)
            alloc, took = self._or_full_replan(sub, full, alloc)
            replanned = replanned | (took[:, None] & sub.reallocatable)
        self.planned_attrs[rows] = np.where(replanned[..., None], attrs,
                                            self.planned_attrs[rows])
        out.robot[rows], out.navigator[rows], out.classifier[rows] = \
            alloc.robot, alloc.navigator, alloc.classifier
        return out

    def _or_full_replan(self, sub: DecisionContext, full: Allocation, alloc: Allocation
                        ) -> tuple[Allocation, np.ndarray]:
        """`alloc` or `full`, a full re-plan decoded afresh (every reallocatable POI, by the
        mode of the scorers), per scenario, whichever greedy's model of worth (expected points
        less human time and re-tasking) prefers; `alloc` wins ties. The re-plan is not
        recorded: to pi_TR's training it is part of the environment. Returns the allocation
        and which scenarios took the re-plan."""
        cost, at, price = retask_cost(sub), plan_start(sub), self.greedy.s.human_time_cost
        # both in one projection (the re-plan's rows where it differs from `alloc`)
        worth_alloc, worth_full = worth_many(sub, at, [alloc, full], sub.reallocatable, cost,
                                             price).T
        take = worth_full > worth_alloc + 1e-9
        return full.where(take[:, None] & sub.reallocatable, alloc), take


class AuxReconstructor:
    """cVAE for fatigue, three stacked GRUs plus a feed-forward layer for delayed states.

    Each epoch it writes, into the reconstructed-state dict the policies read: ``aux_fatigue``
    (B, H), the cVAE's fatigue estimate from the noisy observation conditioned on working hours
    and cognitive ability; ``aux_robots`` (B, R, 5) and ``aux_tasks`` (B, P, 7), the stacked-GRU
    estimates of the current robot and task rows (in the space of ``state_features``) from each
    entity's sequence of observed rows; with a checkpoint that has a status head,
    ``captured_guess`` and ``committed_guess`` (B, P, 1), the POIs the latency shows open that the
    head takes as captured or committed, from features that read across rows and the previous
    epoch's plan (``ata.plugins.ata_hrl.status``). Without it the ``identity`` reconstructor
    leaves the raw state (the w/o.AUX ablation)."""

    @dataclass
    class Settings(TeamWeights):
        checkpoint: str = param(WEIGHTS_FAMILY, help="trained weights: a path, builtin:NAME, "
                                "or a family (builtin:ata_hrl: the shipped member that suits "
                                "the team's size)")
        parts: list[str] = param(["fatigue", "robots", "tasks", "status"],
                                 choices=("fatigue", "robots", "tasks", "status"),
                                 help="what it reconstructs; the rest stays as observed "
                                 "(status: only with a checkpoint that has a status head)")
        guesses: list[str] = param(["captured", "committed"], choices=("captured", "committed"),
                                   help="which of the status head's guesses reach the policies")

    def __init__(self, settings: "AuxReconstructor.Settings", mission: Any, net: Any = None,
                 guess: bool = True):
        settings = settings if settings is not None else self.Settings()
        self.settings = settings.for_team(mission.settings) if mission is not None else settings
        self.from_checkpoint = net is None       # a trainer's live network reports nothing
        if self.from_checkpoint:
            require_trained(self.settings.checkpoint, "aux", "the aux reconstructor")
        self.net = InferenceNet.of(net) if net is not None else \
            load_infer(self.settings.checkpoint)
        self.hidden: dict[str, np.ndarray | None] = {"robots": None, "tasks": None}
        self.tracker = StatusTracker()
        self.guess = guess          # false: the status features only (a trainer's teacher)
        self.status_features: np.ndarray | None = None    # this epoch's (B, P, F), if any

    @hookimpl
    def ata_trained_on(self) -> list[tuple[int, int, int]]:
        return trained_ranges(self.settings.checkpoint) if self.from_checkpoint else []

    @hookimpl
    def ata_reconstruct(self, sim: SimState, obs: Observation, inherent: Observation,
                        out: dict[str, np.ndarray]) -> None:
        feats = state_features(obs)
        f32 = np.float32
        if "fatigue" in self.settings.parts:
            recon = self.net.fatigue(obs["humans"].col("fatigue").astype(f32),
                                     obs["humans"].col("working_time").astype(f32),
                                     inherent["humans"].col("cognitive").astype(f32))
            out["aux_fatigue"] = recon.astype(np.float64)
        for group in ("robots", "tasks"):
            if group not in self.settings.parts:
                continue
            x = feats[group].astype(f32)
            B, N, F = x.shape
            est, self.hidden[group] = self.net.latency(group, x.reshape(B * N, F),
                                                       self.hidden[group])
            out[f"aux_{group}"] = est.reshape(B, N, F).astype(np.float64)
        if "status" in self.settings.parts and self.net.has_status:
            self.status_features = self.tracker.step(sim, obs, inherent)
            if self.status_features is not None and self.guess:
                logits = self.net.status(self.status_features)
                prob = (1.0 / (1.0 + np.exp(-logits.astype(np.float64)))).astype(f32)
                out.update({f"{k}_guess": v for k, v in
                            status_guesses(self.status_features, prob).items()
                            if k in self.settings.guesses})
