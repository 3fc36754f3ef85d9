"""What the classical filter costs greedy: CPU seconds of greedy reading the `filter`'s estimate
of S (the suite's `greedy + filter`) against greedy reading the raw observation (`greedy`), on
the same scenarios, in `ata run`'s batches.

Usage: python benchmarks/bench_filter.py [--scenarios 100] [--level high] [--settings a,b]
                                         [--repeats 3]

Times are CPU seconds of this process, the least of the repeats (`bench_batches`), which a
shared machine disturbs less than wall time; the ratio is the filter's cost per scenario over
greedy's. The filter hands the planners a belief over 225 fatigue curves a human, which they read
at every step of a plan: that reading is what the ratio measures beyond the filter's own update.
"""

from __future__ import annotations

import argparse

from bench_batches import least_cpu_seconds
from ata.session import BASELINE_MISSION, load_session
from ata.experiment.units import RUN_CHUNK, fixed_chunks, scenario_ids

FILTER = ["components.reconstructors=['filter']"]


def filter_over_greedy(setting: str, level: str, scenarios: int, repeats: int
                       ) -> dict[str, float]:
    """CPU seconds of greedy and of greedy + filter on `scenarios` scenarios, and their ratio."""
    base = [f"mission.setting='{setting}'", f"mission.scenarios={scenarios}",
            f"mission.uncertainty='{level}'"]
    cpu = {}
    for name, extra in (("greedy", []), ("greedy + filter", FILTER)):
        session = load_session(str(BASELINE_MISSION), base + extra)
        chunks = fixed_chunks(scenario_ids(session.mission), RUN_CHUNK)
        cpu[name] = least_cpu_seconds(session, chunks, repeats)
    return {**cpu, "ratio": cpu["greedy + filter"] / cpu["greedy"]}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenarios", type=int, default=100)
    parser.add_argument("--level", default="high")
    parser.add_argument("--settings", default="a,b")
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    print(f"{args.scenarios} scenarios at {args.level}, CPU seconds (least of {args.repeats})")
    for setting in args.settings.split(","):
        r = filter_over_greedy(setting, args.level, args.scenarios, args.repeats)
        print(f"  ({setting}) greedy {r['greedy']:.2f} s, greedy + filter "
              f"{r['greedy + filter']:.2f} s: {r['ratio']:.2f}x")


if __name__ == "__main__":
    main()
