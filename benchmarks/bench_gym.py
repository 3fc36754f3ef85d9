"""Gymnasium adapter throughput: N single environments against one vector environment of N.

Usage: python benchmarks/bench_gym.py [--envs 64] [--rounds 5] [--seed 0] [--repeats 1]

For each team (the small custom team of examples/missions/gym_small_team.toml, and setting (a)),
steps `--envs` copies of `ata.gym.CentralisedEnv` under Gymnasium's `SyncVectorEnv` (one
`Simulation` of one scenario each, stepped one after the other) and one
`ata.gym.CentralisedVectorEnv` of `--envs` scenarios (one `Simulation` for all, one kernel call
per epoch), with the same random masked policy (`ata.gym.sample_masked` on the action masks),
for `--rounds` episodes per environment. Prints episodes per second of each, their ratio, and
the wall times. Both are measured in the same run: this machine is shared and noisy, so compare
ratios, not absolute figures across runs.
"""

from __future__ import annotations

import argparse
import math
import time
from pathlib import Path

import numpy as np
from gymnasium.vector import SyncVectorEnv
from rich.console import Console
from rich.table import Table

from ata.session import BASELINE_MISSION, load_session
from ata.gym import CentralisedEnv, CentralisedVectorEnv, sample_masked

SMALL_TEAM = Path(__file__).resolve().parent.parent / "examples" / "missions" / \
    "gym_small_team.toml"
TEAMS = {"small (H/R/P 2/3/10, T 15)": str(SMALL_TEAM),
         "(a) (H/R/P 6/8/60, T 30)": str(BASELINE_MISSION)}


def episodes_per_second(envs, rounds: int, seed: int) -> tuple[float, float, float]:
    """(episodes per second, wall seconds, CPU seconds of this process) of `rounds` episodes in
    every sub-environment under the random masked policy; the autoreset steps are part of the
    time."""
    rng = np.random.default_rng(seed)
    nvec = envs.single_action_space.nvec
    t0, c0 = time.perf_counter(), time.process_time()
    _, info = envs.reset(seed=seed)
    done = 0
    while done < rounds * envs.num_envs:
        _, _, terminated, _, info = envs.step(sample_masked(info["action_mask"], nvec, rng))
        done += int(terminated.sum())
    wall = time.perf_counter() - t0
    return done / wall, wall, time.process_time() - c0


def vector_vs_single(path: str, envs: int, rounds: int, seed: int,
                     repeats: int = 1) -> dict[str, float]:
    """Episodes per second, wall and CPU seconds of `envs` single environments under
    SyncVectorEnv and of one vector environment of `envs`, on the team of mission `path`; the
    ratio of the two, by wall time and by CPU time (steadier on a shared machine). With
    `repeats` > 1 the two are measured that many times in alternation (fresh environments,
    the same episodes) and each keeps its least wall and least CPU time: on a shared machine
    a run is only ever slowed by other work."""
    session = load_session(path)
    wall = {"single": math.inf, "vector": math.inf}
    cpu, episodes = dict(wall), {}
    for _ in range(repeats):
        for side in ("single", "vector"):
            env = (SyncVectorEnv([lambda: CentralisedEnv(session)] * envs) if side == "single"
                   else CentralisedVectorEnv(session, num_envs=envs))
            eps, w, c = episodes_per_second(env, rounds, seed)
            wall[side], cpu[side] = min(wall[side], w), min(cpu[side], c)
            episodes[side] = round(eps * w)        # the same episodes in every repeat
    rate = {side: episodes[side] / wall[side] for side in wall}
    return {"single": rate["single"], "vector": rate["vector"],
            "ratio": rate["vector"] / rate["single"],
            "wall_single": wall["single"], "wall_vector": wall["vector"],
            "cpu_single": cpu["single"], "cpu_vector": cpu["vector"],
            "cpu_ratio": cpu["single"] / cpu["vector"]}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--envs", type=int, default=64, help="environments N")
    parser.add_argument("--rounds", type=int, default=5, help="episodes per environment")
    parser.add_argument("--seed", type=int, default=0, help="root seed and policy seed")
    parser.add_argument("--repeats", type=int, default=1,
                        help="measure both this many times in alternation; keep the least")
    args = parser.parse_args()
    table = Table(title=f"ata.gym throughput, N = {args.envs} (episodes per second)")
    for col in ("team", "N single", "vector", "ratio", "wall single", "wall vector"):
        table.add_column(col, justify="left" if col == "team" else "right")
    for team, path in TEAMS.items():
        r = vector_vs_single(path, args.envs, args.rounds, args.seed, args.repeats)
        table.add_row(team, f"{r['single']:,.1f}", f"{r['vector']:,.1f}",
                      f"{r['ratio']:.1f}x", f"{r['wall_single']:.1f} s",
                      f"{r['wall_vector']:.1f} s")
    Console().print(table)


if __name__ == "__main__":
    main()
