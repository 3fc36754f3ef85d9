"""Time per scenario against team size, for greedy and ATA-HRL: the cost of a bigger team.

Usage: python benchmarks/bench_scaling.py [--quick] [--teams a,b,90,250] [--repeats 1]

Each (method, team) is one `ata run` in a fresh process, one worker, timed as the CPU seconds
of that process (start-up, torch's import and the weights' loading included: the whole
process, as a user pays it), divided by its scenarios. The teams: setting (a) 6/8/60 and (b)
12/16/130 at medium uncertainty, and custom teams 9/12/90 and 20/28/250 at high uncertainty.
ATA-HRL is the default mission (its (a) weights) on (a) and the custom teams, and
examples/missions/ata_hrl_b.toml (the (b) weights) on (b); greedy is ata/missions/greedy.toml
(on-event reallocation) on the same team. The growth exponent is that of ATA-HRL's time per
scenario in the POIs between the two custom teams: log(t_250 / t_90) / log(250 / 90). With
`--repeats` above 1 each figure is the least of its runs, made in alternation. The machine is
shared and noisy: compare the ratios within one run, and run it twice.
"""

from __future__ import annotations

import argparse
import math
import os
import resource
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
ATA_HRL = {"a": "ata/missions/default.toml", "b": "examples/missions/ata_hrl_b.toml"}
GREEDY = "ata/missions/greedy.toml"
TEAMS = {
    "a": ("(a) 6/8/60, medium", ["mission.setting=a"], 60),
    "b": ("(b) 12/16/130, medium", ["mission.setting=b"], 130),
    "90": ("9/12/90, high", ["mission.setting=custom", "mission.humans=9", "mission.robots=12",
                             "mission.tasks=90", "mission.uncertainty=high"], 90),
    "250": ("20/28/250, high", ["mission.setting=custom", "mission.humans=20",
                                "mission.robots=28", "mission.tasks=250",
                                "mission.uncertainty=high"], 250),
}
SCENARIOS = {"a": 200, "b": 100, "90": 40, "250": 12}
"""Scenarios per run (--quick: half): enough that the run, not the start-up, dominates."""


def run_cpu_seconds(mission: str, sets: list[str], scenarios: int) -> float:
    """CPU seconds of one `ata run` of `mission` in a fresh process (one worker)."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    with tempfile.TemporaryDirectory() as out:
        cmd = [sys.executable, "-m", "ata.cli", "run", mission, "-o", str(Path(out) / "run"),
               "-w", "1", "--set", f"mission.scenarios={scenarios}"]
        for s in sets:
            cmd += ["--set", s]
        done = subprocess.run(cmd, cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                              text=True, env={**os.environ, "PYTHONPATH": str(ROOT)})
        if done.returncode:
            raise RuntimeError(f"{' '.join(cmd)} failed:\n{done.stderr[-2000:]}")
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def measure(teams: list[str], quick: bool, repeats: int, say=print) -> dict[str, dict]:
    """Per team: seconds per scenario of greedy and ATA-HRL (the least of `repeats`), and
    their ratio."""
    rows = {}
    for key in teams:
        label, sets, pois = TEAMS[key]
        n = max(2, SCENARIOS[key] // (2 if quick else 1))
        hrl = ATA_HRL.get(key, ATA_HRL["a"])
        best = {"greedy": math.inf, "ATA-HRL": math.inf}
        for _ in range(repeats):
            best["greedy"] = min(best["greedy"], run_cpu_seconds(GREEDY, sets, n) / n)
            best["ATA-HRL"] = min(best["ATA-HRL"], run_cpu_seconds(hrl, sets, n) / n)
        rows[key] = {"label": label, "pois": pois, "scenarios": n, **best,
                     "ratio": best["ATA-HRL"] / best["greedy"]}
        say(f"[scaling] {label}: {n} scenarios, whole process, CPU s per scenario: greedy "
            f"{best['greedy']:.3f}, ATA-HRL {best['ATA-HRL']:.3f} ({rows[key]['ratio']:.2f}x)")
    return rows


def growth(rows: dict[str, dict], method: str, small: str = "90", big: str = "250") -> float:
    """The exponent of `method`'s time per scenario in the POIs between two teams."""
    a, b = rows[small], rows[big]
    return math.log(b[method] / a[method]) / math.log(b["pois"] / a["pois"])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="half the scenarios")
    parser.add_argument("--teams", default="a,b,90,250", help="of: " + ",".join(TEAMS))
    parser.add_argument("--repeats", type=int, default=1)
    args = parser.parse_args()
    rows = measure(args.teams.split(","), args.quick, args.repeats)
    if "90" in rows and "250" in rows:
        for method in ("greedy", "ATA-HRL"):
            print(f"[scaling] {method}: time per scenario grows as POIs^"
                  f"{growth(rows, method):.2f} between 90 and 250 POIs")


if __name__ == "__main__":
    main()
