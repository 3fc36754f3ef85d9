"""The events a policy sees (MODEL.md section 6, as observed): robots newly down and POIs whose
kind or difficulty newly changed, against the last epoch's observation (at the first epoch,
against the state at t = 0: every robot working, the POIs as I estimates them)."""

from __future__ import annotations

import numpy as np

from ata.core.state import DecisionContext


class EventWatch:
    """The last observation of each scenario's robots and POIs, and what changed since."""

    def __init__(self) -> None:
        self.working: np.ndarray | None = None     # (B, R) robots working last epoch
        self.attrs: np.ndarray | None = None       # (B, P, 2) kind, difficulty last epoch

    def step(self, ctx: DecisionContext, working: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(B, R) robots down now that were working, (B, P) POIs whose kind or difficulty the
        observation shows changed, given `working` (B, R) as the policy sees it now; then
        remember this epoch."""
        tasks = ctx.observed["tasks"]
        attrs = np.stack([tasks.col("kind"), tasks.col("difficulty")], axis=-1)
        if self.working is None:
            start = ctx.inherent["tasks"]
            self.working = np.ones_like(working)
            self.attrs = np.stack([start.col("kind"), start.col("difficulty")], axis=-1)
        failed = self.working & ~working
        changed = (attrs != self.attrs).any(axis=-1)
        self.working, self.attrs = working, attrs
        return failed, changed
