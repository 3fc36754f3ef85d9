"""A prototype: a method with the status MLP of tools/round7/status_fit.py guessing, at every
epoch >= 1, the captures and commitments the latency hides; paired with the method as it is,
on N selection scenarios (root seed 99000017). Guessed captures go to `plan_start` as
``captured_guess``; guessed commitments make the POI not reallocatable in the policy's view
(`ctx.reallocatable`). Uses I, S, S an epoch before, the allocation in force and the previous
plan's projection only.

Usage: python tools/round7/status_try.py METHOD SETTING LEVEL N WEIGHTS [VARIANT ...]
VARIANT: captures | commitments | both (default: all three). METHOD as in fresh_parts.py.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import torch

sys.path.insert(0, str(Path(__file__).resolve().parent))
from fresh_parts import session                              # noqa: E402
from status_fit import features, mlp                         # noqa: E402

from ata.core.kernel import Simulation                       # noqa: E402
from ata.plugins.policies.plan import plan_start, project    # noqa: E402


def run(s, n: int, net, variant: str | None) -> np.ndarray:
    sim = Simulation(s.mission, s.registry, list(range(n)))
    sim.reset()
    prev_obs = prev_arr = prev_realloc = None
    while sim.sim.epoch < sim.sim.clock.n_epochs:
        ctx = sim.begin_epoch()
        raw_realloc = ctx.reallocatable.copy()
        if ctx.epoch >= 1 and variant is not None:
            x = features(ctx, prev_obs, prev_arr, prev_realloc)
            with torch.no_grad():
                pred = torch.sigmoid(net(torch.as_tensor(x))).numpy()
            if variant in ("captures", "both"):
                cap = (x[..., 0] > 0.5) & (pred[..., 0] < 0.5)
                ctx.reconstructed["captured_guess"] = cap[..., None].astype(float)
            if variant in ("commitments", "both"):
                ctx.reallocatable &= ~(pred[..., 2] < 0.5)
        sim.end_epoch(*sim.decide(ctx))
        if ctx.observed is not None:
            prev_arr = project(plan_start(ctx), sim.sim.allocation).arrival
            prev_obs = {g: ctx.observed[g].features.copy() for g in ("tasks", "robots")}
            prev_realloc = raw_realloc
    return sim.end_episode().metrics["expected_score"]


def main(method, setting, level, n, weights, variants) -> None:
    s = session(method, setting, level)
    net = mlp(17)
    net.load_state_dict(torch.load(weights, weights_only=True))
    base = run(s, n, net, None)
    print(f"{method}, {setting} {level}, {n} selection scenarios: expected points "
          f"{base.mean():.1f}")
    for v in variants or ["captures", "commitments", "both"]:
        d = run(s, n, net, v) - base
        print(f"  {v:14s} {d.mean():+7.1f} ± {1.96 * d.std(ddof=1) / np.sqrt(n):.1f}",
              flush=True)


if __name__ == "__main__":
    if len(sys.argv) < 6:
        sys.exit(__doc__)
    main(sys.argv[1], sys.argv[2], sys.argv[3], int(sys.argv[4]), sys.argv[5], sys.argv[6:])
