"""The aux phase: the auxiliary state reconstruction, fitted to greedy teacher rollouts.

The teacher (greedy initial allocation, greedy reallocation on events) plays ``aux_batches``
batches of training scenarios; every epoch's observed and true state is logged. The cVAE then
learns the fatigue (reconstruction + 0.1 KL, the paper's L_cVAE) and the stacked GRUs each
robot's and task's current row from its sequence of observed rows (squared error against the
true rows), in ``aux_steps`` supervised steps on minibatches of the logged rows.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import torch

from ata import hookimpl
from ata.core.kernel import Simulation, build_component
from ata.core.settings import param
from ata.plugins.ata_hrl.components import AuxReconstructor
from ata.plugins.ata_hrl.features import HOURS_UNIT, state_column, state_features
from ata.plugins.ata_hrl.network import FatigueCVAE
from ata.plugins.ata_hrl.status import status_targets
from ata.training import Phase
from ata.plugins.ata_hrl.phases.host import Host



@dataclass
class Settings:
    """The aux phase's keys of ``[ata_hrl]``."""

    aux_batches: int = param(6, min=1, help="aux: teacher rollouts (of batch_size scenarios) "
                             "for the reconstruction data")
    aux_steps: int = param(400, min=0, help="aux: supervised steps of the reconstructors")
    aux_lr: float = param(3e-3, min=0.0, max=1.0, help="aux: Adam learning rate of the "
                          "reconstructors")


FATIGUE_IN = ("observed", "hours", "cognitive")
"""The columns of the cVAE's input rows (``fatigue_in``), in `FatigueCVAE`'s argument order: the
observed fatigue, the working hours, the cognitive ability."""


def teacher_log(trainer: Host, mission, ids: np.ndarray) -> dict[str, list]:
    """Roll out the greedy teacher on scenarios `ids` and log the observed and the true S of
    every epoch (and, with a status head, its inputs and targets)."""

    log = {"raw": [], "true": [], "fatigue": [], "cognitive": None,
           "status_in": [], "status_target": []}
    greedy = build_component(trainer.registry, mission, "policy", "greedy")
    on_event = build_component(trainer.registry, mission, "condition", "on_event")

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
    recon = AuxReconstructor(None, mission, net=trainer.net, guess=False)
    overrides = {"initial": teacher, "condition": teacher, "reallocation": teacher,
                 "reconstructors": recon}
    teacher.simulation = Simulation(mission, trainer.registry, ids, overrides=overrides)
    with torch.no_grad():
        teacher.simulation.run()
    return log


class AuxPhase:
    """The aux phase of a trainer (see the module's doc)."""

    name = "aux"

    def __init__(self, trainer: Host):
        self.tr = trainer
        self.data: dict[str, torch.Tensor] = {}

    def phase(self) -> Phase:
        s = self.tr.s
        return Phase(self.name, self.tr.phases()[self.name], self.step,
                     checkpoint_every=s.checkpoint_every, start=self.collect, end=self.report)

    def collect(self) -> None:
        self.data = self.rows(0, self.tr.s.aux_batches)

    def rows(self, first: int, batches: int) -> dict[str, torch.Tensor]:
        """The reconstructors' inputs and targets from teacher batches first .. first+batches-1
        of the aux range (each of the team setting, and level, of its step)."""
        tr = self.tr
        fat_in, fat_target = [], []
        seq_in, seq_target = {"robots": [], "tasks": []}, {"robots": [], "tasks": []}
        for i in range(batches):
            mission = tr.mission_of(tr.setting(first + i), tr.s.seed)
            log = teacher_log(tr, mission, tr.ids("aux", first + i))
            T = len(log["raw"])
            hours = np.stack([state_column(r, "humans", "working_time") * HOURS_UNIT
                              for r in log["raw"]], 1)                     # (B, T, H)
            f_obs = np.stack([state_column(r, "humans", "fatigue") for r in log["raw"]], 1)
            cog = np.broadcast_to(log["cognitive"][:, None, :], hours.shape)
            fat_in.append(np.stack([f_obs, hours, cog], -1).reshape(-1, len(FATIGUE_IN)))
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

    def losses(self, data: dict[str, torch.Tensor], idx: dict[str, torch.Tensor] | None = None,
               sample: bool = True) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """(cVAE loss, fatigue squared error, the GRUs' squared error summed over robot and task
        rows) on the data, or on the rows `idx` of it."""
        net = self.tr.net
        fi, ft = data["fatigue_in"], data["fatigue_target"]
        if idx is not None:
            fi, ft = fi[idx["fatigue"]], ft[idx["fatigue"]]
        recon, mu, logvar = net.fatigue(*fi.unbind(-1), sample=sample)    # FATIGUE_IN's order
        cvae = FatigueCVAE.loss(recon, ft, mu, logvar)
        f_mse = ((recon - ft) ** 2).mean()
        lat_mse = torch.zeros(())
        for g in ("robots", "tasks"):
            x, y = data[f"{g}_in"], data[f"{g}_target"]
            if idx is not None:
                x, y = x[idx[g]], y[idx[g]]
            est, _ = net.latency[g](x)
            err = est - y
            lat_mse = lat_mse + (err * err).mean()
        return cvae, f_mse, lat_mse

    def step(self, k: int) -> tuple[dict[str, Any], int]:
        """One Adam step of the cVAE and the GRUs on a minibatch of 1024 rows of each."""
        tr = self.tr
        sizes = {"fatigue": self.data["fatigue_in"].shape[0],
                 "robots": self.data["robots_in"].shape[0],
                 "tasks": self.data["tasks_in"].shape[0]}
        idx = {name: torch.randint(0, n, (min(n, 1024),), generator=tr.gen)
               for name, n in sizes.items()}
        cvae, f_mse, lat_mse = self.losses(self.data, idx)
        loss = cvae + lat_mse
        tr.aux_opt.zero_grad()
        loss.backward()
        tr.aux_opt.step()
        return {"loss": f"{loss.item():.5f}", "aux_fatigue_mse": f"{f_mse.item():.5f}",
                "aux_latency_mse": f"{lat_mse.item():.5f}"}, 0

    def report(self) -> dict[str, float]:
        """Held-out reconstruction errors (one teacher batch after the training ones): each
        estimate's (``fatigue_mse``; ``robots_mse`` and ``robots_mae``, ``tasks_mse`` and
        ``tasks_mae`` over the rows' columns) beside the same error of the observation taken as
        it is (``..._observed``), which the reconstruction must beat."""
        data = self.rows(self.tr.s.aux_batches, 1)
        net = self.tr.net
        with torch.no_grad():
            _, f_mse, _ = self.losses(data, sample=False)
            observed = data["fatigue_in"][:, FATIGUE_IN.index("observed")]
            raw_f = ((observed - data["fatigue_target"]) ** 2).mean()
            out = {"fatigue_mse": f_mse.item(), "fatigue_mse_observed": raw_f.item()}
            for g in ("robots", "tasks"):
                est, _ = net.latency[g](data[f"{g}_in"])
                err, raw = est - data[f"{g}_target"], data[f"{g}_in"] - data[f"{g}_target"]
                out[f"{g}_mse"], out[f"{g}_mse_observed"] = (err ** 2).mean().item(), \
                    (raw ** 2).mean().item()
                out[f"{g}_mae"], out[f"{g}_mae_observed"] = err.abs().mean().item(), \
                    raw.abs().mean().item()
        return out
