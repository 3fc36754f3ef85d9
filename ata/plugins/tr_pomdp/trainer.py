"""The trainer ``tr_pomdp``: the TR-POMDP agents, by independent double DQN with experience
replay and target networks, one Q-network per member kind, on a team reward with load management.

One phase, ``dqn``, run by the phase loop of ``ata.training``. Each step rolls out
``batch_size`` training episodes with epsilon-greedy agents (reallocating every epoch after the
mission's initial allocation: ``random`` for TR-POMDP, the attention ITA of ATA-HRL, trained
alone and frozen, for AtRL-TR), stores every agent's transitions in its kind's replay buffer,
and makes ``updates`` gradient steps. The reward of agent i for its action at epoch t is

    r_i = (own_i(t) + team_weight * r_perf(t)) / reward_scale
          - load_overload * overload_i(t+1) - load_use * [a_i != keep]

own_i(t) is the points earned in epoch t by the POIs agent i holds (as robot, navigator or
classifier) in the allocation in force; r_perf(t) the team's points of the epoch, shared by
every agent: with the team reward alone, each agent's credit is lost among the others' and the
agents do not learn. The load management term is that of Wu et al.: overload (a human busier
than ``human_load_cap``; a robot holding more than 1.5 fair shares of the open POIs) and
needless use (any change costs a little).
"""

from __future__ import annotations

import copy
from typing import Any

import numpy as np
import torch

from ata.core.errors import MissionError
from ata.core.kernel import Simulation, build_component
from ata.model.agents import AgentConfig, load_terms
import ata.plugins.tr_pomdp.agents as dqn
from ata.plugins.tr_pomdp.policy import KIND, TRPOMDPPolicy, Transition, agents_from_checkpoint
from ata.plugins.tr_pomdp.settings import Settings
from ata.training import (VALIDATION_SEED_OFFSET, CheckpointError, Phase, PhaseLoop, TrainRun,
                          read_checkpoint)

LOG_FIELDS = ["phase", "step", "episodes", "episodes_per_s", "loss", "mean_score", "epsilon",
              "eval_score", "eval_expected", "eval_avg_score", "eval_avg_expected", "wall_s"]
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

    def __init__(self, t: Settings):
        self.t = t
        self.cfg = AgentConfig(k=t.k, hidden=t.hidden)
        self.nets = dqn.AgentNets(self.cfg)
        self.target = copy.deepcopy(self.nets)
        self.opt = torch.optim.Adam(self.nets.parameters(), lr=t.lr)
        self.avg = copy.deepcopy(self.nets) if t.average > 0 else None   # averaged weights
        self.replay = {"robot": Replay(t.buffer, self.cfg.robot_dim, self.cfg.robot_actions),
                       "human": Replay(t.buffer, self.cfg.human_dim, self.cfg.human_actions)}
        self.updates = 0

    def state(self, replay: bool = True) -> dict[str, Any]:
        out = {"agents": self.nets.state_dict(), "agents_config": self.cfg.as_dict(),
               "agents_target": self.target.state_dict(),
               "agents_optimizer": self.opt.state_dict(), "agents_updates": self.updates}
        if replay:
            out["replay"] = {k: r.state() for k, r in self.replay.items()}
        if self.avg is not None:
            out["agents_avg"] = self.avg.state_dict()
        return out

    def load(self, data: dict[str, Any], path: Any) -> None:
        nets = agents_from_checkpoint(data, path)
        self.nets.load_state_dict(nets.state_dict())
        self.target.load_state_dict(data["agents_target"])
        self.opt.load_state_dict(data["agents_optimizer"])
        self.updates = int(data["agents_updates"])
        if self.avg is not None:     # best.pt keeps no average: it starts from its agents
            self.avg.load_state_dict(data.get("agents_avg", self.nets.state_dict()))
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
            over_r, over_h = load_terms(nxt.inputs, t.human_load_cap)
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
        if self.avg is not None:
            with torch.no_grad():
                for a, p in zip(self.avg.parameters(), self.nets.parameters()):
                    a.lerp_(p, 1.0 - t.average)
        return float(loss.item())


