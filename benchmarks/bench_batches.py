"""What `ata run`'s batch size costs: CPU seconds of the same scenarios in one batch and in
batches of `--chunk-size` N (each saved as it ends), for greedy and the default mission (ATA-HRL).

Usage: python benchmarks/bench_batches.py [--scenarios 200] [--sizes 200,100,50] [--repeats 2]

The rows are the same whatever the batches (tests/test_eval.py); only the time differs. Times
are CPU seconds of this process (one torch thread, as `ata run` runs a unit), the least of the
repeats, which a shared machine disturbs less than wall time; the ratio is against the first
size. The fixed cost of a batch (the kernel steps a batch's scenarios together, so each epoch's
hook calls are paid once per batch) is fitted from the times: t = per batch + n x per scenario.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from ata.session import BASELINE_MISSION, BUILTIN_MISSION, load_session
from ata.experiment.runner import run_mission
from ata.experiment.units import fixed_chunks, scenario_ids

MISSIONS = {"greedy": BASELINE_MISSION, "ATA-HRL (default mission)": BUILTIN_MISSION}


def least_cpu_seconds(session, chunks: list[np.ndarray], repeats: int) -> float:
    """The least, over `repeats`, of the CPU seconds of this process running `chunks` (after
    one warm-up batch of 5 scenarios: weights loaded, first calls paid)."""
    run_mission(session, chunks=fixed_chunks(chunks[0][:5], 5))
    best = np.inf
    for _ in range(repeats):
        t0 = time.process_time()
        run_mission(session, chunks=chunks)
        best = min(best, time.process_time() - t0)
    return float(best)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenarios", type=int, default=200)
    parser.add_argument("--sizes", default="200,100,50")
    parser.add_argument("--repeats", type=int, default=2)
    args = parser.parse_args()
    sizes = [int(x) for x in args.sizes.split(",")]
    print(f"{args.scenarios} scenarios, CPU seconds (least of {args.repeats}); ratio to "
          f"batches of {sizes[0]}")
    for name, path in MISSIONS.items():
        session = load_session(str(path), [f"mission.scenarios={args.scenarios}"])
        ids = scenario_ids(session.mission)
        best = {size: least_cpu_seconds(session, fixed_chunks(ids, size), args.repeats)
                for size in sizes}
        batches = [-(-args.scenarios // s) for s in sizes]
        # t = batches x (fixed cost of a batch) + (the scenarios' own time)
        per_batch, own = np.polyfit(batches, [best[s] for s in sizes], 1) \
            if len(set(batches)) > 1 else (float("nan"), float("nan"))
        for size, n in zip(sizes, batches):
            print(f"  {name}: {n} batch(es) of <= {size}: {best[size]:.2f} s "
                  f"(x{best[size] / best[sizes[0]]:.2f})")
        print(f"  {name}: fitted: {per_batch:.2f} s per batch, {own:.2f} s for the "
              "scenarios themselves")


if __name__ == "__main__":
    main()
