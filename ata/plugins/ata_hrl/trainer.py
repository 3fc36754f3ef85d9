"""The trainer ``ata_hrl``: trains the ATA-HRL components a training mission's slots hold.

Which parts it trains follows the slots, not names: the ITA policy if the initial slot holds the
``attention`` component, pi_C if the condition slot holds ``ctr``, pi_TR if the reallocation
slot does, the reconstruction if the reconstructors include ``aux``. So the ablations are the
run-time swaps: ``reconstructors = ["identity"]`` trains w/o.AUX, ``condition = "always"`` trains
w/o.C, and an initial-only mission trains the attention ITA alone (AtRL-TR's first stage).

Phases, each with its own step counter (a killed run resumes inside any of them):

1. **aux**: roll out the greedy teacher, log the observed and the true states, fit the cVAE
   (reconstruction + 0.1 KL) and the stacked GRUs (MSE against the true rows), supervised.
2. **ita**: the ITA policy alone (no reallocation during this phase). Each step samples
   ``samples`` allocations of each of ``batch_size`` scenarios on common random numbers, runs
   them, and takes the advantage of each sample against the mean of its scenario's samples (a
   shared per-scenario baseline, zero-sum per scenario) on R_ITA; plus an optional pull towards
   each scenario's best sample (self-imitation) and an entropy bonus.
3. **cond** (only with ``cond_scenarios``): pi_C by counterfactual rollouts. Training scenarios
   are run once as the policy decides (every decision by its mode) and once per reallocating
   epoch (``cond_epochs = "events"``) or per epoch (``"all"``) with pi_C's decision there turned
   over, on the same random streams; the difference of the two from that epoch on is what the
   other choice was worth, and pi_C is fitted to the better choice of each, weighted by how
   much better (one step of classification-based policy iteration): its network, or with
   ``cond_fit = "features"`` a linear residual on its condition features at event epochs, or
   with ``cond_fit = "rule"`` a weighted logistic regression on those features that decides
   at event epochs in the network's place (fitted to convergence by Newton's method).
4. **ctr**: pi_C and pi_TR after the ITA, frozen and decoding by its mode, in the same way on
   R_C (pi_C) and R_TR (pi_TR).

The rewards use the expected points of each classification (``reward = "expected"``, the
default; ``"realised"`` for the drawn outcomes), which removes the outcome draws' noise.
``best.pt`` follows the held-out evaluation (mean total team performance, decisions by their
mode, on validation scenarios of seed ``seed + 1_000_003``). Checkpoints load with
``torch.load(..., weights_only=True)`` and hold everything needed to resume.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import Any

import numpy as np
import torch

from ata.core.errors import MissionError
from ata.core.kernel import Simulation, build_component
from ata.core.settings import param
from ata.plugins.ata_hrl import decode as D
from ata.plugins.ata_hrl.checkpoint import (FORMAT, KIND, CheckpointError, net_from_checkpoint,
                                            read_checkpoint)
from ata.plugins.ata_hrl.components import (AttentionITA, AuxReconstructor, CTRPolicy,
                                            Recorder)
from ata.plugins.ata_hrl.features import GROUPS, state_features, to_tensors
from ata.plugins.ata_hrl.network import ATAHRLNet, FatigueCVAE, NetConfig
from ata.plugins.ata_hrl.rewards import hierarchical_rewards, rewards_to_go, to_go
from ata.plugins.ata_hrl.status import (GUESSES as STATUS_GUESSES, guesses as status_guesses,
                                        status_targets)
from ata.training import VALIDATION_SEED_OFFSET, TrainRun, resolve, trained_on

PHASE_BASE = {"aux": 0, "ita": 10_000_000, "ctr": 20_000_000, "cond": 30_000_000}
"""First scenario id of each phase's range (root seed ``seed``)."""
PHASE_SPAN = 10_000_000
LOG_FIELDS = ["phase", "step", "setting", "episodes", "episodes_per_s", "loss", "mean_score",
              "R_ITA", "R_C", "R_TR", "reallocations", "eval_score", "eval_expected",
              "aux_fatigue_mse", "aux_latency_mse", "wall_s"]