class TRPOMDPTrainer:
    """Trains the TR-POMDP agents of the mission's reallocation slot (see the module's doc)."""

    log_fields = LOG_FIELDS
    Settings = Settings        # the [tr_pomdp] table, shared with the policy
    presets = {"smoke": {"batch_size": 4, "steps": 12, "updates": 4, "minibatch": 64,
                         "eps_decay_steps": 8, "eval_every": 6, "eval_scenarios": 8,
                         "checkpoint_every": 4}}
    """``ata train --preset smoke``: the DQN phase in well under a minute of 2 cores."""

    def __init__(self, settings: Settings, mission: Any, registry: Any):
        self.t = settings
        self.mission = mission
        self.registry = registry
        info = registry.get("policy", mission.slots.reallocation, "[components]")
        if not (isinstance(info.factory, type) and issubclass(info.factory, TRPOMDPPolicy)):
            raise MissionError("[components]", "reallocation", "trainer 'tr_pomdp' trains the "
                               "TR-POMDP agents: set reallocation = 'tr_pomdp'",
                               file=mission.source)
        torch.manual_seed(settings.seed)
        self.agents = AgentLearner(settings)
        self.gen = torch.Generator().manual_seed(settings.seed + 1)
        self.train_mission = mission.replace(seed=settings.seed)
        self.loop = PhaseLoop(["dqn"], self.checkpoint)
        self.best_source = "online"      # the agents the last validation scored higher

    # -- the trainer interface ------------------------------------------------------------------
    @property
    def counters(self) -> dict[str, int]:
        return self.loop.counters

    def scenario_ranges(self) -> list[tuple[int, int, int]]:
        t = self.t
        return [(t.seed, 0, max(1, t.steps) * t.batch_size),
                (t.seed + VALIDATION_SEED_OFFSET, 0, t.eval_scenarios)]

    def trained_components(self) -> list[str]:
        """The component whose agents best.pt holds (the reallocation slot's)."""
        return [self.mission.slots.reallocation]

    def total_steps(self) -> int:
        return self.t.steps

    def done_steps(self) -> int:
        return self.loop.done_steps()

    def run(self, run: TrainRun, resume: bool = False) -> dict[str, Any]:
        """The DQN steps, resumable from the counters."""
        self.loop.run = run
        torch.set_num_threads(self.t.threads)
        if resume and run.resumes:
            self.load(run.checkpoint_path, run.resume_checkpoint(KIND))
        t = self.t
        self.loop.run_phase(Phase("dqn", t.steps, self.step, checkpoint_every=t.checkpoint_every,
                                  eval_every=t.eval_every, validate=self.validate))
        return self.loop.finish()

    # -- checkpoints ------------------------------------------------------------------------------
    def checkpoint(self, name: str = "checkpoint.pt") -> dict[str, Any]:
        """Everything to resume from; ``best.pt`` leaves out the replay buffers (it is for
        evaluation)."""
        data = {"kind": KIND, "format": 2, "rng": {"torch": torch.get_rng_state(),
                                                   "sampler": self.gen.get_state()},
                **self.loop.state(), "mission": self.mission.to_toml(),
                "trainer": getattr(self, "component_name", "tr_pomdp"),
                "scenario_ranges": [list(r) for r in self.scenario_ranges()]}
        data.update(self.agents.state(replay=name == "checkpoint.pt"))
        if name == "best.pt" and self.best_source == "average":
            data["agents"] = self.agents.avg.state_dict()
        if name == "best.pt":
            data.pop("agents_avg", None)
            data["agents_source"] = self.best_source
        return data

    def load(self, path, data: dict[str, Any] | None = None) -> None:
        """Resume from the checkpoint at `path` (its contents `data`, if already read)."""
        data = data if data is not None else read_checkpoint(path, KIND)
        try:
            self.agents.load(data, path)
            torch.set_rng_state(data["rng"]["torch"])
            self.gen.set_state(data["rng"]["sampler"])
            self.loop.load_state(data)
        except (KeyError, ValueError, RuntimeError, TypeError) as exc:
            raise CheckpointError(path, f"cannot resume from it ({exc})") from None

    # -- the phase ---------------------------------------------------------------------------------
    def rollout(self, ids: np.ndarray, mission, epsilon: float,
                log: list[Transition] | None = None, nets: Any = None):
        """Episodes with the agents (the online ones unless `nets`) reallocating every epoch
        after the mission's (frozen) initial allocation."""
        nets = self.agents.nets if nets is None else nets
        policy = TRPOMDPPolicy(TRPOMDPPolicy.Settings(), mission, nets=nets,
                               log=log, epsilon=epsilon)
        overrides = {"condition": build_component(self.registry, mission, "condition",
                                                  "always"),
                     "reallocation": policy}
        with torch.no_grad():
            return Simulation(mission, self.registry, ids, overrides=overrides).run()

    def step(self, step: int) -> tuple[dict[str, str], int]:
        """Step `step`: a batch of epsilon-greedy episodes into the replay, then `updates`
        gradient steps."""
        t, learner = self.t, self.agents
        eps = learner.epsilon(step)
        log: list[Transition] = []
        ids = step * t.batch_size + np.arange(t.batch_size)
        record = self.rollout(ids, self.train_mission, eps, log)
        learner.store(log, record)
        losses = [learner.update(self.gen) for _ in range(t.updates)]
        return {"loss": f"{np.mean(losses):.4f}", "mean_score": f"{record.total.mean():.2f}",
                "epsilon": f"{eps:.3f}"}, t.batch_size

    def validate(self) -> tuple[float, dict[str, str]]:
        """Mean team performance on held-out validation scenarios, greedy agents: the points
        drawn and in expectation; best.pt follows the one `select` names. With weight
        averaging the averaged agents play the same scenarios, and the higher of the two
        scores is the check's (best.pt then holds those agents)."""
        mission = self.mission.replace(seed=self.t.seed + VALIDATION_SEED_OFFSET)
        ids = np.arange(self.t.eval_scenarios)
        candidates = [("online", None, "eval")]
        if self.agents.avg is not None:
            candidates.append(("average", self.agents.avg, "eval_avg"))
        best, columns = -np.inf, {}
        for source, nets, prefix in candidates:
            record = self.rollout(ids, mission, 0.0, nets=nets)
            drawn = float(record.total.mean())
            expected = float(record.r_expected.sum(1).mean())
            columns.update({f"{prefix}_score": f"{drawn:.2f}",
                            f"{prefix}_expected": f"{expected:.2f}"})
            score = expected if self.t.select == "expected" else drawn
            if score > best:
                best, self.best_source = score, source
        return best, columns
