"""Which part of what the latency hides costs points: runs a method with the latency on, on N
selection scenarios (root seed 99000017, never the held-out ones), once as it is and once per
PART with that part of the observation put back to the truth (the kernel's `last_truth`) before
the policy decides. The latency's own chain of stale rows is left as it is; only what the policy
sees changes. A diagnostic that peeks, by design: it bounds what a reconstruction of each part
could be worth; no policy may use it.

PARTS: realloc (the observed `reallocatable`), status (a task row's unvisited, captured,
classified), attrs (its kind, difficulty), tasks (all of a task row, and realloc), robot_xy,
robot_target, robot_working, robots (all of a robot row); join parts with + to put back several.

Usage: python tools/round7/fresh_parts.py METHOD SETTING LEVEL N PART [PART ...]
METHOD: greedy | wo_aux | ata_hrl. Prints expected points, each variant paired with the method
as it is: mean difference ± 1.96 SE.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from ata.core.kernel import Simulation
from ata.experiment.runner import load_session

ROOT = Path(__file__).resolve().parents[2]
TASK_COLS = {"status": ("unvisited", "captured", "classified"), "attrs": ("kind", "difficulty")}
ROBOT_COLS = {"robot_xy": ("x", "y"), "robot_target": ("target",),
              "robot_working": ("working",)}


def session(method: str, setting: str, level: str):
    sets = [f"mission.setting='{setting}'", f"mission.uncertainty='{level}'",
            "mission.seed=99000017"]
    if method == "greedy":
        return load_session(str(ROOT / "ata" / "missions" / "greedy.toml"), sets)
    name = {"wo_aux": "ata_hrl_wo_aux_a.toml", "ata_hrl": "ata_hrl_a.toml"}[method]
    if setting == "b":
        base = {"wo_aux": "ata_hrl_wo_aux_b_ft", "ata_hrl": "ata_hrl_b_ft"}[method]
        comps = ("attention", "ctr") + (("aux",) if method == "ata_hrl" else ())
        sets += [f"{c}.checkpoint='builtin:{base}'" for c in comps]
    return load_session(str(ROOT / "examples" / "missions" / name), sets)


def put_back(ctx, truth, parts: set[str]) -> None:
    obs = ctx.observed
    cols_t = [c for p, cs in TASK_COLS.items() if p in parts or "tasks" in parts for c in cs]
    cols_r = [c for p, cs in ROBOT_COLS.items() if p in parts or "robots" in parts for c in cs]
    for group, cols in (("tasks", cols_t), ("robots", cols_r)):
        for c in cols:
            j = obs[group].index(c)
            obs[group].features[..., j] = truth[group].features[..., j]
    if "realloc" in parts or "tasks" in parts:
        np.copyto(ctx.reallocatable, truth.reallocatable)


def run(s, n: int, parts: set[str]) -> np.ndarray:
    sim = Simulation(s.mission, s.registry, list(range(n)))
    sim.reset()
    while sim.sim.epoch < sim.sim.clock.n_epochs:
        ctx = sim.begin_epoch()
        if ctx.epoch >= 1 and parts:
            put_back(ctx, sim.last_truth, parts)
        sim.end_epoch(*sim.decide(ctx))
    return sim.end_episode().metrics["expected_score"]


def main(method: str, setting: str, level: str, n: int, variants: list[str]) -> None:
    s = session(method, setting, level)
    base = run(s, n, set())
    print(f"{method}, {setting} {level}, {n} selection scenarios: expected points "
          f"{base.mean():.1f}")
    for v in variants:
        parts = set(v.split("+"))
        unknown = parts - set(TASK_COLS) - set(ROBOT_COLS) - {"realloc", "tasks", "robots"}
        if unknown:
            sys.exit(f"unknown part(s) {sorted(unknown)}\n{__doc__}")
        d = run(s, n, parts) - base
        print(f"  {v:28s} {d.mean():+7.1f} ± {1.96 * d.std(ddof=1) / np.sqrt(n):.1f}",
              flush=True)


if __name__ == "__main__":
    if len(sys.argv) < 6:
        sys.exit(__doc__)
    main(sys.argv[1], sys.argv[2], sys.argv[3], int(sys.argv[4]), sys.argv[5:])
