"""Peak memory of a greedy run: setting (b) at batch 500, and how it grows with the number of POIs.

Usage: python benchmarks/bench_memory.py [--pois 130,260,520] [--batch 20]

Each run is made in a fresh child process, so that its peak is its own:

- the resident set (``resource.getrusage(RUSAGE_SELF).ru_maxrss``): what the system sees, the
  interpreter and its imports (numpy, torch where loaded) included; the child also reports its
  resident set before the run, so the run's own share is the difference;
- with ``traced=True``, the peak of ``tracemalloc`` (Python and numpy allocations only, from the
  run's start): exact and free of the allocator's noise, but it slows the run, so a traced run is
  not timed.

The growth law reads the slope of the traced peak between neighbouring sizes, in KiB per
scenario and added POI: it stays the same from size to size where the peak grows linearly, and
doubles with the POIs where it grows quadratically (greedy's old (batch, POIs, POIs) distance
arrays). The exponent between two slopes is 1 + log(slope ratio) / log(ratio of the intervals'
midpoints): 1 linear, 2 quadratic. The peak's growth over its value at a few POIs would read
less: at small sizes the peak is set by what does not grow with the POIs (the scenario setup,
the records of the other groups), so that growth reads 0 there.
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
    from ata.session import load_session   # noqa: F401  (imports before the base)
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
    """Traced peak memory of greedy (with reallocation) on the (a) team with `pois` POIs (in
    increasing order), one batch of `batch` scenarios each, read by `growth_law`."""
    rows = []
    for p in pois:
        r = isolated("a", [f"mission.tasks={p}", *GREEDY_REALLOC], batch, batch, traced=True)
        rows.append({**r, "pois": p})
    return growth_law(rows, batch)


def growth_law(rows: list[dict], batch: int) -> list[dict]:
    """`rows` (``pois`` increasing, ``traced_peak_mib``) with, from the second on, the slope from
    the row before (``slope_kib``, KiB per scenario and added POI) and from the third on the
    exponent of the peak's growth between the two slopes (module doc)."""
    out: list[dict] = []
    for r in rows:
        r = dict(r)
        if out:
            prev = out[-1]
            r["slope_kib"] = (r["traced_peak_mib"] - prev["traced_peak_mib"]) * 1024 \
                / (r["pois"] - prev["pois"]) / batch
            r["mid"] = math.sqrt(r["pois"] * prev["pois"])
            if prev.get("slope_kib", 0) > 0 and r["slope_kib"] > 0:
                r["exponent"] = 1 + math.log(r["slope_kib"] / prev["slope_kib"]) \
                    / math.log(r["mid"] / prev["mid"])
        out.append(r)
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--pois", default="130,260,520", help="POI counts, increasing")
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
          "peak; its slope from the size before, and the growth exponent between slopes):")
    for r in poi_growth([int(x) for x in args.pois.split(",")], args.batch):
        print(f"  {r['pois']:>5} POIs: {r['traced_peak_mib']:8.1f} MiB traced, peak RSS "
              f"{r['rss_peak_mib']:.0f} MiB{describe(r)}")


def describe(row: dict) -> str:
    """A `poi_growth` row's slope and exponent, as printed after its peak ('' for the first)."""
    out = f", slope {row['slope_kib']:.2f} KiB per scenario and POI" if "slope_kib" in row else ""
    return out + (f", exponent {row['exponent']:.2f}" if "exponent" in row else "")


if __name__ == "__main__":
    main()
