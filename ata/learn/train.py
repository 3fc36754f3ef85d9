"""`ata train`: the training of ATA-HRL and its ablations, with checkpoints and resume.

Three phases, each with its own step counter (docs/training.md gives the reasons):

1. **aux** (when the mission's reconstructors include ``aux``): roll out the greedy teacher,
   log the observed and the true states, and fit the cVAE (reconstruction + 0.1 KL) and the
   stacked GRUs (MSE against the true rows), supervised, before any RL.
2. **imitation** (``imitation_steps`` > 0): a warm start. The attention ITA imitates the greedy
   initial allocation; pi_C imitates the event-triggered condition and pi_TR the greedy
   reallocation, along the teacher's trajectories (cross-entropy).
3. **rl**: REINFORCE with a batch-mean baseline on the paper's hierarchical rewards: R_ITA for
   the ITA policy, R_C for pi_C, R_TR for pi_TR, plus an entropy bonus.

A checkpoint (``checkpoint.pt`` in the run folder, written atomically every
``checkpoint_every`` steps and at the end of each phase) holds the weights, the optimiser,
the torch RNG states, the step counters, the architecture and the resolved mission; it loads
with ``torch.load(..., weights_only=True)``. ``best.pt`` is the checkpoint of the best held-out
evaluation. ``log.csv`` has one row per step.
"""

from __future__ import annotations

import csv
import math
import os
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

import numpy as np
import torch

from ata.core.errors import MissionError
from ata.core.kernel import Simulation
from ata.core.rewards import hierarchical_rewards
from ata.core.state import Allocation, DecisionContext
from ata.learn import nets
from ata.learn.features import (inherent_features, masks_for, state_features,
                                to_tensors)
from ata.learn.nets import ATAHRLNet, NetConfig
from ata.learn.runtime import Recorder, net_from_checkpoint, read_checkpoint
from ata.plugins.conditions import OnEvent
from ata.plugins.ctr import CTRPolicy, reconstructed_features
from ata.plugins.policies.attention import AttentionITA
from ata.plugins.policies.greedy import GreedyPolicy
from ata.plugins.auxiliary import AuxReconstructor

TRAIN_MISSION = Path(__file__).resolve().parent.parent / "missions" / "train_ata_hrl.toml"
"""The built-in training mission of `ata train`."""

EVAL_SEED_OFFSET = 1_000_003
"""Held-out evaluation during training uses root seed train.seed + this."""

TRP_MISSION = TRAIN_MISSION.with_name("train_tr_pomdp.toml")
"""The built-in training mission of `ata train --plugins trp` (TR-POMDP; with ita, AtRL-TR)."""

LOG_FIELDS = ["phase", "step", "episodes", "samples_per_s", "loss", "mean_score", "R_ITA",
              "R_C", "R_TR", "eval_score", "aux_fatigue_mse", "aux_latency_mse", "epsilon",
              "wall_s"]


def net_config(mission) -> NetConfig:
    t = mission.train
    return NetConfig(d_model=t.d_model, heads=t.heads, layers=t.layers, z_dim=t.z_dim,
                     recon_hidden=t.recon_hidden)


@dataclass
class Method:
    """Which learned parts the mission's slots use."""

    ita: bool
    ctr_condition: bool
    ctr_realloc: bool
    aux: bool
    dqn: bool = False

    @classmethod
    def of(cls, mission) -> "Method":
        s = mission.slots
        return cls(ita=s.initial == "attention", ctr_condition=s.condition == "ctr",
                   ctr_realloc=s.reallocation == "ctr", aux="aux" in s.reconstructors,
                   dqn=s.reallocation == "tr_pomdp")

    @property
    def policy_gradient(self) -> bool:
        """Whether there is an attention/GRU policy to train (imitation, then REINFORCE)."""
        return self.ita or self.ctr_condition or self.ctr_realloc


# -- the greedy teacher, recording what the students learn from ----------------------------------

