"""The overhead of `--isolate`: greedy at batch 100 in setting (a), isolated against in-process.

Usage: python benchmarks/bench_isolate.py [--scenarios 200] [--repeats 5] [--timings]

Runs the command a user runs, ``ata run builtin:greedy --set mission.batch_size=100 --set
mission.scenarios=200 -q --out DIR``, alternately without and with ``--isolate``, `--repeats`
times each, each in a fresh process (so each pays its imports, and the isolated one its
sandboxed decision process, as a user does), and prints the ratio isolated / in-process of
each pair with their min and median. A ratio, in one run: this machine is shared and noisy.
`--timings` then runs the same plan isolated in this process and prints where an isolated
batch's extra time goes: each decision call's time less the time its components took in the
decision process (the round trips by phase, and the wait for the process's start).
"""

from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import tempfile
import time
from collections import defaultdict
from pathlib import Path

from ata.isolation import process as isolate
from ata.isolation import require_sandbox
from ata.session import IN_PROCESS, load_session
from ata.experiment.runner import build_once
from ata.experiment.units import fixed_chunks, make_units, run_units, scenario_ids
from ata.runtime.executors import SerialExecutor


def timed(overrides: list[str], isolated: bool) -> float:
    """Wall seconds of one run of the mission, as `ata run` makes it: (with
    `--isolate`, the sandbox checked and a decision process started), the mission loaded, its
    components built once, the batches run."""
    t0 = time.perf_counter()
    backend = require_sandbox(60) if isolated else IN_PROCESS
    session = load_session("builtin:greedy", overrides, backend=backend)
    m = session.mission
    build_once(session)          # when isolated, its process is reused by the batches
    units = make_units([m], [fixed_chunks(scenario_ids(m), 100)], executor=SerialExecutor(),
                       registries=[session.registry], backends=[backend])
    run_units(units, SerialExecutor())
    isolate.close_idle()             # as `ata run` does at its end: each run starts its own
    return time.perf_counter() - t0


def spent_in_calls() -> dict[str, list[float]]:
    """Wrap `DecisionProcess.call` to record, by request, each call's seconds less the seconds
    the components took in the decision process (its ``busy_s``): the channel's and the
    start's share (the first call of a batch also waits for the process to be ready)."""
    spent: dict[str, list[float]] = defaultdict(list)
    call = isolate.DecisionProcess.call

    def recorded(self, req, limit, what):
        t0 = time.perf_counter()
        start = not self.ready
        header, arrays = call(self, req, limit, what)
        spent[("start + " if start else "") + req["op"]].append(
            time.perf_counter() - t0 - float(header.get("busy_s", 0.0)))
        return header, arrays

    isolate.DecisionProcess.call = recorded
    return spent


def command_time(scenarios: int, isolated: bool, out: Path) -> float:
    """Wall seconds of one `ata run` in a fresh process."""
    argv = [str(Path(sys.executable).with_name("ata")), "run", "builtin:greedy", "--set",
            "mission.batch_size=100", "--set", f"mission.scenarios={scenarios}", "-q",
            "--out", str(out), *(["--isolate"] if isolated else [])]
    t0 = time.perf_counter()
    subprocess.run(argv, check=True, stdout=subprocess.DEVNULL)
    return time.perf_counter() - t0


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenarios", type=int, default=200)
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--timings", action="store_true")
    args = parser.parse_args()
    reason = isolate.sandbox.unavailable()
    if reason:
        sys.exit(f"bench_isolate: {reason}")
    ratios, plain, apart = [], [], []
    with tempfile.TemporaryDirectory() as tmp:
        command_time(args.scenarios, False, Path(tmp) / "warm")    # the page cache
        for i in range(args.repeats):       # a new folder each: nothing to resume
            a = command_time(args.scenarios, False, Path(tmp) / f"plain{i}")
            b = command_time(args.scenarios, True, Path(tmp) / f"isolated{i}")
            plain.append(a)
            apart.append(b)
            ratios.append(b / a)
            print(f"ata run {a:6.2f} s   ata run --isolate {b:6.2f} s   ratio {b / a:.3f}",
                  flush=True)
    med = statistics.median
    print(f"greedy, setting (a), batch 100, {args.scenarios} scenarios, {args.repeats} pairs: "
          f"isolated / in-process min {min(ratios):.3f}, median {med(ratios):.3f} "
          f"(ata run median {med(plain):.2f} s, with --isolate {med(apart):.2f} s)")
    if not args.timings:
        return
    spent = spent_in_calls()
    overrides = [f"mission.scenarios={args.scenarios}", "mission.batch_size=100"]
    timed(overrides, False)                  # warm: this process's imports
    wall, in_process = timed(overrides, True), timed(overrides, False)
    batches = -(-args.scenarios // 100)
    print(f"in this process: isolated {wall:.2f} s, in-process {in_process:.2f} s; per "
          "isolated batch, seconds of the channel and the start (a call's time less its "
          "components' own):")
    for op, values in sorted(spent.items()):
        print(f"  {op:24s} {sum(values) / batches:7.3f}  ({len(values) // batches} calls)")
    total = sum(sum(v) for v in spent.values()) / batches
    per_batch = in_process / batches
    print(f"  {'total':24s} {total:7.3f}  = {100 * total / per_batch:.1f}% of an in-process "
          f"batch ({per_batch:.2f} s)")


if __name__ == "__main__":
    main()
