"""Non-learned methods side by side: mean total team performance with 95% confidence intervals
at each uncertainty level, on the same scenarios.

Usage: python benchmarks/compare_baselines.py [--setting a] [--scenarios 500] [--seed 0]
                                              [--methods milp,greedy,greedy_realloc,random]
                                              [--workers 2] [--csv out.csv]
"""

from __future__ import annotations

import argparse
import csv

import numpy as np

from rich.console import Console
from rich.table import Table

from ata.session import BASELINE_MISSION
from ata.session import load_session
from ata.experiment.runner import mean_ci, run_mission

METHODS = {
    "random": ["components.initial='random'", "components.condition='never'",
               "components.reallocation='random'"],
    "greedy": ["components.initial='greedy'", "components.condition='never'",
               "components.reallocation='greedy'"],
    "greedy_realloc": ["components.initial='greedy'", "components.condition='on_event'",
                       "components.reallocation='greedy'"],
    "milp": ["components.initial='milp'", "components.condition='never'",
             "components.reallocation='keep'"],
}
LEVELS = ("low", "medium", "high")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--setting", default="a")
    parser.add_argument("--scenarios", type=int, default=500)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--methods", default="milp,greedy,greedy_realloc,random")
    parser.add_argument("--workers", type=int, default=2, help="MILP solver processes")
    parser.add_argument("--csv", default=None, help="also write the table here")
    args = parser.parse_args()
    methods = args.methods.split(",")
    table = Table(title=f"setting ({args.setting}), {args.scenarios} scenarios, seed {args.seed}:"
                        " mean total team performance (95% CI)")
    table.add_column("method")
    for level in LEVELS:
        table.add_column(level, justify="right")
    rows = []
    for method in methods:
        cells = []
        for level in LEVELS:
            session = load_session(str(BASELINE_MISSION), [f"mission.setting='{args.setting}'",
                                          f"mission.scenarios={args.scenarios}",
                                          f"mission.seed={args.seed}",
                                          f"mission.uncertainty='{level}'",
                                          f"milp.workers={args.workers}", *METHODS[method]]
                                   if method == "milp" else
                                   [f"mission.setting='{args.setting}'",
                                    f"mission.scenarios={args.scenarios}",
                                    f"mission.seed={args.seed}",
                                    f"mission.uncertainty='{level}'", *METHODS[method]])
            result = run_mission(session)
            mean, half = mean_ci(result.total)
            frac = float((result.total / result.upper_bound).mean())
            cells.append(f"{mean:.1f} ± {half:.1f} ({frac:.3f} U)")
            rows.append({"method": method, "level": level, "mean": mean, "ci95": half,
                         "fraction_of_u": frac, "wall_s": result.wall_s,
                         "fallbacks": float(np.sum(result.metrics.get("milp_fallback", 0.0)))})
            print(f"{method} {level}: {cells[-1]}  [{result.wall_s:.0f} s]", flush=True)
        table.add_row(method, *cells)
    Console(width=160).print(table)
    if args.csv:
        with open(args.csv, "w", newline="") as f:
            writer = csv.DictWriter(f, fieldnames=list(rows[0]))
            writer.writeheader()
            writer.writerows(rows)


if __name__ == "__main__":
    main()
