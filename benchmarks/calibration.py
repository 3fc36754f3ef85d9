"""The calibration check of docs/calibration.md: do the defaults leave each phenomenon visible?

Usage: python benchmarks/calibration.py [--scenarios 500] [--seed 0]

Runs setting (a) at medium uncertainty with the greedy allocation (and, for contrast, the random
one) and prints: the share of POIs classified by the horizon, the share of human classifications
made with F_f below 0.95, the shares made on each slope of the F_w curve (u < 0.45, u >= 0.65),
and the robot failure and attribute change rates against the level's p.
"""

from __future__ import annotations

import argparse

from rich.console import Console
from rich.table import Table

from ata.session import BASELINE_MISSION
from ata.session import load_session
from ata.experiment.runner import run_mission

METHODS = {
    "greedy (ITA only)": ["components.initial='greedy'", "components.condition='never'"],
    "greedy + on_event realloc": ["components.initial='greedy'",
                                  "components.condition='on_event'",
                                  "components.reallocation='greedy'"],
    "random (ITA only)": ["components.initial='random'", "components.condition='never'"],
}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenarios", type=int, default=500)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    table = Table(title=f"calibration, setting (a), medium uncertainty, {args.scenarios} "
                        f"scenarios, seed {args.seed}")
    for col in ("method", "POIs classified", "classified with F_f < 0.95",
                "on the rising F_w slope (u < 0.45)", "on the falling slope (u >= 0.65)",
                "robot failure rate (p = 0.2)", "attribute change rate (p = 0.2)", "score"):
        table.add_column(col, justify="right" if col != "method" else "left")
    for name, extra in METHODS.items():
        session = load_session(str(BASELINE_MISSION), [f"mission.scenarios={args.scenarios}",
                                      f"mission.seed={args.seed}", "mission.setting='a'",
                                      "mission.uncertainty='medium'", *extra])
        m = session.mission
        res = run_mission(session)
        met = res.metrics
        n_cls = met["human_classifications"]
        weight = n_cls / n_cls.sum()   # pool the human classifications of all scenarios
        table.add_row(
            name,
            f"{100 * met['classified_share'].mean():.1f}% "
            f"(min {100 * met['classified_share'].min():.0f}%)",
            f"{100 * (weight * met['fatigued_share']).sum():.1f}%",
            f"{100 * (weight * met['underloaded_share']).sum():.1f}%",
            f"{100 * (weight * met['overloaded_share']).sum():.1f}%",
            f"{met['robot_failures'].mean() / m.sizes.robots:.3f}",
            f"{met['attribute_changes'].mean() / m.sizes.tasks:.3f}",
            f"{res.total.mean():.1f}")
    Console(width=200).print(table)


if __name__ == "__main__":
    main()
