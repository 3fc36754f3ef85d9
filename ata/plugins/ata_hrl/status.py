"""The status part of ATA-HRL's auxiliary reconstruction: which POIs the latency shows open
that are truly captured or committed (a robot on its way), learned from what a policy sees.

A stale POI row cannot tell from its own past that its robot has arrived; that shows across
rows (the robot's row, the allocation in force) and in time (the plan the previous epoch made
expected the capture by now). So the features of a POI read its own observed row and whether it
is a copy of the last epoch's, the row of the robot the allocation in force gives it, and when
the previous epoch's plan projected its capture (`ata.model.plan.project`, the model in
expectation on that epoch's observed estimates). Nothing here reads the true state; the
trainer pairs the features with the truth to fit the head (``StatusHead`` in the network).

Its guesses go into the reconstructed-state dict: ``captured_guess`` (B, P, 1), POIs shown
unvisited that it takes as captured, and ``committed_guess`` (B, P, 1), POIs shown reallocatable
that it takes as committed. `plan_start` and `as_seen` apply them.
"""

from __future__ import annotations

import numpy as np

from ata.core.state import Allocation, DecisionContext, Observation, SimState
from ata.model.plan import PlanStart, plan_start, project

STATUS_FEATURES = 17
"""Features per POI (see `status_features`)."""
STATUS_TARGETS = ("unvisited", "classified", "reallocatable")
"""What the head predicts per POI (probabilities of the true values; `status_targets`)."""
GUESSES = {"captured": (0, 0), "committed": (4, 2)}
"""Each guess: (the feature column that shows the POI open: observed unvisited, observed
reallocatable; the target column whose truth the guess denies: unvisited, reallocatable)."""


def status_features(now: float, epoch: int, clock, inherent: Observation, obs: Observation,
                    realloc: np.ndarray, prev_obs: dict[str, np.ndarray],
                    prev_realloc: np.ndarray, allocation: Allocation,
                    prev_arrival: np.ndarray) -> np.ndarray:
    """(B, P, STATUS_FEATURES) float32 per-POI features from I, S now, S an epoch before, the
    allocation in force and the capture times the previous epoch's plan projected."""
    t, rob = obs["tasks"], obs["robots"]
    B, P = t.features.shape[:2]
    copy_t = (t.features == prev_obs["tasks"]).all(-1)
    copy_r = (rob.features == prev_obs["robots"]).all(-1)
    r = np.maximum(allocation.robot, 0)
    has_r = allocation.robot >= 0

    def of_robot(a: np.ndarray) -> np.ndarray:
        return np.take_along_axis(a, r, axis=1)

    target = rob.col("target").astype(np.int64)
    before = prev_obs["robots"][..., rob.index("target")].astype(np.int64)
    p_idx = np.arange(P)[None, :]
    r_target, r_before = of_robot(target), of_robot(before)
    area = inherent.extras["area_m"][:, None]
    it, ir = inherent["tasks"], inherent["robots"]
    dist = np.hypot(of_robot(rob.col("x")) - it.col("x"), of_robot(rob.col("y")) - it.col("y"))
    speed = of_robot(ir.col("speed").astype(float))
    dist_epochs = dist * area / np.maximum(speed, 1e-9) / clock.epoch_s
    due = np.where(np.isfinite(prev_arrival),
                   np.clip((prev_arrival - now) / clock.epoch_s, -3.0, 3.0), 3.0)
    return np.stack([
        t.col("unvisited"), t.col("captured"), t.col("classified"), copy_t,
        realloc, prev_realloc, has_r, of_robot(copy_r) & has_r, of_robot(rob.col("working")),
        r_target == p_idx, r_before == p_idx, (r_target != r_before) & has_r, r_target < 0,
        np.minimum(dist_epochs, 3.0), due, allocation.classifier >= 0,
        np.full((B, P), epoch / clock.n_epochs)], -1).astype(np.float32)


class StatusTracker:
    """What the features need from one epoch to the next: the previous epoch's observed task and
    robot rows, its observed ``reallocatable`` and its plan start. `step` is called once per
    epoch, in the reconstruction (before the decision, with the allocation then in force)."""

    def __init__(self) -> None:
        self.prev_obs: dict[str, np.ndarray] | None = None
        self.prev_realloc: np.ndarray | None = None
        self.prev_start: PlanStart | None = None

    def step(self, sim: SimState, obs: Observation, inherent: Observation) -> np.ndarray | None:
        """The features at this epoch (None at the first: nothing to compare with yet), then
        remember this epoch."""
        B, P = sim.batch_size, sim.sizes.tasks
        realloc = (obs.reallocatable if obs.reallocatable is not None
                   else np.ones((B, P), dtype=bool))
        feats = None
        if self.prev_start is not None and sim.allocation is not None:
            # when the plan now in force, made from the last epoch's S, expected each capture
            arrival = project(self.prev_start, sim.allocation).arrival
            feats = status_features(sim.now, sim.epoch, sim.clock, inherent, obs, realloc,
                                    self.prev_obs, self.prev_realloc, sim.allocation, arrival)
        ctx = DecisionContext(epoch=sim.epoch, time=sim.now, sizes=sim.sizes, clock=sim.clock,
                              inherent=inherent, observed=obs, reconstructed={},
                              previous=sim.allocation, reallocatable=realloc, rng=sim.rng,
                              channel=sim.channel)
        self.prev_start = plan_start(ctx)
        self.prev_obs = {g: obs[g].features.copy() for g in ("tasks", "robots")}
        self.prev_realloc = realloc.copy()
        return feats


def guesses(feats: np.ndarray, prob: np.ndarray) -> dict[str, np.ndarray]:
    """The reconstruction's guesses from the head's probabilities (B, P, 3): a POI shown
    unvisited whose probability of being unvisited is below one half is taken as captured; one
    shown reallocatable whose probability of being reallocatable is below one half, as
    committed."""
    return {name: ((feats[..., shown] > 0.5) & (prob[..., target] < 0.5))[..., None]
            .astype(float) for name, (shown, target) in GUESSES.items()}


def status_targets(truth: Observation) -> np.ndarray:
    """(B, P, 3) the true values the head predicts (the trainer's targets)."""
    tt = truth["tasks"]
    realloc = (truth.reallocatable if truth.reallocatable is not None
               else np.ones(tt.features.shape[:2], dtype=bool))
    cols = {"unvisited": tt.col("unvisited"), "classified": tt.col("classified"),
            "reallocatable": realloc}
    return np.stack([cols[c] for c in STATUS_TARGETS], -1).astype(np.float32)