@dataclass
class TeacherLog:
    """Per epoch: features of I, raw S, reconstructed S, true S; the teacher's choices."""

    inherent: dict[str, np.ndarray] | None = None
    ita: np.ndarray | None = None                          # (B, P, 3)
    raw: list[dict[str, np.ndarray]] = field(default_factory=list)
    recon: list[dict[str, np.ndarray]] = field(default_factory=list)
    true: list[dict[str, np.ndarray]] = field(default_factory=list)
    true_fatigue: list[np.ndarray] = field(default_factory=list)
    cognitive: np.ndarray | None = None
    previous: list[np.ndarray] = field(default_factory=list)     # (B, P, 3) in force
    decision: list[np.ndarray] = field(default_factory=list)     # (B,) from epoch 1
    target: list[np.ndarray] = field(default_factory=list)       # (B, P, 3) from epoch 1
    movable: list[np.ndarray] = field(default_factory=list)      # (B, P) from epoch 1
    robot_ok: list[np.ndarray] = field(default_factory=list)


class Teacher:
    """Greedy initial allocation, event-triggered greedy reallocation; records as it goes."""

    def __init__(self, mission, log: TeacherLog, plan_targets: bool):
        self.greedy = GreedyPolicy(mission.component_settings.get("greedy")
                                   or GreedyPolicy.Settings(), mission)
        self.on_event = OnEvent(None, mission)
        self.log = log
        self.plan_targets = plan_targets
        self.last_target: Allocation | None = None

    def _record_state(self, ctx: DecisionContext) -> None:
        log = self.log
        log.raw.append(state_features(ctx.observed))
        log.recon.append(reconstructed_features(ctx))
        log.true.append(state_features(ctx.truth))
        log.true_fatigue.append(ctx.truth["humans"].col("fatigue").copy())
        log.robot_ok.append(masks_for(ctx.inherent, ctx.observed).robot.numpy())

    def ata_initial_allocation(self, ctx: DecisionContext) -> Allocation:
        self.log.inherent = inherent_features(ctx.inherent)
        self.log.cognitive = ctx.inherent["humans"].col("cognitive").copy()
        self._record_state(ctx)
        alloc = self.greedy.ata_initial_allocation(ctx)
        self.log.ita = alloc.stack()
        return alloc

    def ata_should_reallocate(self, ctx: DecisionContext) -> np.ndarray:
        self._record_state(ctx)
        self.log.previous.append(ctx.previous.stack())
        decide = self.on_event.ata_should_reallocate(ctx)
        self.log.decision.append(decide)
        self.log.movable.append(ctx.reallocatable.copy())
        if self.plan_targets:   # what greedy would do now, for every scenario
            self.last_target = self.greedy.ata_reallocate(ctx, np.ones_like(decide))
            self.log.target.append(self.last_target.stack())
        return decide

    def ata_reallocate(self, ctx: DecisionContext, active: np.ndarray) -> Allocation:
        if self.last_target is not None:
            return self.last_target
        return self.greedy.ata_reallocate(ctx, active)


def _teacher_component(teacher: Teacher) -> Any:
    """The teacher as one component for the three decision slots."""
    from ata import hookimpl

    class TeacherComponent:
        @hookimpl
        def ata_initial_allocation(self, ctx):
            return teacher.ata_initial_allocation(ctx)

        @hookimpl
        def ata_should_reallocate(self, ctx):
            return teacher.ata_should_reallocate(ctx)

        @hookimpl
        def ata_reallocate(self, ctx, active):
            return teacher.ata_reallocate(ctx, active)

    return TeacherComponent()


# -- the trainer --------------------------------------------------------------------------------

