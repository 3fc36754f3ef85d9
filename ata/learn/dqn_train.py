"""Training the TR-POMDP agents: independent double DQN with experience replay and target
networks, one Q-network per member kind, on a team reward with load management.

Each iteration rolls out ``batch_size`` training episodes with epsilon-greedy agents
(reallocating every epoch after the mission's initial allocation: ``random`` for TR-POMDP, the
frozen attention ITA for AtRL-TR), stores every agent's transitions in its kind's replay buffer,
and makes ``dqn_updates`` gradient steps. The reward of agent i for its action at epoch t is

    r_i = (own_i(t) + team_weight * r_perf(t)) / reward_scale
          - load_overload * overload_i(t+1) - load_use * [a_i != keep]

own_i(t) is the points earned in epoch t by the POIs agent i holds (as robot, navigator or
classifier) in the allocation in force; r_perf(t) the team's points of the epoch, shared by
every agent. A shared team reward alone leaves each agent's credit lost among the others' (it
did not learn in our first runs; docs/training.md). The load management term is that of Wu et
al.: overload (a human busier than ``human_load_cap``; a robot holding more than 1.5 fair
shares of the open POIs) and needless use (any change costs a little).
"""

from __future__ import annotations

import copy
import time
from typing import Any

import numpy as np
import torch

from ata.core.kernel import Simulation
from ata.learn import dqn
from ata.plugins.conditions import Always
from ata.plugins.policies.attention import AttentionITA
from ata.plugins.tr_pomdp import TRPOMDPPolicy, Transition, agents_from_checkpoint

KINDS = ("robot", "human")


class Replay:
    """A ring buffer of one kind's transitions, as tensors (saved in checkpoints)."""

    def __init__(self, capacity: int, dim: int, actions: int):
        self.capacity = capacity
        self.data = {"obs": torch.zeros(capacity, dim), "action": torch.zeros(capacity,
                                                                               dtype=torch.long),
                     "reward": torch.zeros(capacity), "next_obs": torch.zeros(capacity, dim),
                     "next_legal": torch.zeros(capacity, actions, dtype=torch.bool),
                     "done": torch.zeros(capacity)}
        self.size = 0
        self.pos = 0

    def add(self, **batch: np.ndarray) -> None:
        n = len(batch["action"])
        if n > self.capacity:                      # keep the newest
            batch = {k: v[-self.capacity:] for k, v in batch.items()}
            n = self.capacity
        idx = (self.pos + np.arange(n)) % self.capacity
        for key, value in batch.items():
            self.data[key][idx] = torch.as_tensor(value, dtype=self.data[key].dtype)
        self.pos = int((self.pos + n) % self.capacity)
        self.size = int(min(self.capacity, self.size + n))

    def sample(self, n: int, gen: torch.Generator) -> dict[str, torch.Tensor]:
        idx = torch.randint(0, self.size, (n,), generator=gen)
        return {k: v[idx] for k, v in self.data.items()}

    def state(self) -> dict[str, Any]:
        return {"data": {k: v[:self.size].clone() for k, v in self.data.items()},
                "pos": self.pos, "size": self.size}

    def load(self, state: dict[str, Any]) -> None:
        self.size, self.pos = int(state["size"]), int(state["pos"])
        for k, v in state["data"].items():
            self.data[k][:self.size] = v


