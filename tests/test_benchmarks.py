"""The benchmarks run (tiny batches): these are not timed tests, but a benchmark that no longer
runs would leave the figures of docs/training.md and docs/benchmarks.md without their command."""

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def test_the_training_benchmark_runs_every_row():
    out = subprocess.run([sys.executable, str(ROOT / "benchmarks" / "bench_training.py"),
                          "--repeats", "1", "--scenarios", "1", "--samples", "2"],
                         capture_output=True, text=True, cwd=ROOT, timeout=300)
    assert out.returncode == 0, out.stderr[-2000:]
    for row in ("simulator + greedy", "ITA decoder, prior alone", "ITA decoder with the network",
                "ITA training step", "pi_C / pi_TR training step"):
        assert row in out.stdout, row


def test_the_recipe_estimate_counts_validations_as_the_trainer_does():
    sys.path.insert(0, str(ROOT / "benchmarks"))
    from bench_training import validations
    # step 0, every 15th step, and the last: 800 ITA steps -> 0, 15, ..., 795, 800
    assert validations(800, 15) == 55
    assert validations(30, 15) == 3
    assert validations(3, 4) == 2
    assert validations(0, 15) == 0


def test_the_memory_benchmark_reports_a_child_run():
    sys.path.insert(0, str(ROOT / "benchmarks"))
    from bench_memory import GREEDY_REALLOC, isolated
    out = isolated("a", [*GREEDY_REALLOC, "mission.tasks=12"], 2, 2, traced=True)
    assert set(out) == {"wall_s", "rate", "cpu_s", "cpu_rate", "rss_base_mib", "rss_peak_mib",
                        "elapsed_s", "traced_peak_mib"}
    assert out["rss_peak_mib"] >= out["rss_base_mib"] > 0
    assert out["traced_peak_mib"] > 0


def test_the_memory_growth_law_reads_linear_as_1_and_quadratic_as_2():
    sys.path.insert(0, str(ROOT / "benchmarks"))
    from bench_memory import growth_law
    pois = [130, 260, 520, 1040]

    def law(peak):
        # a fixed 20 MiB beside the growth, as the interpreter and the setup give
        rows = growth_law([{"pois": p, "traced_peak_mib": 20 + peak(p)} for p in pois], 5)
        return [round(r["exponent"], 6) for r in rows if "exponent" in r]

    assert law(lambda p: 0.01 * p) == [1.0, 1.0]
    assert law(lambda p: 1e-5 * p * p) == [2.0, 2.0]
    rows = growth_law([{"pois": 130, "traced_peak_mib": 21.5},
                       {"pois": 260, "traced_peak_mib": 22.4}], 5)
    assert "slope_kib" not in rows[0] and "exponent" not in rows[1]
    assert abs(rows[1]["slope_kib"] - 0.9 * 1024 / 130 / 5) < 1e-9


def test_the_fast_benchmark_driver_imports_every_figure():
    out = subprocess.run([sys.executable, str(ROOT / "benchmarks" / "bench_fast.py"), "--help"],
                         capture_output=True, text=True, cwd=ROOT, timeout=120)
    assert out.returncode == 0, out.stderr[-2000:]
    assert "--quick" in out.stdout


def test_the_filter_benchmark_reports_both_methods_and_their_ratio():
    out = subprocess.run([sys.executable, str(ROOT / "benchmarks" / "bench_filter.py"),
                          "--scenarios", "6", "--settings", "a", "--repeats", "1"],
                         capture_output=True, text=True, cwd=ROOT, timeout=300)
    assert out.returncode == 0, out.stderr[-2000:]
    assert "6 scenarios at high, CPU seconds (least of 1)" in out.stdout
    assert "(a) greedy " in out.stdout and "greedy + filter " in out.stdout
    assert out.stdout.rstrip().endswith("x")


def test_the_gym_benchmark_keeps_the_least_time_of_alternating_runs(monkeypatch):
    sys.path.insert(0, str(ROOT / "benchmarks"))
    import bench_gym
    # scripted runs, in call order: single, vector, single, vector (episodes/s, wall, CPU)
    runs = iter([(4.0, 32.0, 30.0), (80.0, 1.6, 1.5), (8.0, 16.0, 16.0), (64.0, 2.0, 1.2)])
    sides = []

    def fake(envs, rounds, seed):
        sides.append(type(envs).__name__)
        return next(runs)

    monkeypatch.setattr(bench_gym, "episodes_per_second", fake)
    r = bench_gym.vector_vs_single(str(bench_gym.SMALL_TEAM), 2, 1, 0, repeats=2)
    assert sides == ["SyncVectorEnv", "CentralisedVectorEnv"] * 2
    assert (r["wall_single"], r["wall_vector"]) == (16.0, 1.6)
    assert (r["cpu_single"], r["cpu_vector"]) == (16.0, 1.2)
    assert r["ratio"] == (128 / 1.6) / (128 / 16.0)
    assert r["cpu_ratio"] == 16.0 / 1.2


def test_the_scaling_benchmark_times_a_whole_run_and_reads_growth_as_an_exponent():
    sys.path.insert(0, str(ROOT / "benchmarks"))
    from bench_scaling import GREEDY, growth, run_cpu_seconds
    assert run_cpu_seconds(GREEDY, ["mission.tasks=12"], 2) > 0
    # t = c P^2: an exponent of 2 between any two sizes
    rows = {"90": {"pois": 90, "greedy": 90 ** 2 * 1e-5},
            "250": {"pois": 250, "greedy": 250 ** 2 * 1e-5}}
    assert abs(growth(rows, "greedy") - 2.0) < 1e-12
