"""Simulator throughput: scenario-epochs per second at batch size 1 and 500, settings (a) and (b).

Usage: python benchmarks/bench_kernel.py [--single 20] [--batch 500]

Prints, for each setting and each greedy configuration (greedy initial allocation alone, and
with event-triggered greedy reallocation, ata/missions/greedy.toml), the throughput at batch size 1
(over `--single` scenarios run one at a time) and at batch size `--batch` (one batch), their
ratio, and the wall time of the whole batch. Ratios are taken within one run: this machine is
shared and noisy, so compare ratios, not absolute times across runs.
"""

from __future__ import annotations

import argparse
import time
from typing import NamedTuple

from rich.console import Console
from rich.table import Table

from ata.session import BASELINE_MISSION
from ata.session import load_session
from ata.experiment.runner import run_mission

CONFIGS = {
    "greedy ITA only": ["components.condition='never'"],
    "greedy + on_event realloc": [],
}


class Throughput(NamedTuple):
    """One run's wall seconds and scenario-epochs per second, and the same per CPU second of
    this process (steadier on a shared machine, where waiting for a core inflates wall time)."""

    wall_s: float
    rate: float
    cpu_s: float
    cpu_rate: float


def measure(setting: str, extra: list[str], scenarios: int, batch: int) -> Throughput:
    """The throughput of one run."""
    session = load_session(str(BASELINE_MISSION), [f"mission.setting='{setting}'", f"mission.scenarios={scenarios}",
                                  f"mission.batch_size={batch}", "mission.workers=1", *extra])
    t0, c0 = time.perf_counter(), time.process_time()
    run_mission(session)
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    epochs = scenarios * session.mission.clock.n_epochs
    return Throughput(wall, epochs / wall, cpu, epochs / cpu)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--single", type=int, default=20, help="scenarios run at batch size 1")
    parser.add_argument("--batch", type=int, default=500, help="the large batch size")
    args = parser.parse_args()
    table = Table(title="ata kernel throughput (scenario-epochs per second)")
    for col in ("setting", "configuration", "batch 1", f"batch {args.batch}", "ratio",
                f"wall time, {args.batch} scenarios"):
        table.add_column(col, justify="right" if col != "configuration" else "left")
    for setting in ("a", "b"):
        for name, extra in CONFIGS.items():
            single = measure(setting, extra, args.single, 1).rate
            wall, batched, _, _ = measure(setting, extra, args.batch, args.batch)
            table.add_row(setting, name, f"{single:,.0f}", f"{batched:,.0f}",
                          f"{batched / single:.1f}x", f"{wall:.2f} s")
    Console().print(table)


if __name__ == "__main__":
    main()
