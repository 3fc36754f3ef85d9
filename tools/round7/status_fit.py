"""How far the task status that the latency hides can be learned from what a policy sees:
logs, at every epoch >= 1 of greedy rollouts with the latency on, per POI, features of the
observed S, its previous epoch, the allocation in force and the previous epoch's plan (its
projected capture times, the model in expectation on the observed estimates), with the true
status; fits a small MLP on one root seed and reports, on another (99000017, selection), per
scenario-epoch, how many hidden captures (captured, shown unvisited) and hidden commitments
(shown reallocatable, truly not) it finds, right and wrong.

With OUT, the fitted MLP's state dict goes there (for tools/round7/status_try.py).

Usage: python tools/round7/status_fit.py SETTING LEVEL N_TRAIN N_TEST [OUT]
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import torch

from ata.core.kernel import Simulation
from ata.experiment.runner import load_session
from ata.plugins.policies.plan import plan_start, project

ROOT = Path(__file__).resolve().parents[2]


def features(ctx, prev_obs, prev_arrival, prev_realloc) -> np.ndarray:
    """(B, P, F) per-POI features from I, S, S an epoch before, the allocation in force and
    the previous plan's projected captures."""
    S, alloc = ctx.observed, ctx.previous
    t, rob = S["tasks"], S["robots"]
    B, P = t.features.shape[:2]
    copy_t = (t.features == prev_obs["tasks"]).all(-1)
    copy_r = (rob.features == prev_obs["robots"]).all(-1)
    r = np.maximum(alloc.robot, 0)
    has_r = alloc.robot >= 0
    take = lambda a: np.take_along_axis(a, r, axis=1)          # noqa: E731
    target = rob.col("target").astype(np.int64)
    before = prev_obs["robots"][..., rob.index("target")].astype(np.int64)
    p_idx = np.arange(P)[None, :]
    r_target, r_before = take(target), take(before)
    area = ctx.inherent.extras["area_m"][:, None]
    I_t, I_r = ctx.inherent["tasks"], ctx.inherent["robots"]
    dx = take(rob.col("x")) - I_t.col("x")
    dy = take(rob.col("y")) - I_t.col("y")
    speed = take(I_r.col("speed").astype(float))
    dist_epochs = np.hypot(dx, dy) * area / np.maximum(speed, 1e-9) / ctx.clock.epoch_s
    due = np.clip((prev_arrival - ctx.time) / ctx.clock.epoch_s, -3, 3)
    due = np.where(np.isfinite(prev_arrival), due, 3.0)
    f = np.stack([
        t.col("unvisited"), t.col("captured"), t.col("classified"), copy_t,
        ctx.reallocatable, prev_realloc, has_r, take(copy_r) & has_r,
        take(rob.col("working")), r_target == p_idx, r_before == p_idx,
        (r_target != r_before) & has_r, r_target < 0, np.minimum(dist_epochs, 3.0), due,
        alloc.classifier >= 0, np.full((B, P), ctx.epoch / ctx.clock.n_epochs)],
        -1).astype(np.float32)
    return f


def log(setting: str, level: str, seed: int, n: int):
    s = load_session(str(ROOT / "ata" / "missions" / "greedy.toml"),
                     [f"mission.setting='{setting}'", f"mission.uncertainty='{level}'",
                      f"mission.seed={seed}"])
    sim = Simulation(s.mission, s.registry, list(range(n)))
    sim.reset()
    X, Y, rule = [], [], []
    prev_obs = prev_arr = prev_realloc = None
    while sim.sim.epoch < sim.sim.clock.n_epochs:
        ctx = sim.begin_epoch()
        truth = sim.last_truth
        if ctx.epoch >= 1:
            X.append(features(ctx, prev_obs, prev_arr, prev_realloc))
            tt = truth["tasks"]
            Y.append(np.stack([tt.col("unvisited"), tt.col("classified"),
                               truth.reallocatable], -1).astype(np.float32))
        decision = sim.decide(ctx)
        sim.end_epoch(*decision)
        # the plan in force after this epoch's decision, projected from this epoch's S
        if ctx.observed is not None:
            prev_arr = project(plan_start(ctx), sim.sim.allocation).arrival
            prev_obs = {g: ctx.observed[g].features.copy() for g in ("tasks", "robots")}
            prev_realloc = ctx.reallocatable.copy()
    return np.concatenate(X), np.concatenate(Y), n


def report(name, pred, X, Y, n_scen_epochs):
    shown_open = X[..., 0] > 0.5
    hid_cap = shown_open & (Y[..., 0] < 0.5)
    g_cap = shown_open & (pred[..., 0] < 0.5)
    shown_re = X[..., 4] > 0.5
    hid_com = shown_re & (Y[..., 2] < 0.5)
    g_com = shown_re & (pred[..., 2] < 0.5)
    shown_wait = (X[..., 1] > 0.5) & (X[..., 2] < 0.5)
    hid_cls = shown_wait & (Y[..., 1] > 0.5)
    g_cls = shown_wait & (pred[..., 1] > 0.5)
    per = lambda m: m.sum() / n_scen_epochs                  # noqa: E731
    print(f"{name}: per scenario-epoch")
    for what, hid, g in (("captured, shown unvisited", hid_cap, g_cap),
                         ("committed, shown reallocatable", hid_com, g_com),
                         ("classified, shown waiting", hid_cls, g_cls)):
        print(f"  {what:32s} hidden {per(hid):6.3f}  found {per(g & hid):6.3f}  "
              f"wrong {per(g & ~hid):6.3f}")


def mlp(F: int) -> torch.nn.Module:
    return torch.nn.Sequential(torch.nn.Linear(F, 64), torch.nn.ReLU(), torch.nn.Linear(64, 64),
                               torch.nn.ReLU(), torch.nn.Linear(64, 3))


def main(setting: str, level: str, n_train: int, n_test: int, out: str | None = None) -> None:
    torch.manual_seed(0)
    Xtr, Ytr, _ = log(setting, level, 4242, n_train)
    Xte, Yte, _ = log(setting, level, 99000017, n_test)
    epochs_te = Xte.shape[0] // n_test
    F = Xtr.shape[-1]
    net = mlp(F)
    opt = torch.optim.Adam(net.parameters(), lr=3e-3)
    x = torch.as_tensor(Xtr.reshape(-1, F))
    y = torch.as_tensor(Ytr.reshape(-1, 3))
    for step in range(3000):
        idx = torch.randint(0, x.shape[0], (4096,))
        loss = torch.nn.functional.binary_cross_entropy_with_logits(net(x[idx]), y[idx])
        opt.zero_grad()
        loss.backward()
        opt.step()
    with torch.no_grad():
        pred = torch.sigmoid(net(torch.as_tensor(Xte))).numpy()
    # as observed: the prediction is the observation itself
    report("as observed", np.stack([Xte[..., 0], Xte[..., 2], Xte[..., 4]], -1), Xte, Yte,
           n_test * epochs_te)
    report("MLP", pred, Xte, Yte, n_test * epochs_te)
    if out:
        torch.save(net.state_dict(), out)


if __name__ == "__main__":
    if len(sys.argv) not in (5, 6):
        sys.exit(__doc__)
    main(sys.argv[1], sys.argv[2], int(sys.argv[3]), int(sys.argv[4]), *sys.argv[5:])
