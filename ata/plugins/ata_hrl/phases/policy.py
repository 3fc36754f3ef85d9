"""What the ITA and CTR phases share: a policy-gradient step with a shared per-scenario baseline.

Each step plays one team setting (and level) of the cycle: it samples ``samples`` decisions of
each of ``batch_size`` training scenarios on common random numbers (the same scenario, the same
random streams), runs them, and computes the paper's rewards from each classification's
expected points (the outcome draws do not change what happens next, so this removes their
noise and keeps the expectation). Each sample's advantage is its reward less the mean of its
scenario's samples; one Adam step follows, the policies' gradients clipped to ``grad_clip``.
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Any, Callable, Iterator

import numpy as np
import torch

from ata.core.settings import param
from ata.plugins.ata_hrl.components import Recorder
from ata.plugins.ata_hrl.rewards import hierarchical_rewards, rewards_to_go
from ata.plugins.ata_hrl.phases.host import Host
from ata.training import Phase


@dataclass
class Settings:
    """The keys of ``[ata_hrl]`` that the ITA and CTR phases share."""

    samples: int = param(8, min=2, max=256, help="ita, ctr: samples of each scenario per step "
                         "(the shared baseline is their mean)")
    grad_clip: float = param(1.0, min=0.0, help="ita, ctr: gradient norm clip (0: none)")


def shared_baseline_advantage(reward: np.ndarray, samples: int) -> np.ndarray:
    """Each sample's reward less the mean of its scenario's samples: rewards (B * K,) laid out
    scenario by scenario; the advantages of one scenario sum to zero."""
    r = np.asarray(reward, dtype=float).reshape(-1, samples)
    return (r - r.mean(1, keepdims=True)).reshape(-1)


def per_epoch_advantage(reward: np.ndarray, samples: int) -> np.ndarray:
    """(E, T) rewards from each epoch on, less the mean over the scenario's samples at that
    epoch: the shared baseline, epoch by epoch (zero-sum per scenario and epoch)."""
    E, T = reward.shape
    r = reward.reshape(E // samples, samples, T)
    return (r - r.mean(1, keepdims=True)).reshape(E, T)


def rewards(record) -> dict[str, np.ndarray]:
    """The paper's rewards of a rollout on expected points, per episode, and each one's
    rewards-to-go from every epoch on (``R_C_to_go``, ...)."""
    R = hierarchical_rewards(record, expected=True)
    R.update({f"{key}_to_go": v for key, v in rewards_to_go(record, expected=True).items()})
    return R


def scaled(advantage: np.ndarray, device: torch.device | None = None) -> torch.Tensor:
    """The advantages over their standard deviation (the step's size does not follow the
    rewards' scale)."""
    return torch.as_tensor(advantage / (advantage.std() + 1e-6), dtype=torch.float32,
                           device=device)


def move(net: torch.nn.Module, optimizers: list[torch.optim.Optimizer],
         device: torch.device) -> None:
    """`net`'s parameters (the same objects, so the optimisers still hold them) and the
    optimisers' moment estimates onto `device` (each step count stays on the CPU, where Adam
    keeps it)."""
    net.to(device)
    for opt in optimizers:
        for state in opt.state.values():
            for key, value in state.items():
                if torch.is_tensor(value) and key != "step":
                    state[key] = value.to(device)


@contextmanager
def on_device(net: torch.nn.Module, optimizers: list[torch.optim.Optimizer],
              device: torch.device) -> Iterator[None]:
    """The networks and their optimisers on `device` for an update, then back on the CPU,
    where the rollouts decode and the checkpoints are written from."""
    if device.type == "cpu":
        yield
        return
    from torch.nn.attention import SDPBackend, sdpa_kernel   # on use: a GPU's kernels
    move(net, optimizers, device)
    try:
        # attention by its plain formula: the fused kernels' backward passes are not
        # deterministic, and a seed should give the same run
        with sdpa_kernel(SDPBackend.MATH):
            yield
    finally:
        move(net, optimizers, torch.device("cpu"))


class PolicyPhase:
    """A phase of shared-baseline policy-gradient steps; a subclass gives its name, its
    learning rate and its loss."""

    name = ""
    rewards_logged = ("R_ITA", "R_C", "R_TR")
    """The paper's rewards that mean something in this phase (log.csv leaves the others empty)."""
    reallocates = True
    """Whether the phase's rollouts may reallocate (else log.csv's reallocations stays empty)."""

    def __init__(self, trainer: Host):
        self.tr = trainer

    def lr(self) -> float:
        raise NotImplementedError

    def lr_at(self, k: int) -> float:
        """The learning rate of step k (the phase's own, unless a subclass schedules it)."""
        return self.lr()

    def fresh_best(self) -> bool:
        """Whether best.pt is chosen afresh from this phase's step 0 on."""
        return False

    def loss(self, rec: Recorder, R: dict[str, np.ndarray]) -> torch.Tensor:
        """The step's loss: the sum of its parts."""
        return sum(part() for part in self.parts(rec, R))

    def parts(self, rec: Recorder, R: dict[str, np.ndarray]
              ) -> Iterator[Callable[[], torch.Tensor]]:
        """The step's loss in parts whose sum it is, each a function that builds its part: the
        update takes each part's gradient apart (smaller passes, whose tensors stay in the
        processor's caches; side by side on `threads` CPU threads) and then steps once on
        their sum, added in the parts' order."""
        raise NotImplementedError

    def phase(self) -> Phase:
        s, tr = self.tr.s, self.tr
        return Phase(self.name, tr.phases()[self.name], self.step,
                     checkpoint_every=s.checkpoint_every, eval_every=s.eval_every,
                     validate=lambda: tr.validate(self.name), validate_first=True,
                     fresh_best=self.fresh_best(), start=self.start)

    def start(self) -> None:
        """What the phase does before its first step here (each step sets its own rate)."""

    def step(self, k: int) -> tuple[dict[str, Any], int]:
        tr, s = self.tr, self.tr.s
        setting = tr.setting(k)
        mission = tr.mission_of(setting, s.seed)
        ids = np.repeat(tr.ids(self.name, k), s.samples)
        record, rec = tr.rollout(mission, ids, self.name, train=True)
        R = rewards(record)
        for group in tr.opt.param_groups:
            group["lr"] = self.lr_at(k)
        loss = self.learn(rec, R)
        columns = {"setting": setting, "loss": f"{loss:.4f}",
                   "mean_score": f"{R['total'].mean():.2f}",
                   **{key: f"{R[key].mean():.2f}" for key in self.rewards_logged}}
        if self.reallocates:
            columns["reallocations"] = f"{record.reallocated[:, 1:].sum(1).mean():.2f}"
        return columns, ids.size

    def learn(self, rec: Recorder, R: dict[str, np.ndarray]) -> float:
        """The loss of a rollout and one update on it, on the trainer's update device;
        returns the loss."""
        tr = self.tr
        with on_device(tr.net, [tr.opt], tr.device):
            tr.opt.zero_grad()
            params = [p for p in tr.net.parameters() if p.requires_grad]
            threads = tr.s.threads if tr.device.type == "cpu" else 1
            loss = 0.0
            for value, grads in part_gradients(list(self.parts(rec, R)), params, threads):
                loss += value
                for p, g in zip(params, grads):
                    if g is None:
                        continue
                    if p.grad is None:
                        p.grad = g
                    else:
                        p.grad += g       # as backward() accumulates: the parts in order
            self.update()
            return loss

    def update(self) -> None:
        """One Adam step of the policies on the gradients taken, clipped (not the
        reconstructors')."""
        tr = self.tr
        if tr.s.grad_clip > 0:
            torch.nn.utils.clip_grad_norm_(tr.policy_params, tr.s.grad_clip)
        tr.opt.step()


def part_gradients(parts: list[Callable[[], torch.Tensor]], params: list[torch.Tensor],
                   threads: int) -> list[tuple[float, tuple[torch.Tensor | None, ...]]]:
    """Each part's loss value and its gradients with respect to `params` (None where a part
    does not use one), in the parts' order. With `threads` above 1, that many parts are built
    and differentiated side by side, each on its own thread, every torch operation on one CPU
    thread (the trainer sets one): each part's gradients are those of `threads` = 1, bit for
    bit, so the update does not depend on the count."""
    def one(part: Callable[[], torch.Tensor]):
        loss = part()
        return loss.item(), torch.autograd.grad(loss, params, allow_unused=True)
    if threads <= 1 or len(parts) <= 1:
        return [one(part) for part in parts]
    with ThreadPoolExecutor(min(threads, len(parts))) as pool:
        return list(pool.map(one, parts))