class Trainer:
    """Trains the learned parts a mission uses; resumable from its run folder."""

    def __init__(self, session, run_dir: str | Path, *, resume: bool = False,
                 on_row: Callable[[dict], None] | None = None):
        self.session = session
        self.mission = session.mission
        self.run_dir = Path(run_dir)
        self.method = Method.of(self.mission)
        if not (self.method.policy_gradient or self.method.dqn):
            raise MissionError("[components]", "initial", "nothing to train: use initial = "
                               "'attention', condition/reallocation = 'ctr', or reallocation "
                               "= 'tr_pomdp'", file=self.mission.source)
        self.t = self.mission.train
        torch.set_num_threads(self.t.threads)
        self.cfg = net_config(self.mission)
        self.on_row = on_row
        self.counters = {"aux": 0, "imitation": 0, "rl": 0, "dqn": 0, "episodes": 0}
        self.best_eval = -math.inf
        self.wall = 0.0
        torch.manual_seed(self.t.seed)
        self.net = ATAHRLNet(self.cfg)
        self.opt = torch.optim.Adam(self.net.parameters(), lr=self.t.lr)
        self.aux_opt = torch.optim.Adam(list(self.net.fatigue.parameters())
                                        + list(self.net.latency.parameters()), lr=self.t.aux_lr)
        self.gen = torch.Generator().manual_seed(self.t.seed + 1)
        self.agents = None
        if self.method.dqn:
            from ata.learn.dqn_train import AgentLearner
            self.agents = AgentLearner(self.t)
        self.run_dir.mkdir(parents=True, exist_ok=True)
        if resume:
            self._load(self.run_dir / "checkpoint.pt")
        else:
            (self.run_dir / "mission.resolved.toml").write_text(self.mission.to_toml())
            with open(self.run_dir / "log.csv", "w", newline="") as f:
                csv.DictWriter(f, fieldnames=LOG_FIELDS).writeheader()

    # -- checkpoints ---------------------------------------------------------------------------
    def checkpoint(self, replay: bool = True) -> dict[str, Any]:
        data = {"model": self.net.state_dict(), "optimizer": self.opt.state_dict(),
                "aux_optimizer": self.aux_opt.state_dict(),
                "rng": {"torch": torch.get_rng_state(), "sampler": self.gen.get_state()},
                "counters": dict(self.counters), "best_eval": float(self.best_eval),
                "wall_s": float(self.wall), "config": self.cfg.as_dict(),
                "mission": self.mission.to_toml(), "format": 1}
        if self.agents is not None:
            data.update(self.agents.state(replay=replay))
        return data

    def save(self, name: str = "checkpoint.pt") -> Path:
        """Write atomically: a temporary file in the same folder, then a rename. ``best.pt``
        leaves out the replay buffer (it is for evaluation; resume from checkpoint.pt)."""
        path = self.run_dir / name
        tmp = path.with_suffix(".tmp")
        torch.save(self.checkpoint(replay=name == "checkpoint.pt"), tmp)
        os.replace(tmp, path)
        return path

    def _load(self, path: Path) -> None:
        data = read_checkpoint(path)
        net = net_from_checkpoint(data, path, expect=self.cfg)
        self.net.load_state_dict(net.state_dict())
        try:
            self.opt.load_state_dict(data["optimizer"])
            self.aux_opt.load_state_dict(data["aux_optimizer"])
            torch.set_rng_state(data["rng"]["torch"])
            self.gen.set_state(data["rng"]["sampler"])
            self.counters.update({k: int(v) for k, v in data["counters"].items()})
            if self.agents is not None:
                self.agents.load(data)
        except (KeyError, ValueError, RuntimeError, TypeError) as exc:
            from ata.learn.runtime import CheckpointError
            raise CheckpointError(path, f"cannot resume from it ({exc})") from None
        self.best_eval = float(data.get("best_eval", -math.inf))
        self.wall = float(data.get("wall_s", 0.0))

    def _log(self, row: dict[str, Any]) -> None:
        row = {k: row.get(k, "") for k in LOG_FIELDS}
        with open(self.run_dir / "log.csv", "a", newline="") as f:
            csv.DictWriter(f, fieldnames=LOG_FIELDS).writerow(row)
        if self.on_row is not None:
            self.on_row(row)

    # -- rollouts ------------------------------------------------------------------------------
    def _ids(self, phase: str, step: int) -> np.ndarray:
        """Training scenarios: a disjoint index range per phase and step of root seed t.seed."""
        base = {"aux": 0, "imitation": 10_000_000, "rl": 20_000_000, "dqn": 30_000_000}[phase]
        return base + step * self.t.batch_size + np.arange(self.t.batch_size)

    def _training_mission(self):
        return self.mission.replace(seed=self.t.seed)

    def teacher_rollout(self, ids: np.ndarray, plan_targets: bool) -> TeacherLog:
        mission = self._training_mission()
        log = TeacherLog()
        teacher = _teacher_component(Teacher(mission, log, plan_targets))
        overrides = {"initial": teacher, "condition": teacher, "reallocation": teacher}
        if self.method.aux:
            overrides["reconstructors"] = AuxReconstructor(None, mission, net=self.net)
        with torch.no_grad():
            Simulation(mission, self.session.registry, ids, overrides=overrides).run()
        return log

    def student_rollout(self, ids: np.ndarray, mission=None, sample: bool = True):
        """Run the students; returns (record, recorder). Training rollouts (sample=True) record
        log-probabilities; evaluation rollouts sample from each scenario's own stream, as the
        shipped missions do (``sample = true``)."""
        mission = mission or self._training_mission()
        recorder = Recorder() if sample else None
        overrides = {}
        if self.method.ita:
            overrides["initial"] = AttentionITA(AttentionITA.Settings(sample=True), mission,
                                                net=self.net, recorder=recorder,
                                                generator=self.gen)
        if self.method.ctr_condition or self.method.ctr_realloc:
            ctr = CTRPolicy(CTRPolicy.Settings(sample=True), mission, net=self.net,
                            recorder=recorder, generator=self.gen)
            if self.method.ctr_condition:
                overrides["condition"] = ctr
            if self.method.ctr_realloc:
                overrides["reallocation"] = ctr
        if self.method.aux:
            overrides["reconstructors"] = AuxReconstructor(None, mission, net=self.net)
        if self.method.dqn and self.method.ita:      # AtRL-TR: the ITA is trained alone, with no reallocation
            from ata.plugins.conditions import Never
            overrides["condition"] = Never(None, mission)
            overrides["reallocation"] = overrides["initial"]
        sim = Simulation(mission, self.session.registry, ids, overrides=overrides)
        record = sim.run()
        return record, recorder

    def evaluate(self) -> float:
        """Mean total team performance on held-out scenarios (sampled decisions, each scenario
        from its own random stream)."""
        mission = self.mission.replace(seed=self.t.seed + EVAL_SEED_OFFSET)
        with torch.no_grad():
            record, _ = self.student_rollout(np.arange(self.t.eval_scenarios), mission,
                                             sample=False)
        return float(record.total.mean())

    # -- phase 1: auxiliary reconstruction -----------------------------------------------------
    def aux_data(self, first: int, batches: int) -> dict[str, torch.Tensor]:
        fat_in, fat_target, seq_in, seq_target = [], [], {"robots": [], "tasks": []}, \
            {"robots": [], "tasks": []}
        for i in range(batches):
            log = self.teacher_rollout(self._ids("aux", first + i), plan_targets=False)
            T = len(log.raw)
            hours = np.stack([r["humans"][..., 0] * 3.0 for r in log.raw], 1)   # (B, T, H)
            f_obs = np.stack([r["humans"][..., 1] for r in log.raw], 1)
            cog = np.broadcast_to(log.cognitive[:, None, :], hours.shape)
            fat_in.append(np.stack([f_obs, hours, cog], -1).reshape(-1, 3))
            fat_target.append(np.stack(log.true_fatigue, 1).reshape(-1))
            for g in ("robots", "tasks"):
                raw = np.stack([r[g] for r in log.raw], 2)          # (B, N, T, F)
                true = np.stack([r[g] for r in log.true], 2)
                B, N = raw.shape[:2]
                seq_in[g].append(raw.reshape(B * N, T, -1))
                seq_target[g].append(true.reshape(B * N, T, -1))
        out = {"fatigue_in": np.concatenate(fat_in), "fatigue_target": np.concatenate(fat_target)}
        for g in ("robots", "tasks"):
            out[f"{g}_in"] = np.concatenate(seq_in[g])
            out[f"{g}_target"] = np.concatenate(seq_target[g])
        return {k: torch.as_tensor(v, dtype=torch.float32) for k, v in out.items()}

    def aux_losses(self, data: dict[str, torch.Tensor], idx: dict[str, torch.Tensor] | None = None,
                   sample: bool = True) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """(cVAE loss, fatigue MSE, latency MSE) on the data (or the rows in idx)."""
        fi, ft = data["fatigue_in"], data["fatigue_target"]
        if idx is not None:
            fi, ft = fi[idx["fatigue"]], ft[idx["fatigue"]]
        recon, mu, logvar = self.net.fatigue(fi[:, 0], fi[:, 1], fi[:, 2], sample=sample)
        cvae = nets.FatigueCVAE.loss(recon, ft, mu, logvar)
        f_mse = ((recon - ft) ** 2).mean()
        lat = 0.0
        for g in ("robots", "tasks"):
            x, y = data[f"{g}_in"], data[f"{g}_target"]
            if idx is not None:
                x, y = x[idx[g]], y[idx[g]]
            est, _ = self.net.latency[g](x)
            lat = lat + ((est - y) ** 2).mean()
        return cvae, f_mse, lat

    def train_aux(self) -> dict[str, float]:
        if not self.method.aux or self.counters["aux"] >= self.t.aux_steps:
            return {}
        data = self.aux_data(0, max(self.t.aux_batches, 1))
        opt = self.aux_opt
        n = {"fatigue": data["fatigue_in"].shape[0], "robots": data["robots_in"].shape[0],
             "tasks": data["tasks_in"].shape[0]}
        while self.counters["aux"] < self.t.aux_steps:
            t0 = time.perf_counter()
            idx = {k: torch.randint(0, v, (min(v, 1024),), generator=self.gen)
                   for k, v in n.items()}
            cvae, f_mse, lat = self.aux_losses(data, idx)
            loss = cvae + lat
            opt.zero_grad()
            loss.backward()
            opt.step()
            self.counters["aux"] += 1
            self.wall += time.perf_counter() - t0
            self._log({"phase": "aux", "step": self.counters["aux"], "loss": f"{loss.item():.5f}",
                       "aux_fatigue_mse": f"{f_mse.item():.5f}",
                       "aux_latency_mse": f"{lat.item():.5f}", "wall_s": f"{self.wall:.1f}"})
            if self.counters["aux"] % self.t.checkpoint_every == 0:
                self.save()
        self.save()
        return self.aux_report()

    def aux_report(self) -> dict[str, float]:
        """Held-out reconstruction error against the raw observation's (for the docs/tests)."""
        data = self.aux_data(10_000, 1)
        with torch.no_grad():
            _, f_mse, _ = self.aux_losses(data, sample=False)
            raw_f = ((data["fatigue_in"][:, 0] - data["fatigue_target"]) ** 2).mean()
            out = {"fatigue_mse": f_mse.item(), "fatigue_mse_raw": raw_f.item()}
            for g in ("robots", "tasks"):
                est, _ = self.net.latency[g](data[f"{g}_in"])
                out[f"{g}_mse"] = ((est - data[f"{g}_target"]) ** 2).mean().item()
                out[f"{g}_mse_raw"] = ((data[f"{g}_in"] - data[f"{g}_target"]) ** 2).mean().item()
        return out

    # -- phase 2: imitation warm start -------------------------------------------------------------
    def imitation_loss(self, log: TeacherLog) -> torch.Tensor:
        loss = torch.zeros(())
        I = to_tensors(log.inherent)
        B = log.ita.shape[0]
        skill_high = torch.as_tensor(log.inherent["humans"][..., 4] > 0.5)
        if self.method.ita:
            masks = nets_masks(log.robot_ok[0], skill_high)
            logits = self.net.ita_logits(I, masks)
            target = torch.as_tensor(log.ita)
            ok = nets.legal(logits, target).float()
            loss = loss - (nets.log_prob(logits, target) * ok).sum() / ok.sum().clamp(min=1)
        if self.method.ctr_condition or self.method.ctr_realloc:
            hidden = self.net.initial_hidden(B)
            for k in range(len(log.previous)):
                masks = nets_masks(log.robot_ok[k + 1], skill_high)
                cond, logits, hidden = self.net.ctr_step(
                    I, to_tensors(log.raw[k + 1]), to_tensors(log.recon[k + 1]),
                    torch.as_tensor(log.previous[k]), hidden, masks)
                if self.method.ctr_condition:
                    target = torch.as_tensor(log.decision[k], dtype=torch.float32)
                    loss = loss + torch.nn.functional.binary_cross_entropy_with_logits(
                        cond, target) / len(log.previous)
                if self.method.ctr_realloc and log.target:
                    target = torch.as_tensor(log.target[k])
                    movable = torch.as_tensor(log.movable[k]) & nets.legal(logits, target)
                    movable = movable.float()
                    lp = nets.log_prob(logits, target)
                    loss = loss - (lp * movable).sum() / movable.sum().clamp(min=1) \
                        / len(log.previous)
        return loss

    def train_imitation(self) -> None:
        while self.counters["imitation"] < self.t.imitation_steps:
            t0 = time.perf_counter()
            step = self.counters["imitation"]
            log = self.teacher_rollout(self._ids("imitation", step),
                                       plan_targets=self.method.ctr_realloc)
            loss = self.imitation_loss(log)
            self._optimise(loss)
            self.counters["imitation"] += 1
            self.counters["episodes"] += self.t.batch_size
            dt = time.perf_counter() - t0
            self.wall += dt
            self._log({"phase": "imitation", "step": step + 1,
                       "episodes": self.counters["episodes"],
                       "samples_per_s": f"{self.t.batch_size / dt:.1f}",
                       "loss": f"{loss.item():.4f}", "wall_s": f"{self.wall:.1f}"})
            if self.counters["imitation"] % self.t.checkpoint_every == 0:
                self.save()
        self.save()

    # -- phase 3: REINFORCE ------------------------------------------------------------------------
    def train_rl(self) -> None:
        for group in self.opt.param_groups:   # fine-tuning a warm-started policy: smaller steps
            group["lr"] = self.t.rl_lr
        while self.counters["rl"] < self.t.rl_steps:
            t0 = time.perf_counter()
            step = self.counters["rl"]
            record, rec = self.student_rollout(self._ids("rl", step))
            R = hierarchical_rewards(record)
            loss = torch.zeros(())
            ent = torch.zeros(())

            def advantage(x: np.ndarray) -> torch.Tensor:
                a = (x - x.mean()) / (x.std() + 1e-6)
                return torch.as_tensor(a, dtype=torch.float32)

            if rec.ita_logp is not None:
                loss = loss - (advantage(R["R_ITA"]) * rec.ita_logp).mean()
                ent = ent + rec.ita_entropy.mean()
            if rec.cond_logp:
                loss = loss - (advantage(R["R_C"]) * torch.stack(rec.cond_logp, 1).sum(1)).mean()
                ent = ent + torch.stack(rec.cond_entropy, 1).mean()
            if rec.tr_logp:
                loss = loss - (advantage(R["R_TR"]) * torch.stack(rec.tr_logp, 1).sum(1)).mean()
                ent = ent + torch.stack(rec.tr_entropy, 1).mean()
            loss = loss - self.t.entropy * ent
            self._optimise(loss)
            self.counters["rl"] += 1
            self.counters["episodes"] += self.t.batch_size
            dt = time.perf_counter() - t0
            self.wall += dt
            row = {"phase": "rl", "step": step + 1, "episodes": self.counters["episodes"],
                   "samples_per_s": f"{self.t.batch_size / dt:.1f}", "loss": f"{loss.item():.4f}",
                   "mean_score": f"{R['total'].mean():.2f}", "R_ITA": f"{R['R_ITA'].mean():.2f}",
                   "R_C": f"{R['R_C'].mean():.2f}", "R_TR": f"{R['R_TR'].mean():.2f}"}
            if self.counters["rl"] % self.t.eval_every == 0 or \
                    self.counters["rl"] == self.t.rl_steps:
                score = self.evaluate()
                row["eval_score"] = f"{score:.2f}"
                if score > self.best_eval:
                    self.best_eval = score
                    self.save("best.pt")
            row["wall_s"] = f"{self.wall:.1f}"
            self._log(row)
            if self.counters["rl"] % self.t.checkpoint_every == 0:
                self.save()
        self.save()

    def _optimise(self, loss: torch.Tensor) -> None:
        self.opt.zero_grad()
        loss.backward()
        if self.t.grad_clip > 0:
            torch.nn.utils.clip_grad_norm_(self.net.parameters(), self.t.grad_clip)
        self.opt.step()

    def run(self) -> dict[str, Any]:
        """All phases, resuming wherever the counters stand."""
        report = self.train_aux()
        if self.method.policy_gradient:
            self.train_policy()
        if self.method.dqn:
            from ata.learn.dqn_train import train_agents
            train_agents(self)
        if not (self.run_dir / "best.pt").exists():
            self.save("best.pt")
        return {"aux": report, "best_eval": self.best_eval, "wall_s": self.wall,
                "counters": dict(self.counters)}

    def train_policy(self) -> None:
        """Imitation warm start, then REINFORCE; best.pt follows the held-out evaluation."""
        if self.t.imitation_steps:
            self.train_imitation()
        if self.counters["rl"] == 0 and self.t.rl_steps and not (self.run_dir / "best.pt").exists():
            # the warm-started policy is the first candidate for best.pt
            score = self.evaluate()
            self._log({"phase": "rl", "step": 0, "eval_score": f"{score:.2f}",
                       "wall_s": f"{self.wall:.1f}"})
            self.best_eval = score
            self.save("best.pt")
        self.train_rl()