class AgentLearner:
    """The agents, their target copies, optimiser and replay buffers."""

    def __init__(self, t):
        self.t = t
        self.cfg = dqn.AgentConfig(k=t.dqn_k, hidden=t.dqn_hidden)
        self.nets = dqn.AgentNets(self.cfg)
        self.target = copy.deepcopy(self.nets)
        self.opt = torch.optim.Adam(self.nets.parameters(), lr=t.dqn_lr)
        self.replay = {"robot": Replay(t.dqn_buffer, self.cfg.robot_dim, self.cfg.robot_actions),
                       "human": Replay(t.dqn_buffer, self.cfg.human_dim, self.cfg.human_actions)}
        self.updates = 0
        self.best = -float("inf")

    def state(self, replay: bool = True) -> dict[str, Any]:
        out = {"agents": self.nets.state_dict(), "agents_config": self.cfg.as_dict(),
               "agents_target": self.target.state_dict(),
               "agents_optimizer": self.opt.state_dict(),
               "agents_updates": self.updates, "agents_best": float(self.best)}
        if replay:
            out["replay"] = {k: r.state() for k, r in self.replay.items()}
        return out

    def load(self, data: dict[str, Any]) -> None:
        if "agents" not in data:
            return                              # a checkpoint from before the DQN phase
        nets = agents_from_checkpoint(data, "checkpoint")
        self.nets.load_state_dict(nets.state_dict())
        self.target.load_state_dict(data["agents_target"])
        self.opt.load_state_dict(data["agents_optimizer"])
        self.updates = int(data["agents_updates"])
        self.best = float(data["agents_best"])
        for k, r in self.replay.items():
            if "replay" in data:
                r.load(data["replay"][k])

    def epsilon(self, step: int) -> float:
        t = self.t
        frac = min(1.0, step / max(1, t.eps_decay_steps))
        return t.eps_start + frac * (t.eps_end - t.eps_start)

    def store(self, log: list[Transition], record) -> None:
        """Turn one batch of episodes (decisions at epochs 1..T-1) into transitions."""
        t = self.t
        H, R = log[0].human_a.shape[1], log[0].robot_a.shape[1]
        for i, step in enumerate(log):
            epoch = i + 1
            last = i == len(log) - 1
            nxt = step if last else log[i + 1]
            over_r, over_h = dqn.load_terms(nxt.inputs, t.human_load_cap)
            gain = np.where(record.task_epoch == epoch, record.task_gain, 0.0)     # (B, P)
            alloc = record.allocations[:, epoch].astype(np.int64)                   # (B, P, 3)
            own_r = np.einsum("bp,bpr->br", gain, alloc[..., 0, None] == np.arange(R))
            held_h = (alloc[..., 1, None] == np.arange(H)) | (alloc[..., 2, None] == np.arange(H))
            own_h = np.einsum("bp,bph->bh", gain, held_h)
            team = t.team_weight * record.r_perf[:, epoch][:, None]
            for kind, a, over, own in (("robot", step.robot_a, over_r, own_r),
                                       ("human", step.human_a, over_h, own_h)):
                obs = getattr(step.inputs, f"{kind}_obs")
                reward = (own + team) / t.reward_scale - t.load_overload * over \
                    - t.load_use * (a != 0)
                legal = getattr(nxt.inputs, f"{kind}_legal")
                next_obs = getattr(nxt.inputs, f"{kind}_obs")
                flat = lambda x: x.reshape(-1, *x.shape[2:])  # noqa: E731
                self.replay[kind].add(obs=flat(obs), action=flat(a), reward=flat(reward),
                                      next_obs=flat(next_obs), next_legal=flat(legal),
                                      done=np.full(a.size, float(last)))

    def update(self, gen: torch.Generator) -> float:
        """One double-DQN gradient step on both kinds; returns the loss."""
        t = self.t
        loss = torch.zeros(())
        for kind in KINDS:
            buf = self.replay[kind]
            if buf.size == 0:
                continue
            b = buf.sample(t.dqn_minibatch, gen)
            q = self.nets.q(kind, b["obs"]).gather(1, b["action"][:, None])[:, 0]
            with torch.no_grad():
                a_next = dqn.masked_argmax(self.nets.q(kind, b["next_obs"]), b["next_legal"])
                q_next = self.target.q(kind, b["next_obs"]).gather(1, a_next[:, None])[:, 0]
                y = b["reward"] + t.dqn_gamma * (1.0 - b["done"]) * q_next
            loss = loss + torch.nn.functional.smooth_l1_loss(q, y)
        self.opt.zero_grad()
        loss.backward()
        torch.nn.utils.clip_grad_norm_(self.nets.parameters(), 10.0)
        self.opt.step()
        self.updates += 1
        if self.updates % t.dqn_target_sync == 0:
            self.target.load_state_dict(self.nets.state_dict())
        return float(loss.item())


def rollout(trainer, ids: np.ndarray, mission, epsilon: float,
            log: list[Transition] | None = None):
    """Episodes with the agents reallocating every epoch (and the frozen ITA for AtRL-TR)."""
    learner = trainer.agents
    policy = TRPOMDPPolicy(TRPOMDPPolicy.Settings(), mission, nets=learner.nets, log=log,
                           epsilon=epsilon)
    overrides = {"condition": Always(None, mission), "reallocation": policy}
    if trainer.method.ita:
        overrides["initial"] = AttentionITA(AttentionITA.Settings(sample=True), mission,
                                            net=trainer.net)
    with torch.no_grad():
        return Simulation(mission, trainer.session.registry, ids, overrides=overrides).run()


def evaluate_agents(trainer) -> float:
    """Mean total team performance on held-out scenarios, greedy agents."""
    from ata.learn.train import EVAL_SEED_OFFSET
    mission = trainer.mission.replace(seed=trainer.t.seed + EVAL_SEED_OFFSET)
    record = rollout(trainer, np.arange(trainer.t.eval_scenarios), mission, 0.0)
    return float(record.total.mean())


def train_agents(trainer) -> None:
    """The DQN phase of `ata train`, resumable from its counters."""
    t, learner = trainer.t, trainer.agents
    best = trainer.run_dir / "best.pt"
    if trainer.method.ita and trainer.counters["dqn"] == 0 and best.exists():
        # the agents learn after the best ITA of the policy phase, the one that ships
        from ata.learn.runtime import read_checkpoint
        trainer.net.load_state_dict(read_checkpoint(best)["model"])
    trainer.net.eval()
    mission = trainer._training_mission()
    while trainer.counters["dqn"] < t.dqn_steps:
        t0 = time.perf_counter()
        step = trainer.counters["dqn"]
        eps = learner.epsilon(step)
        log: list[Transition] = []
        record = rollout(trainer, trainer._ids("dqn", step), mission, eps, log)
        learner.store(log, record)
        losses = [learner.update(trainer.gen) for _ in range(t.dqn_updates)]
        trainer.counters["dqn"] += 1
        trainer.counters["episodes"] += t.batch_size
        dt = time.perf_counter() - t0
        trainer.wall += dt
        row = {"phase": "dqn", "step": step + 1, "episodes": trainer.counters["episodes"],
               "samples_per_s": f"{t.batch_size / dt:.1f}", "loss": f"{np.mean(losses):.4f}",
               "mean_score": f"{record.total.mean():.2f}", "epsilon": f"{eps:.3f}"}
        done = trainer.counters["dqn"]
        if done % t.eval_every == 0 or done == t.dqn_steps:
            score = evaluate_agents(trainer)
            row["eval_score"] = f"{score:.2f}"
            if score > learner.best:
                learner.best = score
                trainer.best_eval = score
                trainer.save("best.pt")
        row["wall_s"] = f"{trainer.wall:.1f}"
        trainer._log(row)
        if done % t.checkpoint_every == 0:
            trainer.save()
    trainer.save()
