"""The six figures of the "Fast" goals (docs/benchmarks.md), each measured in one run, beside its goal.

Usage: python benchmarks/bench_fast.py [--quick] [--only 1,2,...] [--train-set TABLE.KEY=VALUE]

1. the paper's suite (`ata eval examples/paper_suite.toml -w 2`) with an empty ITA-MILP cache,
   wall time (--quick: 50 scenarios per cell, one `ata eval` unit of 50 each, extrapolated
   tenfold to the 500 of the suite: an upper bound, the suite's units being of 250);
2. ATA-HRL's CPU time per scenario over greedy's, whole process (`ata run` in a fresh process),
   settings (a) and (b) and the custom teams 9/12/90 and 20/28/250 at high uncertainty, and the
   growth of ATA-HRL's time with the POIs between the last two (goals 1 and 2 of figure 2;
   bench_scaling; --quick: half the scenarios);
3. greedy with on-event reallocation, batch 500 over batch 1 throughput, (a) and (b), each side
   the best of 2 (--quick) or 3 runs made in alternation;
4. ATA-HRL's (a) training recipe (ata/missions/train_ata_hrl.toml): a few steps of each part
   timed, extrapolated to the recipe's step counts;
5. peak memory of setting (b) at batch 500 (greedy), and its growth with the number of POIs;
6. the gym vector env against single envs, setting (a), each side the least time of 2
   (--quick) or 3 runs made in alternation.

Each figure has one implementation, in the benchmark it belongs to (bench_suite, bench_scaling,
bench_kernel, bench_training, bench_memory, bench_gym); this driver calls them. Figures are
ratios or sizes within one run: the machine is shared and noisy, so compare ratios, and run
twice. What is measured and what is extrapolated is printed with each figure.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

import bench_gym  # noqa: E402
import bench_kernel  # noqa: E402
import bench_memory  # noqa: E402
import bench_scaling  # noqa: E402
import bench_suite  # noqa: E402
import bench_training  # noqa: E402
from ata.experiment.evaluate import DEFAULT_CHUNK  # noqa: E402

# the quick suite runs 50 scenarios a cell, one unit of 50 per cell. Each unit pays a fixed
# time beside its scenarios' (the learned methods' decoder steps), which the full suite, in
# units of 250 (`ata eval`'s default), pays a fifth as often: the tenfold extrapolation is an
# upper bound (at 20 a cell it came out several times too high)
QUICK = {"suite": 50, "single": 10,
         "recipe": (10, 3, 1), "pois": [130, 260, 520], "poi_batch": 5, "gym_rounds": 2,
         "least_of": 2}
FULL = {"suite": 500, "single": 20,
        "recipe": (50, 4, 2), "pois": [130, 260, 520, 1040], "poi_batch": 10, "gym_rounds": 5,
        "least_of": 3}
SUMMARY: list[str] = []


def say(line: str, summary: bool = False) -> None:
    print(line, flush=True)
    if summary:
        SUMMARY.append(line)


def figure_suite(cfg: dict) -> None:
    n = cfg["suite"]
    wall, per = bench_suite.run_suite(n, workers=2)
    scale = bench_suite.SUITE_SCENARIOS / n
    total = sum(per.values())
    say(f"[1] paper suite, {n} scenarios per cell, -w 2, empty MILP cache: {wall:.0f} s "
        f"elapsed (chunk seconds summed over workers: {total:.0f})")
    by_method: dict[str, float] = {}
    for (m, _), v in per.items():
        by_method[m] = by_method.get(m, 0.0) + v
    for m, v in sorted(by_method.items(), key=lambda kv: -kv[1]):
        say(f"      {m}: {v:.0f} s ({100 * v / total:.0f}%)")
    what = "measured" if scale == 1 else f"extrapolated linearly x{scale:g} from {n} per cell"
    if scale != 1 and n < DEFAULT_CHUNK:
        what += f" in units of {n}; an upper bound, the suite's units being of {DEFAULT_CHUNK}"
    say(f"(1) paper suite -w 2, cold MILP cache: {wall * scale / 60:.1f} min ({what}) "
        "(goal < 10 min)", summary=True)


def figure_per_scenario(cfg: dict) -> None:
    """Figure (2), goals 1 and 2: ATA-HRL's time per scenario over greedy's, whole process,
    in (a), (b) and at 20/28/250, and its growth with the POIs (bench_scaling)."""
    rows = bench_scaling.measure(["a", "b", "90", "250"], cfg["least_of"] < 3, 1, say=say)
    for key in ("a", "b"):
        say(f"(2) goal 1: ATA-HRL per scenario vs greedy, whole process, "
            f"{rows[key]['label']}: {rows[key]['ratio']:.1f}x (goal <= 2x)", summary=True)
    say(f"(2) goal 2: ATA-HRL per scenario vs greedy, whole process, {rows['250']['label']}: "
        f"{rows['250']['ratio']:.1f}x (goal <= 4x)", summary=True)
    say(f"(2) goal 2: ATA-HRL's time per scenario grows as POIs^"
        f"{bench_scaling.growth(rows, 'ATA-HRL'):.2f} from 90 to 250 POIs (greedy's: POIs^"
        f"{bench_scaling.growth(rows, 'greedy'):.2f}) (goal: at most POIs^1.5)", summary=True)


def figure_batch_and_memory(cfg: dict, do_batch: bool, do_memory: bool) -> None:
    """Figures 3 and 5 share the (b) batch-500 run: made in a child process, it gives both its
    throughput and its peak memory."""
    n = cfg["least_of"] if do_batch else 1
    for setting in ("a", "b") if do_batch else ("b",):
        # batch 500 and batch 1 in alternation, n times; each keeps its best rates (a run on a
        # shared machine is only ever slowed by other work) and the highest memory peak
        bigs, singles = [], []
        for _ in range(n):
            bigs.append(bench_memory.isolated(setting, bench_memory.GREEDY_REALLOC, 500, 500))
            if do_batch:
                singles.append(bench_kernel.measure(setting, bench_memory.GREEDY_REALLOC,
                                                    cfg["single"], 1))
        big = {k: max(r[k] for r in bigs) for k in ("rate", "cpu_rate", "rss_peak_mib",
                                                      "rss_base_mib")}
        big["wall_s"] = min(r["wall_s"] for r in bigs)
        if do_batch:
            rate, cpu_rate = max(r.rate for r in singles), max(r.cpu_rate for r in singles)
            say(f"[3] ({setting}) greedy + on_event realloc, best of {n} alternating runs: "
                f"batch 1 {rate:,.0f} scenario-epochs/s, {cpu_rate:,.0f} per CPU second "
                f"({cfg['single']} scenarios), batch 500 {big['rate']:,.0f}, "
                f"{big['cpu_rate']:,.0f} per CPU second ({big['wall_s']:.1f} s for 500, in a "
                f"fresh process)")
            say(f"(3) greedy batch 500 vs 1 ({setting}): {big['rate'] / rate:.1f}x "
                f"(in CPU time {big['cpu_rate'] / cpu_rate:.1f}x) (goal >= 30x)",
                summary=True)
        if do_memory and setting == "b":
            say(f"(5) peak memory, (b) greedy at batch 500: {big['rss_peak_mib'] / 1024:.2f} "
                f"GiB resident ({big['rss_base_mib']:.0f} MiB before the run) (goal < 2 GiB)",
                summary=True)
    if do_memory:
        rows = bench_memory.poi_growth(cfg["pois"], cfg["poi_batch"])
        for r in rows:
            say(f"[5] team (a) with {r['pois']} POIs, greedy + realloc, batch "
                f"{cfg['poi_batch']}: traced peak {r['traced_peak_mib']:.1f} MiB"
                f"{bench_memory.describe(r)}")
        law = ", ".join(f"{r['exponent']:.2f}" for r in rows if "exponent" in r) or "none"
        say(f"(5) peak memory growth exponent in POIs, from its slopes: {law} (goal: 1, "
            "linear; 2 is quadratic)", summary=True)


def figure_recipe(cfg: dict) -> None:
    aux, ita, ctr = cfg["recipe"]
    rows = bench_training.recipe_estimate(aux, ita, ctr, cfg.get("train_set", []))
    for part, sec, n, m, est in rows:
        say(f"[4] {part}: {sec:.1f} s for {n} measured -> {est:.0f} s for the recipe's {m}")
    total = sum(r[4] for r in rows)
    changed = f", with {' '.join(cfg['train_set'])}" if cfg.get("train_set") else ""
    say(f"(4) ATA-HRL (a) training recipe{changed}: {total / 60:.1f} min (extrapolated from "
        f"{aux} aux, {ita} ITA, {ctr} CTR steps and their validations) (goal < 15 min)",
        summary=True)


def figure_gym(cfg: dict) -> None:
    r = bench_gym.vector_vs_single(bench_gym.TEAMS["(a) (H/R/P 6/8/60, T 30)"], 64,
                                   cfg["gym_rounds"], 0, repeats=cfg["least_of"])
    say(f"[6] (a), 64 envs, {cfg['gym_rounds']} episode(s) each, least of {cfg['least_of']} "
        f"alternating runs: single {r['single']:.1f} "
        f"episodes/s ({r['wall_single']:.1f} s, {r['cpu_single']:.1f} CPU s), vector "
        f"{r['vector']:.1f} ({r['wall_vector']:.1f} s, {r['cpu_vector']:.1f} CPU s)")
    say(f"(6) gym vector env vs 64 single envs (a): {r['ratio']:.1f}x (in CPU time "
        f"{r['cpu_ratio']:.1f}x) (goal >= 30x)", summary=True)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true",
                        help="the short version (a few minutes; the suite extrapolated)")
    parser.add_argument("--only", default="1,2,3,4,5,6", help="figures to measure")
    parser.add_argument("--train-set", action="append", default=[], metavar="TABLE.KEY=VALUE",
                        help="figure 4: change a setting of the recipe, as ata train's --set "
                        "(ata_hrl.device=cuda: the updates on a GPU)")
    args = parser.parse_args()
    cfg = {**(QUICK if args.quick else FULL), "train_set": args.train_set}
    only = {int(x) for x in args.only.split(",")}
    commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True,
                            text=True, cwd=HERE).stdout.strip()
    say(f"bench_fast {'--quick' if args.quick else '(full)'}, commit {commit}, "
        f"{time.strftime('%Y-%m-%d %H:%M')}")
    t0 = time.perf_counter()
    # the cheap figures first, the suite last: a partial run still says most
    if 3 in only or 5 in only:
        figure_batch_and_memory(cfg, 3 in only, 5 in only)
    if 2 in only:
        figure_per_scenario(cfg)
    if 6 in only:
        figure_gym(cfg)
    if 4 in only:
        figure_recipe(cfg)
    if 1 in only:
        figure_suite(cfg)
    print(f"\nsummary ({time.perf_counter() - t0:.0f} s in all):")
    for line in sorted(SUMMARY):
        print("  " + line)


if __name__ == "__main__":
    main()