def nets_masks(robot_ok: np.ndarray, skill_high: torch.Tensor):
    from ata.learn.features import Masks
    return Masks(robot=torch.as_tensor(robot_ok), human=torch.ones_like(skill_high),
                 navigator=skill_high)


def method_overrides(plugins: list[str]) -> list[str]:
    """`--set` lines that make the slots follow the learned parts named: without ``ctr`` the
    ITA policy never reallocates; without ``aux`` the identity reconstructor feeds the raw S;
    ``trp`` reallocates with the TR-POMDP agents every epoch, after a random initial
    allocation, or after the attention ITA when ``ita`` is named too (AtRL-TR)."""
    out = []
    if "trp" in plugins:
        if "ctr" in plugins:
            raise MissionError("--plugins", "trp", "trp and ctr are two reallocation methods; "
                               "name one")
        out += ["components.condition='always'", "components.reallocation='tr_pomdp'",
                "components.initial='attention'" if "ita" in plugins
                else "components.initial='random'"]
    elif "ctr" not in plugins:
        out += ["components.condition='never'", "components.reallocation='attention'"]
    if "aux" not in plugins:
        out += ["components.reconstructors=['identity']"]
    return out


def total_steps(mission) -> int:
    t, m = mission.train, Method.of(mission)
    return ((t.aux_steps if m.aux else 0)
            + (t.imitation_steps + t.rl_steps if m.policy_gradient else 0)
            + (t.dqn_steps if m.dqn else 0))
