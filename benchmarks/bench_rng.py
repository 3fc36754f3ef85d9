"""The world's generator measured: its cost per draw call at batch 500, its share of a greedy
run's time, and a statistical check of its output (p-values that should look uniform).

    python benchmarks/bench_rng.py            # about half a minute on 2 cores
    python benchmarks/bench_rng.py --quick
"""

from __future__ import annotations

import argparse
import collections
import time

import numpy as np
from scipy import stats

from ata.core import rng as rng_mod
from ata.core.rng import BatchRNG


def per_call(batch: int, shapes: list[tuple[int, ...]], repeats: int) -> list[tuple]:
    """(shape, draws per call, ms per call, ns per draw) of `bits` at this batch size."""
    gen = BatchRNG(0, np.arange(batch))
    out = []
    for shape in shapes:
        gen.bits("bench", 0, shape)                    # warm
        t0 = time.perf_counter()
        for k in range(repeats):
            gen.bits("bench", k, shape)
        dt = (time.perf_counter() - t0) / repeats
        n = batch * int(np.prod(shape))
        out.append((shape, n, 1e3 * dt, 1e9 * dt / n))
    return out


def share_of_a_run(scenarios: int) -> tuple[float, float, int, int]:
    """(run seconds, seconds drawing, draw calls, draws) of `ata run builtin:greedy` at one
    batch of `scenarios`."""
    from ata.session import load_session
    from ata.experiment.runner import run_mission
    spent = [0.0]
    calls = collections.Counter()
    original = rng_mod.StreamRNG.bits

    def timed(self, stream, counter, shape=()):
        t0 = time.perf_counter()
        out = original(self, stream, counter, shape)
        spent[0] += time.perf_counter() - t0
        calls["calls"] += 1
        calls["draws"] += out.size
        return out

    rng_mod.StreamRNG.bits = timed
    try:
        session = load_session("builtin:greedy", [f"mission.scenarios={scenarios}",
                                                  f"mission.batch_size={scenarios}"])
        t0 = time.perf_counter()
        run_mission(session)
        total = time.perf_counter() - t0
    finally:
        rng_mod.StreamRNG.bits = original
    return total, spent[0], calls["calls"], calls["draws"]


def statistics(n_scenarios: int, n: int) -> list[tuple[str, float]]:
    """(test, p-value) of the world's draws: each under the hypothesis of independent uniform
    bits; a sound generator gives p-values spread over (0, 1), none tiny."""
    gen = BatchRNG(12345, np.arange(n_scenarios))
    bits = gen.bits("stats", 0, (n,))
    u = gen.uniform("stats.u", 0, (n,))
    out = []
    # every bit position set half the time (64 tests folded into one chi-square)
    ones = np.array([((bits >> np.uint64(b)) & np.uint64(1)).sum() for b in range(64)],
                    dtype=float)
    total = bits.size
    z = (ones - total / 2) / np.sqrt(total / 4)
    out.append(("bit frequency, 64 positions (chi2 of z)", stats.chi2.sf((z**2).sum(), 64)))
    # the bytes uniform over 256 values
    counts = np.bincount(bits.view(np.uint8).ravel(), minlength=256)
    out.append(("byte values, 256 bins (chi2)", stats.chisquare(counts).pvalue))
    # uniforms: Kolmogorov-Smirnov, and 100 bins
    out.append(("uniform floats (Kolmogorov-Smirnov)", stats.kstest(u.ravel(), "uniform").pvalue))
    out.append(("uniform floats, 100 bins (chi2)",
                stats.chisquare(np.histogram(u, bins=100, range=(0, 1))[0]).pvalue))
    # pairs of neighbours (index i, i+1) and of neighbouring scenarios: 10 x 10 cells
    for name, a, b in (("neighbouring elements, 10x10 cells", u[:, :-1:2], u[:, 1::2]),
                       ("neighbouring scenarios, 10x10 cells", u[:-1:2], u[1::2])):
        cells = np.histogram2d(a.ravel(), b.ravel(), bins=10, range=[[0, 1], [0, 1]])[0]
        out.append((name + " (chi2)", stats.chisquare(cells.ravel()).pvalue))
    # neighbouring counters and streams: correlation of the same elements
    c1 = gen.uniform("stats.u", 1, (n,))
    s2 = gen.uniform("stats.v", 0, (n,))
    for name, other in (("counter 0 against counter 1", c1), ("stream u against stream v", s2)):
        r = np.corrcoef(u.ravel(), other.ravel())[0, 1]
        out.append((name + " (correlation)", 2 * stats.norm.sf(abs(r) * np.sqrt(u.size))))
    # runs up and down along each scenario's row (Wald-Wolfowitz on the signs of differences)
    signs = np.diff(u, axis=1).ravel() > 0
    runs = 1 + np.count_nonzero(signs[1:] != signs[:-1])
    m = signs.size
    mean, var = (2 * m - 1) / 3, (16 * m - 29) / 90
    out.append(("runs up and down", 2 * stats.norm.sf(abs(runs - mean) / np.sqrt(var))))
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="fewer repeats and draws")
    args = parser.parse_args()
    repeats = 20 if args.quick else 100
    print("Threefry-2x64-20, per draw call at batch 500 (uint64 draws):")
    for shape, n, ms, ns in per_call(500, [(), (6,), (60,), (60, 2), (130, 2), (600,)], repeats):
        print(f"  shape {str(shape):9s} {n:8d} draws  {ms:7.3f} ms a call  {ns:5.1f} ns a draw")
    total, spent, calls, draws = share_of_a_run(100 if args.quick else 500)
    print(f"greedy, setting (a), one batch: {total:.2f} s, of which drawing {spent:.3f} s "
          f"({100 * spent / total:.1f}%): {calls} calls, {draws} draws")
    print("statistical check (p-values; a sound generator gives none below 1e-4):")
    for name, p in statistics(500 if args.quick else 2000, 1000):
        print(f"  {name:48s} p = {p:.3f}")


if __name__ == "__main__":
    main()
