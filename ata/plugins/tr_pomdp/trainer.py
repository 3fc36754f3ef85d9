"""The trainer ``dqn``: the TR-POMDP agents, by independent double DQN with experience replay
and target networks, one Q-network per member kind, on a team reward with load management.

Each step rolls out ``batch_size`` training episodes with epsilon-greedy agents (reallocating
every epoch after the mission's initial allocation: ``random`` for TR-POMDP, the attention ITA of
ATA-HRL, trained alone and frozen, for AtRL-TR), stores every agent's transitions in its kind's
replay buffer, and makes ``updates`` gradient steps. The reward of agent i for its action at
epoch t is

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
import math
import time
from dataclasses import dataclass
from typing import Any

import numpy as np
import torch

from ata.core.kernel import Simulation, build_component
from ata.core.settings import param
from ata.plugins.tr_pomdp import agents as dqn
from ata.plugins.tr_pomdp.policy import KIND, TRPOMDPPolicy, Transition, agents_from_checkpoint
from ata.training import VALIDATION_SEED_OFFSET, CheckpointError, TrainRun, read_checkpoint

LOG_FIELDS = ["phase", "step", "episodes", "episodes_per_s", "loss", "mean_score", "epsilon",
              "eval_score", "wall_s"]
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

    def __init__(self, t: "DQNTrainer.Settings"):
        self.t = t
        self.cfg = dqn.AgentConfig(k=t.k, hidden=t.hidden)
        self.nets = dqn.AgentNets(self.cfg)
        self.target = copy.deepcopy(self.nets)
        self.opt = torch.optim.Adam(self.nets.parameters(), lr=t.lr)
        self.replay = {"robot": Replay(t.buffer, self.cfg.robot_dim, self.cfg.robot_actions),
                       "human": Replay(t.buffer, self.cfg.human_dim, self.cfg.human_actions)}
        self.updates = 0

    def state(self, replay: bool = True) -> dict[str, Any]:
        out = {"agents": self.nets.state_dict(), "agents_config": self.cfg.as_dict(),
               "agents_target": self.target.state_dict(),
               "agents_optimizer": self.opt.state_dict(), "agents_updates": self.updates}
        if replay:
            out["replay"] = {k: r.state() for k, r in self.replay.items()}
        return out

    def load(self, data: dict[str, Any], path: Any) -> None:
        nets = agents_from_checkpoint(data, path)
        self.nets.load_state_dict(nets.state_dict())
        self.target.load_state_dict(data["agents_target"])
        self.opt.load_state_dict(data["agents_optimizer"])
        self.updates = int(data["agents_updates"])
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
            b = buf.sample(t.minibatch, gen)
            q = self.nets.q(kind, b["obs"]).gather(1, b["action"][:, None])[:, 0]
            with torch.no_grad():
                a_next = dqn.masked_argmax(self.nets.q(kind, b["next_obs"]), b["next_legal"])
                q_next = self.target.q(kind, b["next_obs"]).gather(1, a_next[:, None])[:, 0]
                y = b["reward"] + t.gamma * (1.0 - b["done"]) * q_next
            loss = loss + torch.nn.functional.smooth_l1_loss(q, y)
        self.opt.zero_grad()
        loss.backward()
        torch.nn.utils.clip_grad_norm_(self.nets.parameters(), 10.0)
        self.opt.step()
        self.updates += 1
        if self.updates % t.target_sync == 0:
            self.target.load_state_dict(self.nets.state_dict())
        return float(loss.item())


class DQNTrainer:
    """Trains the TR-POMDP agents of the mission's reallocation slot (see the module's doc)."""

    log_fields = LOG_FIELDS

    @dataclass
    class Settings:
        seed: int = param(12345, min=0, max=2**40, help="root seed of the training scenarios "
                          f"(validation uses seed + {VALIDATION_SEED_OFFSET})")
        batch_size: int = param(16, min=1, max=4096, help="episodes per step")
        steps: int = param(500, min=0, help="steps: each rolls out batch_size episodes with "
                           "epsilon-greedy agents, then makes `updates` gradient steps")
        updates: int = param(32, min=1, help="gradient steps per step")
        lr: float = param(1e-3, min=0.0, max=1.0, help="Adam learning rate of the agents")
        gamma: float = param(0.9, min=0.0, max=1.0, help="discount per decision epoch")
        buffer: int = param(30000, min=64, help="replay buffer capacity, transitions per "
                            "member kind")
        minibatch: int = param(256, min=1, help="transitions per gradient step")
        target_sync: int = param(50, min=1, help="gradient steps between copies of the online "
                                 "networks into the target networks")
        eps_start: float = param(1.0, min=0.0, max=1.0, help="epsilon of the first step")
        eps_end: float = param(0.05, min=0.0, max=1.0, help="epsilon after the decay")
        eps_decay_steps: int = param(300, min=1, help="steps of linear epsilon decay")
        k: int = param(4, min=1, help="candidate POIs per agent (and roles a human may "
                       "release)")
        hidden: int = param(64, min=4, help="width of the agents' Q-networks")
        reward_scale: float = param(20.0, min=1e-6, help="points per unit of agent reward")
        team_weight: float = param(0.5, min=0.0, help="weight of the team's points of the "
                                   "epoch in each agent's reward, beside its own POIs'")
        load_overload: float = param(0.1, min=0.0, help="load management: penalty per unit of "
                                     "overload (human utilisation above human_load_cap, robots "
                                     "holding more than 1.5 fair shares of the open POIs)")
        load_use: float = param(0.005, min=0.0, help="load management: penalty per non-idle "
                                "action (discourages needless changes)")
        human_load_cap: float = param(0.65, min=0.0, max=0.99, help="utilisation above which "
                                      "a human counts as overloaded")
        eval_every: int = param(50, min=1, help="held-out validation every N steps")
        eval_scenarios: int = param(64, min=1, help="validation scenarios")
        checkpoint_every: int = param(10, min=1, help="write checkpoint.pt every N steps")
        threads: int = param(1, min=1, max=256, help="torch CPU threads")

    def __init__(self, settings: "DQNTrainer.Settings", mission: Any, registry: Any):
        self.t = settings
        self.mission = mission
        self.registry = registry
        info = registry.get("policy", mission.slots.reallocation, "[components]")
        if not (isinstance(info.factory, type) and issubclass(info.factory, TRPOMDPPolicy)):
            from ata.core.errors import MissionError
            raise MissionError("[components]", "reallocation", "trainer 'dqn' trains the "
                               "TR-POMDP agents: set reallocation = 'tr_pomdp'",
                               file=mission.source)
        torch.manual_seed(settings.seed)
        self.agents = AgentLearner(settings)
        self.gen = torch.Generator().manual_seed(settings.seed + 1)
        self.counters = {"dqn": 0, "episodes": 0}
        self.best_eval = -math.inf
        self.wall = 0.0
        self.run_folder: TrainRun | None = None

    # -- the trainer interface ------------------------------------------------------------------
    def scenario_ranges(self) -> list[tuple[int, int, int]]:
        t = self.t
        return [(t.seed, 0, max(1, t.steps) * t.batch_size),
                (t.seed + VALIDATION_SEED_OFFSET, 0, t.eval_scenarios)]

    def total_steps(self) -> int:
        return self.t.steps

    def done_steps(self) -> int:
        return self.counters["dqn"]

    def checkpoint(self, replay: bool = True) -> dict[str, Any]:
        data = {"kind": KIND, "format": 2, "rng": {"torch": torch.get_rng_state(),
                                                   "sampler": self.gen.get_state()},
                "counters": dict(self.counters), "best_eval": float(self.best_eval),
                "wall_s": float(self.wall), "mission": self.mission.to_toml(), "trainer": "dqn",
                "scenario_ranges": [list(r) for r in self.scenario_ranges()]}
        data.update(self.agents.state(replay=replay))
        return data

    def save(self, name: str = "checkpoint.pt") -> None:
        """``best.pt`` leaves out the replay buffers (it is for evaluation)."""
        self.run_folder.save(self.checkpoint(replay=name == "checkpoint.pt"), name)

    def load(self, path, data: dict[str, Any] | None = None) -> None:
        """Resume from the checkpoint at `path` (its contents `data`, if already read)."""
        data = data if data is not None else read_checkpoint(path, KIND)
        try:
            self.agents.load(data, path)
            torch.set_rng_state(data["rng"]["torch"])
            self.gen.set_state(data["rng"]["sampler"])
            self.counters.update({k: int(v) for k, v in data["counters"].items()})
        except (KeyError, ValueError, RuntimeError, TypeError) as exc:
            raise CheckpointError(path, f"cannot resume from it ({exc})") from None
        self.best_eval = float(data.get("best_eval", -math.inf))
        self.wall = float(data.get("wall_s", 0.0))

    # -- rollouts ----------------------------------------------------------------------------------
    def rollout(self, ids: np.ndarray, mission, epsilon: float,
                log: list[Transition] | None = None):
        """Episodes with the agents reallocating every epoch after the mission's (frozen)
        initial allocation."""
        policy = TRPOMDPPolicy(TRPOMDPPolicy.Settings(), mission, nets=self.agents.nets,
                               log=log, epsilon=epsilon)
        overrides = {"condition": build_component(self.registry, mission, "condition",
                                                  "always"),
                     "reallocation": policy}
        with torch.no_grad():
            return Simulation(mission, self.registry, ids, overrides=overrides).run()

    def evaluate(self) -> float:
        """Mean total team performance on held-out validation scenarios, greedy agents."""
        mission = self.mission.replace(seed=self.t.seed + VALIDATION_SEED_OFFSET)
        record = self.rollout(np.arange(self.t.eval_scenarios), mission, 0.0)
        return float(record.total.mean())

    def run(self, run: TrainRun, resume: bool = False) -> dict[str, Any]:
        """The DQN steps, resumable from the counters."""
        self.run_folder = run
        t, learner = self.t, self.agents
        torch.set_num_threads(t.threads)
        if resume:
            self.load(run.checkpoint_path, run.resume_checkpoint(KIND))
        mission = self.mission.replace(seed=t.seed)
        while self.counters["dqn"] < t.steps:
            t0 = time.perf_counter()
            step = self.counters["dqn"]
            eps = learner.epsilon(step)
            log: list[Transition] = []
            ids = step * t.batch_size + np.arange(t.batch_size)
            record = self.rollout(ids, mission, eps, log)
            learner.store(log, record)
            losses = [learner.update(self.gen) for _ in range(t.updates)]
            self.counters["dqn"] += 1
            self.counters["episodes"] += t.batch_size
            dt = time.perf_counter() - t0
            self.wall += dt
            row = {"phase": "dqn", "step": step + 1, "episodes": self.counters["episodes"],
                   "episodes_per_s": f"{t.batch_size / dt:.1f}",
                   "loss": f"{np.mean(losses):.4f}", "mean_score": f"{record.total.mean():.2f}",
                   "epsilon": f"{eps:.3f}"}
            done = self.counters["dqn"]
            if done % t.eval_every == 0 or done == t.steps:
                score = self.evaluate()
                row["eval_score"] = f"{score:.2f}"
                if score > self.best_eval:
                    self.best_eval = score
                    self.save("best.pt")
            row["wall_s"] = f"{self.wall:.1f}"
            run.log(row)
            if done % t.checkpoint_every == 0:
                self.save()
        self.save()
        if not run.best_path.exists():
            self.save("best.pt")
        return {"best_eval": self.best_eval, "wall_s": self.wall, "counters": dict(self.counters),
                "best": str(run.best_path)}
