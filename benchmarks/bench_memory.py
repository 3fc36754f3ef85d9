"""Peak memory of a greedy run: setting (b) at batch 500, and how it grows with the number of POIs.

Usage: python benchmarks/bench_memory.py [--pois 60,130,260,520] [--batch 20]

Each run is made in a fresh child process, so that its peak is its own:

- the resident set (``resource.getrusage(RUSAGE_SELF).ru_maxrss``): what the system sees, the
  interpreter and its imports (numpy, torch where loaded) included; the child also reports its
  resident set before the run, so the run's own share is the difference;
- with ``traced=True``, the peak of ``tracemalloc`` (Python and numpy allocations only, from the
  run's start): exact and free of the allocator's noise, but it slows the run, so a traced run is
  not timed.

The growth law is the slope of log(peak - floor) against log(POIs) between neighbouring sizes,
where the floor is the traced peak of the same run with 10 POIs (what does not grow with the
POIs: the scenario setup, the records of the other groups): 1 is linear, 2 quadratic (greedy's
(batch, POIs, POIs) distance arrays).
"""

from __future__ import annotations

import argparse
import json
import math
import resource
import subprocess
import sys
import time
import tracemalloc
from pathlib import Path

HERE = Path(__file__).resolve().parent
GREEDY_REALLOC: list[str] = []
"""The greedy reference mission as it is: greedy initial allocation, on-event greedy
reallocation (bench_kernel's "greedy + on_event realloc")."""


def _rss_mib() -> float:
    # ru_maxrss is in KiB on Linux
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def _child(spec: dict) -> dict:
    """Run one greedy mission here (the child), as bench_kernel.measure does."""
    sys.path.insert(0, str(HERE))
    from bench_kernel import measure   # noqa: E402  (a sibling script, not a package)
    from ata.experiment.runner import load_session   # noqa: F401  (imports before the base)
    base = _rss_mib()
    if spec.get("traced"):
        tracemalloc.start()
    t0 = time.perf_counter()
    run = measure(spec["setting"], spec["extra"], spec["scenarios"], spec["batch"])
    out = {**run._asdict(), "rss_base_mib": base, "rss_peak_mib": _rss_mib(),
           "elapsed_s": time.perf_counter() - t0}
    if spec.get("traced"):
        out["traced_peak_mib"] = tracemalloc.get_traced_memory()[1] / 2**20
        tracemalloc.stop()
    return out


def isolated(setting: str, extra: list[str], scenarios: int, batch: int,
             traced: bool = False) -> dict:
    """bench_kernel.measure(setting, extra, scenarios, batch) in a fresh process: its wall and
    CPU times and throughputs (untraced), and its peak memory (module doc)."""
    spec = {"setting": setting, "extra": list(extra), "scenarios": scenarios, "batch": batch,
            "traced": traced}
    out = subprocess.run([sys.executable, str(Path(__file__).resolve()), "--child",
                          json.dumps(spec)], capture_output=True, text=True, check=False)
    if out.returncode != 0:
        raise RuntimeError(f"child run failed: {out.stderr[-2000:]}")
    return json.loads(out.stdout.strip().splitlines()[-1])


def poi_growth(pois: list[int], batch: int) -> list[dict]:
    """Traced peak memory of greedy (with reallocation) on the (a) team with `pois` POIs, one
    batch of `batch` scenarios each, its growth over the floor (the peak at 10 POIs), and the
    growth exponent from the size before."""
    rows = []
    floor = isolated("a", ["mission.tasks=10", *GREEDY_REALLOC], batch, batch,
                     traced=True)["traced_peak_mib"]
    for p in pois:
        r = isolated("a", [f"mission.tasks={p}", *GREEDY_REALLOC], batch, batch, traced=True)
        r["pois"] = p
        r["growth_mib"] = max(r["traced_peak_mib"] - floor, 1e-9)
        if rows:
            prev = rows[-1]
            r["exponent"] = math.log(r["growth_mib"] / prev["growth_mib"]) \
                / math.log(p / prev["pois"])
        rows.append(r)
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--pois", default="60,130,260,520")
    parser.add_argument("--batch", type=int, default=20, help="scenarios (one batch) per size")
    parser.add_argument("--child", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        print(json.dumps(_child(json.loads(args.child))))
        return
    b = isolated("b", GREEDY_REALLOC, 500, 500)
    print(f"setting (b), greedy + on_event realloc, batch 500: peak RSS "
          f"{b['rss_peak_mib']:.0f} MiB ({b['rss_base_mib']:.0f} MiB before the run), "
          f"{b['wall_s']:.1f} s")
    print(f"greedy + on_event realloc, team (a) with N POIs, batch {args.batch} (tracemalloc "
          "peak, growth exponent from the size before):")
    for r in poi_growth([int(x) for x in args.pois.split(",")], args.batch):
        exp = f", exponent {r['exponent']:.2f}" if "exponent" in r else ""
        print(f"  {r['pois']:>5} POIs: {r['traced_peak_mib']:8.1f} MiB traced ("
              f"{r['growth_mib']:.1f} over 10 POIs'), peak RSS "
              f"{r['rss_peak_mib']:.0f} MiB{exp}")


if __name__ == "__main__":
    main()
