"""How far are the auxiliary reconstruction's estimates from the true state, against the raw
observation they are made from? Runs the shipped ATA-HRL of a setting on N scenarios of root seed
99000017 (selection scenarios, never the held-out ones) and, at every epoch >= 1, compares with the
true state (the kernel's `last_truth`): human fatigue, robot rows (x, y, idleness, working, has a
target) and task rows (unvisited, captured, classified, kind, difficulty). Prints mean absolute
errors: observed, reconstructed, and reconstructed only where the observed row equals the one
observed an epoch before (a stale row is such a copy, so a row that changed is known fresh) and
observed elsewhere ("gated"); and the share of rows that are copies.

Usage: python tools/round5/aux_errors.py SETTING LEVEL [N] [CHECKPOINT]   (e.g. b high 24; the
checkpoint, a path or builtin:NAME, replaces the mission's weights for all three components)
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from ata.core.kernel import Simulation
from ata.experiment.runner import load_session
from ata.plugins.ata_hrl.features import state_features

ROOT = Path(__file__).resolve().parents[2]
ROBOT_COLS = ("x", "y", "idleness", "working", "target")
TASK_COLS = ("unvisited", "captured", "classified", "kind", "d0", "d1", "d2")


def main(setting: str, level: str, n: int = 24, checkpoint: str | None = None) -> None:
    mission = ROOT / "examples" / "missions" / f"ata_hrl_{setting}.toml"
    weights = [f"{c}.checkpoint='{checkpoint}'" for c in ("attention", "ctr", "aux")
               if checkpoint]
    s = load_session(str(mission), [f"mission.uncertainty='{level}'", "mission.seed=99000017",
                                     *weights])
    sim = Simulation(s.mission, s.registry, list(range(n)))
    sim.reset()
    err = {k: [] for k in ("fatigue obs", "fatigue aux")}
    rows = {g: {"obs": [], "aux": [], "gated": [], "copy": []} for g in ("robots", "tasks")}
    prev = None
    while sim.sim.epoch < sim.sim.clock.n_epochs:
        ctx = sim.begin_epoch()
        if ctx.epoch >= 1:
            truth = state_features(sim.last_truth)
            obs = state_features(ctx.observed)
            rec = ctx.reconstructed
            err["fatigue obs"].append(np.abs(obs["humans"][..., 1] - truth["humans"][..., 1]))
            err["fatigue aux"].append(np.abs(rec["aux_fatigue"] - truth["humans"][..., 1]))
            for g, r in rows.items():
                F = obs[g].shape[-1]
                copy = (obs[g] == prev[g]).all(-1, keepdims=True)
                gated = np.where(copy, rec[f"aux_{g}"], obs[g])
                r["obs"].append(np.abs(obs[g] - truth[g]).reshape(-1, F))
                r["aux"].append(np.abs(rec[f"aux_{g}"] - truth[g]).reshape(-1, F))
                r["gated"].append(np.abs(gated - truth[g]).reshape(-1, F))
                r["copy"].append(copy.ravel())
        prev = state_features(ctx.observed)
        sim.end_epoch(*sim.decide(ctx))
    print(f"{setting} {level}, {n} scenarios: mean absolute error against the true state")
    for k, v in err.items():
        print(f"  {k:12s} {np.concatenate([x.ravel() for x in v]).mean():.4f}")
    for name, cols in (("robots", ROBOT_COLS), ("tasks", TASK_COLS)):
        r = rows[name]
        o, a, g = (np.concatenate(r[k]).mean(0) for k in ("obs", "aux", "gated"))
        print(f"  {name}: {np.concatenate(r['copy']).mean():.3f} of rows are copies of the last")
        for c, eo, ea, eg in zip(cols, o, a, g):
            print(f"  {name}.{c:11s} observed {eo:.4f}  reconstructed {ea:.4f}  gated {eg:.4f}")


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2], *(int(a) for a in sys.argv[3:4]), *sys.argv[4:5])