class ATAHRLTrainer:
    """Trains ATA-HRL's components (see the module's doc)."""

    log_fields = LOG_FIELDS

    @dataclass
    class Settings:
        seed: int = param(12345, min=0, max=2**40, help="root seed of the training scenarios "
                          f"(validation uses seed + {VALIDATION_SEED_OFFSET})")
        team_settings: list[str] = param(["a"], choices=("a", "b"), help="team settings "
                                         "trained on, in turn (a mixture when several)")
        uncertainty_levels: list[str] = param([], choices=("none", "low", "medium", "high"),
                                              help="uncertainty levels trained on in turn, "
                                              "crossed with team_settings (step k: the k-th "
                                              "pair, cyclically), and validated on; empty: "
                                              "the mission's level alone")
        batch_size: int = param(16, min=1, max=4096, help="scenarios per step")
        samples: int = param(8, min=2, max=256, help="samples of each scenario per step (the "
                             "shared baseline is their mean)")
        ita_steps: int = param(300, min=0, help="steps of the ITA phase")
        ita_reallocates: bool = param(False, help="in the ITA phase, reallocate as the mission "
                                      "does, with pi_C and pi_TR as they stand (their greedy "
                                      "priors when untrained): R_ITA then counts what happens "
                                      "after the reallocations (false: never reallocate)")
        ita_from: str = param("", help="take the ITA policy from this checkpoint (a path or "
                              "builtin:NAME) and skip the ITA phase: the full method and its "
                              "ablations can share one ITA, trained alone")
        init_from: str = param("", help="start every network from this checkpoint (a path or "
                               "builtin:NAME) and train on from there (another team setting, "
                               "say)")
        ctr_steps: int = param(200, min=0, help="steps of the pi_C / pi_TR phase")
        lr: float = param(1e-3, min=0.0, max=1.0, help="Adam learning rate of the ITA phase")
        ctr_lr: float = param(1e-3, min=0.0, max=1.0, help="Adam learning rate of the pi_C / "
                              "pi_TR phase")
        tr_from_ita: bool = param(True, help="start pi_TR's encoder and scorers as copies of "
                                  "the trained ITA's (its state embedding and keep step at "
                                  "zero): it decodes as the ITA learned to, from the start")
        entropy: float = param(0.0, min=0.0, help="entropy bonus weight (per decision)")
        self_imitation: float = param(0.0, min=0.0, help="weight of the pull towards each "
                                      "scenario's best sample (per decision)")
        grad_clip: float = param(1.0, min=0.0, help="gradient norm clip (0: none)")
        reward: str = param("expected", choices=("expected", "realised"),
                            help="points of a classification: expected given how it was made, "
                                 "or as drawn")
        aux_batches: int = param(6, min=1, help="teacher rollouts (of batch_size scenarios) "
                                 "for the reconstruction data")
        aux_steps: int = param(400, min=0, help="supervised steps of the reconstructors")
        aux_lr: float = param(3e-3, min=0.0, max=1.0, help="Adam learning rate of the "
                              "reconstructors")
        aux_loss: str = param("mse", choices=("mse", "l1"), help="the stacked GRUs' loss: "
                              "squared error (the mean of what a row may be) or absolute "
                              "error (its median: a row more often fresh than stale is left "
                              "as observed)")
        status_hidden: int = param(0, min=0, help="width of the aux module's status head "
                                   "(0: none); trained only where the reconstructors include "
                                   "aux (the shipped (b) weights: 64)")
        status_levels: list[str] = param(["low", "medium", "high"],
                                         choices=("none", "low", "medium", "high"),
                                         help="uncertainty levels of the status head's teacher "
                                         "rollouts")
        status_batches: int = param(4, min=1, help="teacher rollouts (of batch_size scenarios) "
                                    "per team setting and level for the status head's data")
        status_steps: int = param(2000, min=0, help="supervised steps of the status head")
        status_lr: float = param(3e-3, min=0.0, max=1.0, help="Adam learning rate of the "
                                 "status head")
        cond_scenarios: int = param(0, min=0, help="pi_C by counterfactual rollouts (the "
                                    "'cond' phase, before 'ctr'): training scenarios per team "
                                    "setting and level of cond_levels (0: no such phase)")
        cond_levels: list[str] = param(["high"], choices=("none", "low", "medium", "high"),
                                       help="uncertainty levels of the cond phase's rollouts")
        cond_epochs: str = param("events", choices=("events", "all"), help="the epochs whose "
                                 "decision the cond phase turns over: where the policy "
                                 "reallocates, or every epoch")
        cond_target: str = param("points", choices=("points", "R_C"), help="what the cond "
                                 "phase compares from the turned-over epoch on: the points "
                                 "(as `reward` says), or the paper's R_C")
        cond_fit: str = param("network", choices=("network", "features", "rule"),
                              help="what the cond phase fits: pi_C's network (its GRU and "
                              "head); a linear residual on its ten condition features at event "
                              "epochs alone (the network gains that residual); or a logistic "
                              "rule on those features that decides at event epochs in the "
                              "network's place (quiet epochs stay the network's)")
        cond_steps: int = param(300, min=1, help="full-batch Adam steps of pi_C's weighted "
                                "cross-entropy in the cond phase (cond_fit = 'rule': one step, "
                                "the rule solved to convergence by Newton's method)")
        cond_l2: float = param(1e-2, min=0.0, help="cond_fit = 'rule': the L2 penalty of the "
                               "logistic regression, on its standardised features")
        cond_rounds: int = param(1, min=1, help="cond_fit = 'rule': rounds of labels and fit; "
                                 "from the second on, the labels are collected with the rule "
                                 "of the round before deciding, at every event epoch (what it "
                                 "did there turned over), and the rule is fitted to them "
                                 "alone (approximate policy iteration)")
        cond_lr: float = param(1e-3, min=0.0, max=1.0, help="Adam learning rate of the cond "
                               "phase")
        eval_every: int = param(25, min=1, help="held-out validation every N steps")
        eval_scenarios: int = param(64, min=1, help="validation scenarios per team setting "
                                    "(and per uncertainty level, with uncertainty_levels)")
        checkpoint_every: int = param(10, min=1, help="write checkpoint.pt every N steps")
        d_model: int = param(32, min=8, help="embedding width")
        heads: int = param(4, min=1, help="attention heads")
        layers: int = param(2, min=1, help="attention layers")
        hidden: int = param(64, min=4, help="width of the scorers")
        z_dim: int = param(4, min=1, help="cVAE latent size")
        recon_hidden: int = param(32, min=4, help="width of the reconstruction networks")
        threads: int = param(1, min=1, max=256, help="torch CPU threads")

    def __init__(self, settings: "ATAHRLTrainer.Settings", mission: Any, registry: Any):
        self.s = settings
        self.mission = mission
        self.registry = registry
        slots = mission.slots
        factory = {slot: registry.get(kind, getattr(slots, slot), "[components]").factory
                   for slot, kind in (("initial", "policy"), ("condition", "condition"),
                                      ("reallocation", "policy"))}
        self.trains_ita = _is(factory["initial"], AttentionITA)
        self.trains_cond = _is(factory["condition"], CTRPolicy)
        self.trains_tr = _is(factory["reallocation"], CTRPolicy)
        self.trains_aux = any(_is(registry.get("reconstructor", n, "").factory,
                                  AuxReconstructor) for n in slots.reconstructors)
        if not (self.trains_ita or self.trains_cond or self.trains_tr):
            raise MissionError("[components]", "initial", "trainer 'ata_hrl' has nothing to "
                               "train: put 'attention' in the initial slot or 'ctr' in the "
                               "condition or reallocation slot", file=mission.source)
        self.cfg = NetConfig(d_model=settings.d_model, heads=settings.heads,
                             layers=settings.layers, hidden=settings.hidden,
                             z_dim=settings.z_dim, recon_hidden=settings.recon_hidden,
                             status_hidden=settings.status_hidden if self.trains_aux else 0,
                             cond_linear=bool(settings.cond_scenarios)
                             and settings.cond_fit in ("features", "rule"),
                             cond_rule=bool(settings.cond_scenarios)
                             and settings.cond_fit == "rule")
        torch.manual_seed(settings.seed)
        self.net = ATAHRLNet(self.cfg)
        self.policy_params = [p for n, p in self.net.named_parameters()
                              if not n.startswith(("fatigue.", "latency.", "status."))]
        self.opt = torch.optim.Adam(self.policy_params, lr=settings.lr)
        self.aux_opt = torch.optim.Adam(list(self.net.fatigue.parameters())
                                        + list(self.net.latency.parameters()),
                                        lr=settings.aux_lr)
        self.status_opt = (torch.optim.Adam(self.net.status.parameters(), lr=settings.status_lr)
                           if self.cfg.status_hidden else None)
        self.gen = torch.Generator().manual_seed(settings.seed + 1)
        self.status_gen = torch.Generator().manual_seed(settings.seed + 2)
        self.counters = {"aux": 0, "status": 0, "ita": 0, "cond": 0, "ctr": 0, "episodes": 0}
        self.validated_at_start: set[str] = set()   # phases whose step-0 validation is logged
        self.best_eval = -math.inf
        self.wall = 0.0
        self.run_folder: TrainRun | None = None

    # -- the trainer interface ------------------------------------------------------------------
    def scenario_ranges(self) -> list[tuple[int, int, int]]:
        s = self.s
        per_step = s.batch_size
        ranges = [(s.seed, PHASE_BASE[p], PHASE_BASE[p] + PHASE_SPAN) for p in PHASE_BASE]
        steps = {"aux": s.aux_batches + 1 + self._status_rollouts(s.status_batches + 1),
                 "ita": s.ita_steps, "ctr": s.ctr_steps,
                 "cond": -(-s.cond_scenarios * len(self._cond_pairs()) // per_step)}
        for phase, n in steps.items():
            if n * per_step > PHASE_SPAN:
                raise MissionError(f"[{self.name}]", "batch_size", f"{phase}: {n} steps of "
                                   f"{per_step} scenarios overrun its range of {PHASE_SPAN} ids")
        ranges.append((s.seed + VALIDATION_SEED_OFFSET, 0, s.eval_scenarios))
        for other in (s.ita_from, s.init_from):   # what another run's networks saw
            if other:
                ranges += [r for r in trained_on(other, KIND) if r not in ranges]
        return ranges

    @property
    def name(self) -> str:
        return getattr(self, "component_name", "ata_hrl")

    def phases(self) -> dict[str, int]:
        s = self.s
        return {"aux": s.aux_steps if self.trains_aux else 0,
                "status": s.status_steps if self.cfg.status_hidden else 0,
                "ita": s.ita_steps if self.trains_ita and not s.ita_from else 0,
                "cond": (s.cond_rounds if s.cond_fit == "rule" else s.cond_steps)
                if self.trains_cond and s.cond_scenarios else 0,
                "ctr": s.ctr_steps if (self.trains_cond or self.trains_tr) else 0}

    def total_steps(self) -> int:
        return sum(self.phases().values())

    def done_steps(self) -> int:
        return sum(self.counters[k] for k in ("aux", "status", "ita", "cond", "ctr"))

    def run(self, run: TrainRun, resume: bool = False) -> dict[str, Any]:
        """Every phase, resuming wherever the counters stand."""
        self.run_folder = run
        torch.set_num_threads(self.s.threads)
        if resume:
            self.load(run.checkpoint_path, run.resume_checkpoint(KIND))
        else:
            if self.s.init_from:
                self.take_ita(self.s.init_from, whole=True)
            if self.s.ita_from:
                self.take_ita(self.s.ita_from)
        report = self.train_aux()
        report.update(self.train_status())
        self.train_policy("ita")
        report.update(self.train_condition())
        self.train_policy("ctr")
        self._tr_at_step_0()
        if not run.best_path.exists():
            self.save("best.pt")
        return {"aux": report, "best_eval": self.best_eval, "wall_s": self.wall,
                "counters": dict(self.counters), "best": str(run.best_path)}

    # -- checkpoints ------------------------------------------------------------------------------
    def checkpoint(self) -> dict[str, Any]:
        return {"kind": KIND, "format": FORMAT, "model": self.net.state_dict(),
                "config": self.cfg.as_dict(), "optimizer": self.opt.state_dict(),
                "aux_optimizer": self.aux_opt.state_dict(),
                **({"status_optimizer": self.status_opt.state_dict()} if self.status_opt else {}),
                "rng": {"torch": torch.get_rng_state(), "sampler": self.gen.get_state(),
                        "status": self.status_gen.get_state()},
                "counters": dict(self.counters), "best_eval": float(self.best_eval),
                "validated_at_start": sorted(self.validated_at_start),
                "wall_s": float(self.wall), "mission": self.mission.to_toml(),
                "trainer": self.name,
                "scenario_ranges": [list(r) for r in self.scenario_ranges()],
                "trained": [k for k, v in (("ita", self.trains_ita), ("cond", self.trains_cond),
                                           ("tr", self.trains_tr), ("aux", self.trains_aux))
                            if v],
                "ita_from": self.s.ita_from, "init_from": self.s.init_from}

    def save(self, name: str = "checkpoint.pt") -> None:
        self.run_folder.save(self.checkpoint(), name)

    def _tr_at_step_0(self) -> None:
        """A run with no CTR step (``ctr_steps = 0``) still ends with pi_TR at the CTR phase's
        step 0, copied from its ITA, in checkpoint.pt and best.pt, as a run with CTR steps
        starts from it (without this, pi_TR kept its random initialisation)."""
        if self.phases()["ctr"] != 0 or not (self.trains_tr or self.trains_cond) \
                or not (self.s.tr_from_ita and self.trains_ita):
            return
        tr_from_ita(self.net)
        self.save()
        best = self.run_folder.best_path
        if best.exists():                  # the ITA phase's best step: the same copy in it
            data = read_checkpoint(best, KIND)
            net = net_from_checkpoint(data, best, expect=self.cfg)
            tr_from_ita(net)
            data["model"] = net.state_dict()
            self.run_folder.save(data, "best.pt")

    def take_ita(self, spec: str, whole: bool = False) -> None:
        """The ITA network of another ATA-HRL checkpoint (one that trained its ITA), or, with
        `whole`, every network of it."""
        path = resolve(spec)
        data = read_checkpoint(path, KIND)
        if not whole and "ita" not in data.get("trained", []):
            raise CheckpointError(path, "trained no ITA policy (ita_from needs one that did)")
        # the status head's width may differ: a checkpoint from before the head has none, and
        # the head (trained in this run's status phase) is not taken from it
        # (unless `whole` and the widths match), nor is pi_C's linear residual, which this
        # run's cond phase fits
        own = ("status_hidden", "cond_linear", "cond_rule")
        mine = {k: v for k, v in self.cfg.as_dict().items() if k not in own}
        theirs = {k: v for k, v in (data.get("config") or {}).items() if k not in own}
        if theirs != mine:
            raise CheckpointError(path, f"architecture {data.get('config')} does not match "
                                        f"the training's {self.cfg.as_dict()}")
        prefix = "" if whole else "ita."
        part = self.net if whole else self.net.ita
        skip = ("cond.linear.",) if whole and self.cfg.status_hidden \
            and self.cfg.status_hidden == (data.get("config") or {}).get("status_hidden") \
            else ("status.", "cond.linear.")
        weights = {k[len(prefix):]: v for k, v in data["model"].items() if k.startswith(prefix)
                   and not k.startswith(skip)}
        try:
            missing, unexpected = part.load_state_dict(weights, strict=False)
            if unexpected or any(not k.startswith(skip) for k in missing):
                raise RuntimeError(f"missing {missing}, unexpected {unexpected}")
        except RuntimeError as exc:
            raise CheckpointError(path, "its networks do not fit the architecture: "
                                        f"{str(exc).splitlines()[0][:200]}") from None

    def load(self, path, data: dict[str, Any] | None = None) -> None:
        """Resume from the checkpoint at `path` (its contents `data`, if already read)."""
        data = data if data is not None else read_checkpoint(path, KIND)
        net = net_from_checkpoint(data, path, expect=self.cfg)
        self.net.load_state_dict(net.state_dict())
        try:
            self.opt.load_state_dict(data["optimizer"])
            self.aux_opt.load_state_dict(data["aux_optimizer"])
            if self.status_opt is not None:
                self.status_opt.load_state_dict(data["status_optimizer"])
                self.status_gen.set_state(data["rng"]["status"])
            torch.set_rng_state(data["rng"]["torch"])
            self.gen.set_state(data["rng"]["sampler"])
            self.counters.update({k: int(v) for k, v in data["counters"].items()})
            self.validated_at_start = set(data.get("validated_at_start", []))
        except (KeyError, ValueError, RuntimeError, TypeError) as exc:
            raise CheckpointError(path, f"cannot resume from it ({exc})") from None
        self.best_eval = float(data.get("best_eval", -math.inf))
        self.wall = float(data.get("wall_s", 0.0))

    # -- missions and components ---------------------------------------------------------------
    def _mission(self, setting: str, seed: int):
        """The mission of a step or a validation: `setting` is a team setting, or
        ``SETTING/LEVEL`` with an uncertainty level when ``uncertainty_levels`` mixes them."""
        m = self.mission
        setting, _, level = setting.partition("/")
        if setting != m.settings.setting and m.settings.setting != "custom":
            from ata.core.mission import TEAM_SETTINGS
            sz = TEAM_SETTINGS[setting]
            m = m.replace(setting=setting, humans=sz.humans, robots=sz.robots, tasks=sz.tasks)
        if level:
            from ata.core.mission import UNCERTAINTY_LEVELS
            variance, p = UNCERTAINTY_LEVELS[level]
            m = m.replace(uncertainty=level, fatigue_variance=variance, event_probability=p)
        return m.replace(seed=seed)

    def _settings(self) -> list[str]:
        """What the trainer cycles through and validates on: the team settings, each crossed
        with the uncertainty levels of ``uncertainty_levels`` (``a/high``) if any."""
        ts, levels = self.s.team_settings, self.s.uncertainty_levels
        return [f"{t}/{lv}" for lv in levels for t in ts] if levels else list(ts)

    def _setting(self, step: int) -> str:
        ts = self._settings()
        return ts[step % len(ts)]

    def _component(self, mission, slot_kind: str, name: str) -> Any:
        info = self.registry.get(slot_kind, name, "[components]")
        settings = mission.component_settings.get(name)
        if _is(info.factory, (AttentionITA, CTRPolicy, AuxReconstructor)):
            return info.factory(settings, mission, net=self.net)
        return build_component(self.registry, mission, slot_kind, name)

    def _overrides(self, mission, phase: str, recorder: Recorder | None,
                   sampler: D.Chooser | None) -> dict[str, Any]:
        """The slots' components for a rollout: the live network in every ATA-HRL part; the
        part(s) the phase trains sample and record; the ITA phase never reallocates."""
        slots = mission.slots
        out: dict[str, Any] = {}
        initial = self._component(mission, "policy", slots.initial)
        out["initial"] = initial
        if phase == "ita":
            if recorder is not None:
                initial.train_with(self.net, recorder, sampler)
        if phase == "ita" and not self.s.ita_reallocates:
            out["condition"] = build_component(self.registry, mission, "condition", "never")
            out["reallocation"] = build_component(self.registry, mission, "policy", "keep")
        else:
            ctr = None
            if self.trains_cond or self.trains_tr:
                ctr = self._component(mission, "policy", slots.reallocation
                                      if self.trains_tr else slots.condition)
                if recorder is not None and phase == "ctr":
                    ctr.train_with(self.net, recorder, sampler)
            out["condition"] = ctr if self.trains_cond else \
                self._component(mission, "condition", slots.condition)
            out["reallocation"] = ctr if self.trains_tr else \
                self._component(mission, "policy", slots.reallocation)
        if phase == "ita" and not self.s.ita_reallocates:   # the ITA reads I only
            out["reconstructors"] = build_component(self.registry, mission, "reconstructor",
                                                    "identity")
        elif self.trains_aux:
            out["reconstructors"] = AuxReconstructor(None, mission, net=self.net)
        return out

    def rollout(self, mission, ids: np.ndarray, phase: str, train: bool):
        recorder = Recorder() if train else None
        sampler = D.torch_sampler(self.gen) if train else None
        overrides = self._overrides(mission, phase, recorder, sampler)
        record = Simulation(mission, self.registry, ids, overrides=overrides).run()
        return record, recorder

    def _ids(self, phase: str, step: int) -> np.ndarray:
        s = self.s
        return PHASE_BASE[phase] + step * s.batch_size + np.arange(s.batch_size)

    # -- held-out validation -------------------------------------------------------------------
    def evaluate(self, phase: str) -> tuple[float, float]:
        """(mean total team performance, its expectation) on the validation scenarios of every
        team setting (and uncertainty level) trained on, each decision by its mode."""
        totals, expected = [], []
        for setting in self._settings():
            mission = self._mission(setting, self.s.seed + VALIDATION_SEED_OFFSET)
            with torch.no_grad():
                record, _ = self.rollout(mission, np.arange(self.s.eval_scenarios), phase,
                                         train=False)
            totals.append(record.total.mean())
            expected.append(record.r_expected.sum(1).mean())
        return float(np.mean(totals)), float(np.mean(expected))

    # -- phase 1: auxiliary reconstruction ---------------------------------------------------------
    def teacher_log(self, mission, ids: np.ndarray) -> dict[str, list]:
        """Roll out the greedy teacher (greedy initial allocation, greedy reallocation on
        events) and log the observed and the true S of every epoch."""
        from ata import hookimpl

        log = {"raw": [], "true": [], "fatigue": [], "cognitive": None,
               "status_in": [], "status_target": []}
        greedy = build_component(self.registry, mission, "policy", "greedy")
        on_event = build_component(self.registry, mission, "condition", "on_event")

        class Teacher:
            @hookimpl
            def ata_initial_allocation(self, ctx):
                log["cognitive"] = ctx.inherent["humans"].col("cognitive").copy()
                self._log(ctx)
                return greedy.ata_initial_allocation(ctx)

            @hookimpl
            def ata_should_reallocate(self, ctx):
                self._log(ctx)
                return on_event.ata_should_reallocate(ctx)

            @hookimpl
            def ata_reallocate(self, ctx, active):
                return greedy.ata_reallocate(ctx, active)

            def _log(self, ctx):
                truth = self.simulation.last_truth      # the teacher wraps the kernel
                log["raw"].append(state_features(ctx.observed))
                log["true"].append(state_features(truth))
                log["fatigue"].append(truth["humans"].col("fatigue").copy())
                if recon.status_features is not None and ctx.epoch >= 1:
                    log["status_in"].append(recon.status_features)
                    log["status_target"].append(status_targets(truth))

        teacher = Teacher()
        # features only: the teacher plans from the observation as it is
        recon = AuxReconstructor(None, mission, net=self.net, guess=False)
        overrides = {"initial": teacher, "condition": teacher, "reallocation": teacher,
                     "reconstructors": recon}
        teacher.simulation = Simulation(mission, self.registry, ids, overrides=overrides)
        with torch.no_grad():
            teacher.simulation.run()
        return log

    def aux_data(self, first: int, batches: int) -> dict[str, torch.Tensor]:
        fat_in, fat_target = [], []
        seq_in, seq_target = {"robots": [], "tasks": []}, {"robots": [], "tasks": []}
        for i in range(batches):
            mission = self._mission(self._setting(first + i), self.s.seed)
            log = self.teacher_log(mission, self._ids("aux", first + i))
            T = len(log["raw"])
            hours = np.stack([r["humans"][..., 0] * 3.0 for r in log["raw"]], 1)   # (B, T, H)
            f_obs = np.stack([r["humans"][..., 1] for r in log["raw"]], 1)
            cog = np.broadcast_to(log["cognitive"][:, None, :], hours.shape)
            fat_in.append(np.stack([f_obs, hours, cog], -1).reshape(-1, 3))
            fat_target.append(np.stack(log["fatigue"], 1).reshape(-1))
            for g in ("robots", "tasks"):
                raw = np.stack([r[g] for r in log["raw"]], 2)          # (B, N, T, F)
                true = np.stack([r[g] for r in log["true"]], 2)
                B, N = raw.shape[:2]
                seq_in[g].append(raw.reshape(B * N, T, -1))
                seq_target[g].append(true.reshape(B * N, T, -1))
        out = {"fatigue_in": np.concatenate(fat_in), "fatigue_target": np.concatenate(fat_target)}
        for g in ("robots", "tasks"):
            # sequences of different team sizes have the same length T: stack them all
            out[f"{g}_in"] = np.concatenate(seq_in[g])
            out[f"{g}_target"] = np.concatenate(seq_target[g])
        return {k: torch.as_tensor(v, dtype=torch.float32) for k, v in out.items()}

    # -- phase 1b: the aux module's status head --------------------------------------------------
    def _status_rollouts(self, batches: int) -> int:
        """Teacher rollouts of `batches` batches per team setting and status level."""
        return batches * len(self.s.team_settings) * len(self.s.status_levels)

    def status_data(self, first: int, batches: int) -> tuple[torch.Tensor, torch.Tensor]:
        """(features, targets) of every POI at every epoch >= 1 of greedy teacher rollouts with
        the injectors on: `batches` batches per team setting and level, from the aux phase's id
        range, after the aux phase's own rollouts."""
        X, Y = [], []
        combos = [(t, lv) for t in self.s.team_settings for lv in self.s.status_levels]
        for i in range(batches):
            for j, (setting, level) in enumerate(combos):
                k = self.s.aux_batches + 1 + (first + i) * len(combos) + j
                log = self.teacher_log(self._mission(f"{setting}/{level}", self.s.seed),
                                       self._ids("aux", k))
                X += [x.reshape(-1, x.shape[-1]) for x in log["status_in"]]
                Y += [y.reshape(-1, y.shape[-1]) for y in log["status_target"]]
        return torch.as_tensor(np.concatenate(X)), torch.as_tensor(np.concatenate(Y))

    def train_status(self) -> dict[str, float]:
        steps = self.phases()["status"]
        if steps == 0 or self.counters["status"] >= steps:
            return {}
        x, y = self.status_data(0, self.s.status_batches)
        while self.counters["status"] < steps:
            t0 = time.perf_counter()
            idx = torch.randint(0, x.shape[0], (min(x.shape[0], 4096),), generator=self.status_gen)
            loss = torch.nn.functional.binary_cross_entropy_with_logits(
                self.net.status(x[idx]), y[idx])
            self.status_opt.zero_grad()
            loss.backward()
            self.status_opt.step()
            self.counters["status"] += 1
            self.wall += time.perf_counter() - t0
            self.run_folder.log({"phase": "status", "step": self.counters["status"],
                                 "loss": f"{loss.item():.5f}", "wall_s": f"{self.wall:.1f}"})
            if self.counters["status"] % self.s.checkpoint_every == 0:
                self.save()
        self.save()
        return self.status_report()

    def status_report(self) -> dict[str, float]:
        """On held-out teacher rollouts (one batch per team setting and level), as shares of
        all their POI-epochs after the first epoch: the POIs shown open that are truly captured
        / committed (hidden), how many of those the head finds, and how many it takes wrongly."""
        x, y = self.status_data(self.s.status_batches, 1)
        with torch.no_grad():
            prob = torch.sigmoid(self.net.status(x)).numpy()
        x, y = x.numpy(), y.numpy()
        g = status_guesses(x, prob)
        out = {}
        for name, (shown, target) in STATUS_GUESSES.items():
            hidden = (x[:, shown] > 0.5) & (y[:, target] < 0.5)
            took = g[name][:, 0] > 0.5
            out[f"status_{name}_hidden"] = float(hidden.mean())
            out[f"status_{name}_found"] = float((took & hidden).mean())
            out[f"status_{name}_wrong"] = float((took & ~hidden).mean())
        return out

    def aux_losses(self, data: dict[str, torch.Tensor], idx: dict | None = None,
                   sample: bool = True) -> tuple[torch.Tensor, ...]:
        """(cVAE loss, fatigue MSE, latency loss (`aux_loss` of the robot and task rows), latency
        MSE) on the data (or the rows in idx)."""
        fi, ft = data["fatigue_in"], data["fatigue_target"]
        if idx is not None:
            fi, ft = fi[idx["fatigue"]], ft[idx["fatigue"]]
        recon, mu, logvar = self.net.fatigue(fi[:, 0], fi[:, 1], fi[:, 2], sample=sample)
        cvae = FatigueCVAE.loss(recon, ft, mu, logvar)
        f_mse = ((recon - ft) ** 2).mean()
        lat, lat_mse = torch.zeros(()), torch.zeros(())
        for g in ("robots", "tasks"):
            x, y = data[f"{g}_in"], data[f"{g}_target"]
            if idx is not None:
                x, y = x[idx[g]], y[idx[g]]
            est, _ = self.net.latency[g](x)
            err = est - y
            sq = (err * err).mean()
            lat_mse = lat_mse + sq
            lat = lat + (err.abs().mean() if self.s.aux_loss == "l1" else sq)
        return cvae, f_mse, lat, lat_mse

    def train_aux(self) -> dict[str, float]:
        steps = self.phases()["aux"]
        if steps == 0 or self.counters["aux"] >= steps:
            return {}
        data = self.aux_data(0, self.s.aux_batches)
        n = {"fatigue": data["fatigue_in"].shape[0], "robots": data["robots_in"].shape[0],
             "tasks": data["tasks_in"].shape[0]}
        while self.counters["aux"] < steps:
            t0 = time.perf_counter()
            idx = {k: torch.randint(0, v, (min(v, 1024),), generator=self.gen)
                   for k, v in n.items()}
            cvae, f_mse, lat, lat_mse = self.aux_losses(data, idx)
            loss = cvae + lat
            self.aux_opt.zero_grad()
            loss.backward()
            self.aux_opt.step()
            self.counters["aux"] += 1
            self.wall += time.perf_counter() - t0
            self.run_folder.log({"phase": "aux", "step": self.counters["aux"],
                                 "loss": f"{loss.item():.5f}",
                                 "aux_fatigue_mse": f"{f_mse.item():.5f}",
                                 "aux_latency_mse": f"{lat_mse.item():.5f}",
                                 "wall_s": f"{self.wall:.1f}"})
            if self.counters["aux"] % self.s.checkpoint_every == 0:
                self.save()
        self.save()
        return self.aux_report()

    def aux_report(self) -> dict[str, float]:
        """Held-out reconstruction errors against the raw observation's."""
        data = self.aux_data(self.s.aux_batches, 1)
        with torch.no_grad():
            _, f_mse, _, _ = self.aux_losses(data, sample=False)
            raw_f = ((data["fatigue_in"][:, 0] - data["fatigue_target"]) ** 2).mean()
            out = {"fatigue_mse": f_mse.item(), "fatigue_mse_raw": raw_f.item()}
            for g in ("robots", "tasks"):
                est, _ = self.net.latency[g](data[f"{g}_in"])
                err, raw = est - data[f"{g}_target"], data[f"{g}_in"] - data[f"{g}_target"]
                out[f"{g}_mse"], out[f"{g}_mse_raw"] = (err ** 2).mean().item(), (raw ** 2).mean().item()
                out[f"{g}_mae"], out[f"{g}_mae_raw"] = err.abs().mean().item(), raw.abs().mean().item()
        return out

    # -- phases 2 and 3: policies -----------------------------------------------------------------
    def train_policy(self, phase: str) -> None:
        steps = self.phases()[phase]
        if steps == 0 or self.counters[phase] >= steps:
            return
        s = self.s
        for group in self.opt.param_groups:
            group["lr"] = s.lr if phase == "ita" else s.ctr_lr
        if phase == "ctr" and self.counters["ctr"] == 0 and s.tr_from_ita \
                and self.trains_ita:
            tr_from_ita(self.net)
        if self.counters[phase] == 0 and phase not in self.validated_at_start:
            self._validate(phase, 0)          # the untrained part: greedy's prior alone
            self.validated_at_start.add(phase)
            self.save()                       # a resumed run neither redoes nor loses its row
        while self.counters[phase] < steps:
            t0 = time.perf_counter()
            step = self.counters[phase]
            setting = self._setting(step)
            mission = self._mission(setting, s.seed)
            ids = np.repeat(self._ids(phase, step), s.samples)
            record, rec = self.rollout(mission, ids, phase, train=True)
            R, loss = self.rewards_and_loss(phase, record, rec)
            self.update(loss)
            self.counters[phase] += 1
            self.counters["episodes"] += ids.size
            dt = time.perf_counter() - t0
            self.wall += dt
            row = {"phase": phase, "step": step + 1, "setting": setting,
                   "episodes": self.counters["episodes"], "episodes_per_s": f"{ids.size / dt:.1f}",
                   "loss": f"{loss.item():.4f}", "mean_score": f"{R['total'].mean():.2f}",
                   "R_ITA": f"{R['R_ITA'].mean():.2f}", "R_C": f"{R['R_C'].mean():.2f}",
                   "R_TR": f"{R['R_TR'].mean():.2f}",
                   "reallocations": f"{record.reallocated[:, 1:].sum(1).mean():.2f}",
                   "wall_s": f"{self.wall:.1f}"}
            if self.counters[phase] % s.eval_every == 0 or self.counters[phase] == steps:
                self._validate(phase, self.counters[phase], row)
            else:
                self.run_folder.log(row)
            if self.counters[phase] % s.checkpoint_every == 0:
                self.save()
        self.save()

    # -- phase 3 (optional): pi_C by counterfactual rollouts ---------------------------------------
    def _cond_pairs(self) -> list[str]:
        return [f"{t}/{lv}" for lv in self.s.cond_levels for t in self.s.team_settings]

    def train_condition(self) -> dict[str, float]:
        """The cond phase: label pi_C's decisions by counterfactual rollouts (`cond_batch`),
        then fit pi_C alone to the better choices, each weighted by how much better it was
        (with a rule, once per round of `cond_rounds`). A fit, or a rule's round, is done whole
        or not at all: a run killed inside it does it again on resume, from the same weights and
        the same rollouts (every decision is its mode)."""
        steps = self.phases()["cond"]
        if steps == 0 or self.counters["cond"] >= steps:
            return {}
        s = self.s
        if s.tr_from_ita and self.trains_ita and self.counters["ctr"] == 0:
            tr_from_ita(self.net)          # pi_TR as the CTR phase's step 0 has it
        if "cond" not in self.validated_at_start:
            self._validate("cond", 0)     # pi_C as it stands (at first: the on_event prior)
            self.validated_at_start.add("cond")
            self.save()
        pairs = self._cond_pairs()
        report: dict[str, float] = {}
        # a rule fits once per round (each round a step, checkpointed: a run killed in a later
        # round resumes there, with the rule of the rounds before); the other fits take their
        # `cond_steps` Adam steps on one collection
        while self.counters["cond"] < steps:
            t0 = time.perf_counter()
            batches = self._cond_labels(pairs)
            if s.cond_fit == "rule":
                fit_rule(self.net.cond.linear, batches, s.cond_l2)
                with torch.no_grad():
                    loss = self.cond_loss(batches)
                self.counters["cond"] += 1
            else:
                fit = self.net.cond.linear if self.net.cond.linear is not None else self.net.cond
                opt = torch.optim.Adam(fit.parameters(), lr=s.cond_lr)
                for _ in range(steps):
                    loss = self.cond_loss(batches)
                    opt.zero_grad()
                    loss.backward()
                    opt.step()
                self.counters["cond"] = steps
            self.counters["episodes"] += sum(b["episodes"] for b in batches)
            dt = time.perf_counter() - t0
            self.wall += dt
            labelled = np.concatenate([b["weight"][b["labelled"]] for b in batches])  # |gain|
            better = np.concatenate([(b["target"] != b["taken"])[b["labelled"]]
                                     for b in batches])
            row = {"phase": "cond", "step": self.counters["cond"], "setting": ",".join(pairs),
                   "episodes": self.counters["episodes"],
                   "episodes_per_s": f"{sum(b['episodes'] for b in batches) / dt:.1f}",
                   "loss": f"{loss.item():.4f}", "wall_s": f"{self.wall:.1f}"}
            self._validate("cond", self.counters["cond"], row)
            self.save()
            report = {"cond_turned_over": int(labelled.size),
                      "cond_other_better": float(better.mean()) if better.size else 0.0,
                      "cond_mean_abs_gain": float(labelled.mean()) if labelled.size else 0.0}
        return report

    def _cond_labels(self, pairs: list[str]) -> list[dict[str, Any]]:
        """`cond_batch` over the cond phase's training scenarios of every pair, in batches."""
        s = self.s
        batches = []
        for j, pair in enumerate(pairs):
            mission = self._mission(pair, s.seed)
            first = PHASE_BASE["cond"] + j * s.cond_scenarios
            for lo in range(0, s.cond_scenarios, s.batch_size):
                ids = first + np.arange(lo, min(lo + s.batch_size, s.cond_scenarios))
                batches.append(self.cond_batch(mission, ids))
                if self.run_folder is not None and self.run_folder.on_row is not None:
                    done = j * s.cond_scenarios + lo + ids.size    # the progress bar alone
                    self.run_folder.on_row({"phase": "cond", "step": f"rollouts of {done} of "
                                            f"{len(pairs) * s.cond_scenarios} scenarios"})
        return batches

    def cond_batch(self, mission, ids: np.ndarray) -> dict[str, Any]:
        """Counterfactual labels of pi_C's decisions on scenarios `ids`: the policy as it
        decides, recording pi_C's inputs; then, on the same random streams, one run per
        scenario and turned-over epoch. Each turned-over epoch's target is the choice that did
        better from that epoch on, its weight by how much."""
        s = self.s
        rec = Recorder()
        with torch.no_grad():
            base = Simulation(mission, self.registry, ids, overrides=self._overrides(
                mission, "ctr", rec, D.argmax_chooser)).run()
        taken = np.stack(rec.cond_choice, 1)                      # (B, T-1): epochs 1..T-1
        B, E1 = taken.shape
        if s.cond_epochs == "all":
            labelled = np.ones_like(taken)
        elif self._rule_on():    # the rule decides event epochs: each of them, either way
            labelled = np.stack(rec.cond_prior, 1) > 0
        else:                    # where the policy reallocated
            labelled = taken
        sb, se = np.nonzero(labelled)
        gain = np.zeros((B, E1))
        if sb.size:
            overrides = self._overrides(mission, "ctr", None, None)
            overrides["condition"].flip_at = se + 1
            with torch.no_grad():
                flipped = Simulation(mission, self.registry, ids[sb], overrides=overrides).run()
            go_b, go_f = self._to_go(base), self._to_go(flipped)
            gain[sb, se] = go_f[np.arange(sb.size), se + 1] - go_b[sb, se + 1]
        with torch.no_grad():
            emb_i = self.net.tr.encoder(to_tensors(rec.inherent))
            pooled = torch.stack([torch.cat([e[g] for g in GROUPS], 1).mean(1) for e in (
                self.net.tr.embed(emb_i, to_tensors(raw), to_tensors(seen))
                for raw, seen in rec.cond_state)], 1)              # (B, T-1, d)
        return {"pooled": pooled, "feats": torch.as_tensor(np.stack(rec.cond_feats, 1)),
                "prior": torch.as_tensor(np.stack(rec.cond_prior, 1)), "taken": taken,
                "labelled": labelled, "target": taken ^ (gain > 0), "weight": np.abs(gain),
                "episodes": B + sb.size}

    def _rule_on(self) -> bool:
        """Whether pi_C has a fitted rule, switched on, deciding its event epochs."""
        cond = self.net.cond
        return bool(cond.rule and cond.linear.on > 0)

    def _to_go(self, record) -> np.ndarray:
        """(E, T) what the cond phase compares, from each epoch on."""
        expected = self.s.reward == "expected"
        if self.s.cond_target == "R_C":
            return rewards_to_go(record, expected=expected)["R_C"]
        return to_go(record.r_expected if expected else record.r_perf)

    def cond_loss(self, batches: list[dict[str, Any]]) -> torch.Tensor:
        """pi_C's cross-entropy against the better choices, weighted by how much better."""
        total, weight = torch.zeros(()), 0.0
        for b in batches:
            E, E1, _ = b["pooled"].shape
            hidden = torch.zeros(E, self.cfg.d_model)
            logits = []
            for k in range(E1):
                logit, hidden = self.net.cond(b["pooled"][:, k], b["feats"][:, k],
                                              b["prior"][:, k], hidden)
                logits.append(logit)
            w = torch.as_tensor(b["weight"] * b["labelled"], dtype=torch.float32)
            bce = torch.nn.functional.binary_cross_entropy_with_logits(
                torch.stack(logits, 1), torch.as_tensor(b["target"], dtype=torch.float32),
                reduction="none")
            total = total + (w * bce).sum()
            weight += float(w.sum())
        return total / max(weight, 1e-9)

    def update(self, loss: torch.Tensor) -> None:
        """One Adam step of the policies on `loss`, their gradients clipped (not the
        reconstructors')."""
        self.opt.zero_grad()
        loss.backward()
        if self.s.grad_clip > 0:
            torch.nn.utils.clip_grad_norm_(self.policy_params, self.s.grad_clip)
        self.opt.step()

    def rewards_and_loss(self, phase: str, record, rec) -> tuple[dict, torch.Tensor]:
        """The paper's rewards of a training rollout (with their per-epoch rewards-to-go) and
        the policy loss of the phase."""
        expected = self.s.reward == "expected"
        R = hierarchical_rewards(record, expected=expected)
        R.update({f"{k}_to_go": v for k, v in rewards_to_go(record, expected=expected).items()})
        return R, self.policy_loss(phase, rec, R)

    def _validate(self, phase: str, step: int, row: dict | None = None) -> None:
        score, expected = self.evaluate(phase)
        row = dict(row or {"phase": phase, "step": step, "wall_s": f"{self.wall:.1f}"})
        row["eval_score"] = f"{score:.2f}"
        row["eval_expected"] = f"{expected:.2f}"
        # the ITA phase selects by the ITA alone; the first phase that reallocates (cond, else
        # ctr) starts afresh from its untrained parts (the ITA's validation never reallocated)
        if step == 0 and (phase == "cond" or (phase == "ctr" and not self.phases()["cond"])):
            self.best_eval = -math.inf
        if expected > self.best_eval:
            self.best_eval = expected
            self.save("best.pt")
        self.run_folder.log(row)

    def policy_loss(self, phase: str, rec: Recorder, R: dict[str, np.ndarray]) -> torch.Tensor:
        """Shared-baseline policy gradient (+ self-imitation, entropy) of the phase's parts."""
        s = self.s
        K = s.samples
        loss = torch.zeros(())
        if phase == "ita":
            emb = self.net.ita.encoder(to_tensors(rec.inherent))
            logp, ent = D.trace_log_prob(self.net.ita, emb, rec.ita)
            n = max(rec.ita.n_steps, 1)
            return self._term(R["R_ITA"], logp, ent, n, K)
        emb_i = self.net.tr.encoder(to_tensors(rec.inherent))
        if self.trains_cond and rec.cond_choice:
            # pi_C decides at epochs 1 .. T-1: each decision against R_C from its epoch on
            logp, ent = self._condition_log_prob(rec, emb_i)          # (E, T-1)
            adv = per_epoch_advantage(R["R_C_to_go"][:, 1:], K)
            loss = loss + self._weighted(adv, logp, ent, K, R["R_C_to_go"][:, 1:])
        if self.trains_tr and rec.tr:
            adv_all = per_epoch_advantage(R["R_TR_to_go"], K)
            terms, ents, advs = [], [], []
            for item in rec.tr:
                rows = torch.as_tensor(item["rows"])
                emb = self.net.tr.embed({g: v[rows] for g, v in emb_i.items()},
                                        to_tensors(item["raw"]), to_tensors(item["seen"]))
                lp, en = D.trace_log_prob(self.net.tr, emb, item["trace"])
                terms.append(lp)
                ents.append(en)
                advs.append(adv_all[item["rows"], item["epoch"]])
            adv = np.concatenate(advs)
            scale = adv.std() + 1e-6
            logp = torch.cat(terms)
            loss = loss - (torch.as_tensor(adv / scale, dtype=torch.float32) * logp).sum() \
                / R["total"].size - self.s.entropy * torch.cat(ents).sum() / R["total"].size
        return loss

    def _weighted(self, adv: np.ndarray, logp: torch.Tensor, ent: torch.Tensor, K: int,
                  reward: np.ndarray) -> torch.Tensor:
        """-(advantage * log-prob) summed over decisions, averaged over episodes, minus the
        entropy bonus; plus the pull towards each scenario's best sample (by its reward from
        the first decision on)."""
        E = adv.shape[0]
        scale = adv.std() + 1e-6
        term = -(torch.as_tensor(adv / scale, dtype=torch.float32) * logp).sum() / E
        term = term - self.s.entropy * ent.sum() / E
        if self.s.self_imitation > 0:
            first = reward[:, 0]
            best = first.reshape(-1, K).argmax(1) + np.arange(E // K) * K
            term = term - self.s.self_imitation * logp[torch.as_tensor(best)].sum(-1).mean() \
                / logp.shape[1]
        return term

    def _condition_log_prob(self, rec: Recorder, emb_i: dict[str, torch.Tensor]
                            ) -> tuple[torch.Tensor, torch.Tensor]:
        """pi_C's log-probabilities and entropies of its decisions, (E, epochs decided)."""
        E = rec.cond_feats[0].shape[0]
        hidden = torch.zeros(E, self.cfg.d_model)
        logps, ents = [], []
        for k, (raw, seen) in enumerate(rec.cond_state):
            emb = self.net.tr.embed(emb_i, to_tensors(raw), to_tensors(seen))
            pooled = torch.cat([emb[g] for g in GROUPS], 1).mean(1)
            logit, hidden = self.net.cond(pooled, torch.as_tensor(rec.cond_feats[k]),
                                          torch.as_tensor(rec.cond_prior[k]), hidden)
            two = torch.log_softmax(torch.stack([torch.zeros_like(logit), logit], -1), -1)
            choice = torch.as_tensor(rec.cond_choice[k]).long()
            logps.append(two.gather(-1, choice[:, None])[:, 0])
            ents.append(-(two.exp() * two).sum(-1))
        return torch.stack(logps, 1), torch.stack(ents, 1)

    def _term(self, reward: np.ndarray, logp: torch.Tensor, ent: torch.Tensor, n: float,
              K: int) -> torch.Tensor:
        """-(advantage * log-prob) with each scenario's mean as the baseline, minus the
        entropy bonus, plus the pull towards each scenario's best sample (per decision)."""
        adv = shared_baseline_advantage(reward, K)
        scale = adv.std() + 1e-6
        term = -(torch.as_tensor(adv / scale, dtype=torch.float32) * logp).mean()
        term = term - self.s.entropy * ent.mean() / n
        if self.s.self_imitation > 0:
            best = reward.reshape(-1, K).argmax(1) + np.arange(reward.size // K) * K
            term = term - self.s.self_imitation * logp[torch.as_tensor(best)].mean() / n
        return term


def per_epoch_advantage(reward: np.ndarray, samples: int) -> np.ndarray:
    """(E, T) rewards from each epoch on, less the mean over the scenario's samples at that
    epoch: the shared baseline, epoch by epoch (zero-sum per scenario and epoch)."""
    E, T = reward.shape
    r = reward.reshape(E // samples, samples, T)
    return (r - r.mean(1, keepdims=True)).reshape(E, T)


def shared_baseline_advantage(reward: np.ndarray, samples: int) -> np.ndarray:
    """Each sample's reward less the mean of its scenario's samples: rewards (B * K,) laid out
    scenario by scenario; the advantages of one scenario sum to zero."""
    r = np.asarray(reward, dtype=float).reshape(-1, samples)
    return (r - r.mean(1, keepdims=True)).reshape(-1)


def _is(factory: Any, cls: type | tuple[type, ...]) -> bool:
    return isinstance(factory, type) and issubclass(factory, cls)


def tr_from_ita(net) -> None:
    """pi_TR's encoder and decoder scorers as the ITA's, its state embedding and keep step at
    zero: at the start of the CTR phase pi_TR decodes exactly as the trained ITA (a pure
    function of the ITA's weights, so a resumed run does the same)."""
    tr, ita = net.tr, net.ita
    with torch.no_grad():
        tr.encoder.load_state_dict(ita.encoder.state_dict())
        tr.scorers.load_state_dict(ita.scorers.state_dict())
        tr.auto.copy_(ita.auto)
        tr.onboard.copy_(ita.onboard)
        for layer in [*tr.state.values(), tr.keep.out[-1], tr.keep.linear]:
            torch.nn.init.zeros_(layer.weight)
            torch.nn.init.zeros_(layer.bias)


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


def fit_rule(linear: torch.nn.Linear, batches: list[dict[str, Any]], l2: float) -> None:
    """cond_fit = "rule": `linear` becomes the logit of "reallocating does better" at the
    labelled event epochs, a logistic regression on the condition features (standardised
    over those epochs, the standardisation folded into the layer), each epoch weighted by how
    much better the better choice was."""
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
        linear.weight.copy_(torch.as_tensor(beta[:-1] / sd)[None])
        linear.bias.copy_(torch.as_tensor([beta[-1] - float(np.sum(beta[:-1] * mu / sd))]))
        linear.on.fill_(1.0)
