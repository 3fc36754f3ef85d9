"""The status phase: the aux module's status head (``status_hidden`` > 0), fitted after aux.

The greedy teacher plays ``status_batches`` batches per team setting and level of
``status_levels``, with the injectors on, from the aux range after the aux phase's own
rollouts; the head then learns, per POI and epoch after the first, whether the POI is truly
unvisited, classified and reallocatable (binary cross-entropy, ``status_steps`` Adam steps on
minibatches of 4096 POI-epochs). Its data and minibatches come from a generator of its own, so
a run with the head trains every other part as a run without it does.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import torch

from ata.core.settings import param
from ata.plugins.ata_hrl.phases.aux import teacher_log
from ata.plugins.ata_hrl.status import GUESSES, guesses
from ata.training import Phase
from ata.plugins.ata_hrl.phases.host import Host



@dataclass
class Settings:
    """The status phase's keys of ``[ata_hrl]``."""

    status_hidden: int = param(0, min=0, help="status: width of the aux module's status head "
                               "(0: none); trained only where the reconstructors include aux "
                               "(the shipped (b) weights: 64)")
    status_levels: list[str] = param(["low", "medium", "high"],
                                     choices=("none", "low", "medium", "high"),
                                     help="status: uncertainty levels of the head's teacher "
                                     "rollouts")
    status_batches: int = param(4, min=1, help="status: teacher rollouts (of batch_size "
                                "scenarios) per team setting and level for the head's data")
    status_steps: int = param(2000, min=0, help="status: supervised steps of the head")
    status_lr: float = param(3e-3, min=0.0, max=1.0, help="status: Adam learning rate of the "
                             "head")


class StatusPhase:
    """The status phase of a trainer (see the module's doc)."""

    name = "status"

    def __init__(self, trainer: Host):
        self.tr = trainer
        self.x = self.y = torch.zeros(0)

    def phase(self) -> Phase:
        return Phase(self.name, self.tr.phases()[self.name], self.step,
                     checkpoint_every=self.tr.s.checkpoint_every, start=self.collect,
                     end=self.report)

    def rollouts(self, batches: int) -> int:
        """Teacher rollouts of `batches` batches per team setting and status level."""
        return batches * len(self.tr.s.team_settings) * len(self.tr.s.status_levels)

    def collect(self) -> None:
        self.x, self.y = self.rows(0, self.tr.s.status_batches)

    def rows(self, first: int, batches: int) -> tuple[torch.Tensor, torch.Tensor]:
        """(features, targets) of every POI at every epoch >= 1 of the teacher batches first ..
        first+batches-1 of each team setting and level."""
        tr, s = self.tr, self.tr.s
        X, Y = [], []
        combos = [(t, lv) for t in s.team_settings for lv in s.status_levels]
        for i in range(batches):
            for j, (setting, level) in enumerate(combos):
                k = s.aux_batches + 1 + (first + i) * len(combos) + j
                log = teacher_log(tr, tr.mission_of(f"{setting}/{level}", s.seed),
                                  tr.ids("aux", k))
                X += [x.reshape(-1, x.shape[-1]) for x in log["status_in"]]
                Y += [y.reshape(-1, y.shape[-1]) for y in log["status_target"]]
        return torch.as_tensor(np.concatenate(X)), torch.as_tensor(np.concatenate(Y))

    def step(self, k: int) -> tuple[dict[str, Any], int]:
        tr = self.tr
        idx = torch.randint(0, self.x.shape[0], (min(self.x.shape[0], 4096),),
                            generator=tr.status_gen)
        loss = torch.nn.functional.binary_cross_entropy_with_logits(
            tr.net.status(self.x[idx]), self.y[idx])
        tr.status_opt.zero_grad()
        loss.backward()
        tr.status_opt.step()
        return {"loss": f"{loss.item():.5f}"}, 0

    def report(self) -> dict[str, float]:
        """On held-out teacher rollouts (one batch per team setting and level), as shares of
        all their POI-epochs after the first epoch: the POIs shown open that are truly captured
        / committed (hidden), how many of those the head finds, and how many it takes wrongly."""
        x, y = self.rows(self.tr.s.status_batches, 1)
        with torch.no_grad():
            prob = torch.sigmoid(self.tr.net.status(x)).numpy()
        x, y = x.numpy(), y.numpy()
        g = guesses(x, prob)
        out = {}
        for name, (shown, target) in GUESSES.items():
            hidden = (x[:, shown] > 0.5) & (y[:, target] < 0.5)
            took = g[name][:, 0] > 0.5
            out[f"status_{name}_hidden"] = float(hidden.mean())
            out[f"status_{name}_found"] = float((took & hidden).mean())
            out[f"status_{name}_wrong"] = float((took & ~hidden).mean())
        return out
