"""ATA-HRL (shipped weights) against its ablations and the non-learned methods, on held-out
scenarios: mean total team performance with 95% CIs, and paired differences to the full method.

Usage: python benchmarks/eval_ata_hrl.py [--scenarios 500] [--seed 0] [--uncertainty medium]
                                         [--skip-milp]

Seed 0 is held out: training uses root seed 12345 and its held-out checks 12345 + 1000003.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from rich.console import Console
from rich.table import Table

from ata.session import BASELINE_MISSION, load_session
from ata.experiment.runner import mean_ci, run_mission

EXAMPLES = Path(__file__).resolve().parent.parent / "examples" / "missions"
METHODS = {
    "ATA-HRL": (EXAMPLES / "ata_hrl_a.toml", []),
    "w/o.AUX": (EXAMPLES / "ata_hrl_wo_aux_a.toml", []),
    "w/o.C": (EXAMPLES / "ata_hrl_wo_c_a.toml", []),
    "greedy + on_event": (None, ["components.initial='greedy'",
                                 "components.condition='on_event'",
                                 "components.reallocation='greedy'"]),
    "ITA-MILP": (None, ["components.initial='milp'", "components.condition='never'",
                        "components.reallocation='keep'", "milp.workers=2"]),
}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenarios", type=int, default=500)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--uncertainty", default="medium")
    parser.add_argument("--skip-milp", action="store_true")
    args = parser.parse_args()
    totals, fracs, walls = {}, {}, {}
    for name, (path, extra) in METHODS.items():
        if args.skip_milp and name == "ITA-MILP":
            continue
        session = load_session(str(path) if path else str(BASELINE_MISSION),
                               [f"mission.scenarios={args.scenarios}", f"mission.seed={args.seed}",
                                "mission.setting='a'", f"mission.uncertainty='{args.uncertainty}'",
                                "mission.batch_size=500", *extra])
        result = run_mission(session)
        totals[name] = result.total
        fracs[name] = float((result.total / result.upper_bound).mean())
        walls[name] = result.wall_s
        print(f"{name}: {result.total.mean():.1f}  [{result.wall_s:.0f} s]", flush=True)
    table = Table(title=f"setting (a), {args.uncertainty} uncertainty, {args.scenarios} held-out "
                        f"scenarios (seed {args.seed})")
    for col in ("method", "mean total (95% CI)", "fraction of U", "full method minus this "
                "(paired, 95% CI)", "wall time"):
        table.add_column(col, justify="right" if col != "method" else "left")
    full = totals.get("ATA-HRL")
    for name, total in totals.items():
        mean, half = mean_ci(total)
        diff = ""
        if full is not None and name != "ATA-HRL":
            d_mean, d_half = mean_ci(full - total)
            diff = f"{d_mean:+.1f} ± {d_half:.1f}"
        table.add_row(name, f"{mean:.1f} ± {half:.1f}", f"{fracs[name]:.3f}", diff,
                      f"{walls[name]:.0f} s")
    Console(width=160).print(table)


if __name__ == "__main__":
    main()
