"""What the latency hides, row by row: runs w/o.AUX of a setting on N selection scenarios (root
seed 99000017, never the held-out ones) and, at every epoch >= 1, counts the task and robot rows
whose observation differs from the true state (the kernel's `last_truth`), by what differs: a
task captured or classified that shows as before, a revealed kind or difficulty not yet shown,
the observed `reallocatable` wrong; a failed robot shown working, a robot's target or position
out of date. Per scenario and epoch, and whether the row is a copy of the one observed an epoch
before (a row that changed is known fresh). With `arrivals` last, w/o.AUX runs with the
`arrivals` reconstructor too, and its guesses are counted: right (truly captured) and wrong.

Usage: python tools/round6/stale_rows.py SETTING LEVEL [N [arrivals]]   (e.g. b high 24)
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from ata.core.kernel import Simulation
from ata.experiment.runner import load_session

ROOT = Path(__file__).resolve().parents[2]


def main(setting: str, level: str, n: int = 24, arrivals: bool = False) -> None:
    mission = ROOT / "examples" / "missions" / "ata_hrl_wo_aux_a.toml"
    extra = ([f"{c}.checkpoint='builtin:ata_hrl_wo_aux_b_ft'" for c in ("attention", "ctr")]
             if setting == "b" else [])
    s = load_session(str(mission), [f"mission.setting='{setting}'",
                                     f"mission.uncertainty='{level}'", "mission.seed=99000017",
                                     *extra, *(["components.reconstructors=['identity','arrivals']"]
                                                  if arrivals else [])])
    sim = Simulation(s.mission, s.registry, list(range(n)))
    sim.reset()
    counts: dict[str, float] = {}
    epochs = 0

    def add(name: str, mask: np.ndarray) -> None:
        counts[name] = counts.get(name, 0.0) + float(mask.sum())

    prev = None
    while sim.sim.epoch < sim.sim.clock.n_epochs:
        ctx = sim.begin_epoch()
        obs, truth = ctx.observed, sim.last_truth
        if ctx.epoch >= 1:
            epochs += 1
            ot, tt = obs["tasks"], truth["tasks"]
            copy_t = (ot.features == prev["tasks"]).all(-1)
            add("tasks: captured, shown unvisited", (ot.col("unvisited") > 0.5)
                & (tt.col("unvisited") < 0.5))
            add("tasks: classified, shown waiting", (ot.col("captured") > 0.5)
                & (tt.col("classified") > 0.5))
            add("tasks: kind or difficulty not yet shown",
                (ot.col("kind") != tt.col("kind")) | (ot.col("difficulty") != tt.col("difficulty")))
            add("tasks: shown reallocatable, truly not", ctx.reallocatable
                & ~truth.reallocatable)
            add("tasks: rows that differ from the truth", (ot.features != tt.features).any(-1))
            add("tasks: ... of them copies of the last", copy_t
                & (ot.features != tt.features).any(-1))
            add("tasks: copies of the last (all)", copy_t)
            if arrivals:
                guess = ctx.reconstructed["captured_guess"][..., 0] > 0.5
                add("arrivals: guessed captured, right", guess & (tt.col("unvisited") < 0.5))
                add("arrivals: guessed captured, wrong", guess & (tt.col("unvisited") > 0.5))
            orb, trb = obs["robots"], truth["robots"]
            copy_r = (orb.features == prev["robots"]).all(-1)
            add("robots: failed, shown working", (orb.col("working") > 0.5)
                & (trb.col("working") < 0.5))
            add("robots: target out of date", orb.col("target") != trb.col("target"))
            add("robots: position out of date", (orb.col("x") != trb.col("x"))
                | (orb.col("y") != trb.col("y")))
            add("robots: copies of the last (all)", copy_r)
        prev = {g: obs[g].features.copy() for g in ("tasks", "robots")}
        sim.end_epoch(*sim.decide(ctx))
    per = n * epochs
    print(f"w/o.AUX, {setting} {level}, {n} scenarios x {epochs} epochs: rows per scenario-epoch")
    for k, v in counts.items():
        print(f"  {k:42s} {v / per:8.3f}")


if __name__ == "__main__":
    if len(sys.argv) < 3 or sys.argv[5:] or sys.argv[4:5] not in ([], ["arrivals"]):
        sys.exit(__doc__)
    main(sys.argv[1], sys.argv[2], *(int(a) for a in sys.argv[3:4]), *(True for _ in sys.argv[4:5]))
