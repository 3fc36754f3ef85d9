"""The across-seed statistics (`ata.results.seeds`) on synthetic rows whose answer is known: the
two-level bootstrap's interval counts the variance between seeds and between scenarios, each
alone and both together, so that a bootstrap of one level fails; the IQM, the spread and P(a
seed of A beats a seed of B); and the across-seed tables of `ata report` and `ata compare`."""

from __future__ import annotations

import csv
import math

import numpy as np
import pytest

from ata.results import seeds as sd
from ata.results.rows import bootstrap_ci, read_results

Z = 1.959964
K, N = 40, 60          # seeds, scenarios: enough that the bootstrap's interval is near normal
R = 6000


def width(interval) -> float:
    return interval[2] - interval[1]


@pytest.fixture(scope="module")
def effects():
    gen = np.random.default_rng(7)
    a = gen.normal(0.0, 8.0, K)                 # each seed's effect
    b = gen.normal(0.0, 10.0, N)                # each scenario's effect, the same for every seed
    return a, b


def test_seed_variance_alone_gives_the_interval_of_the_mean_of_k_seed_means(effects):
    a, _ = effects
    scores = 50.0 + a[:, None] + np.zeros((K, N))          # no scenario noise
    # the bootstrap of the mean of K values: sd = their population sd / sqrt(K)
    analytic = 2 * Z * a.std() / math.sqrt(K)
    assert width(sd.two_level(scores, R)) == pytest.approx(analytic, rel=0.08)


def test_scenario_variance_alone_gives_the_scenario_level_interval(effects):
    _, b = effects
    scores = 50.0 + np.zeros((K, 1)) + b[None, :]          # every seed the same
    expected = width(bootstrap_ci(b, R))
    assert width(sd.two_level(scores, R)) == pytest.approx(expected, rel=0.08)
    assert expected == pytest.approx(2 * Z * b.std() / math.sqrt(N), rel=0.08)


def test_both_levels_add_up_and_are_wider_than_either(effects):
    a, b = effects
    scores = 50.0 + a[:, None] + b[None, :]
    seeds_alone = 2 * Z * a.std() / math.sqrt(K)
    scenarios_alone = 2 * Z * b.std() / math.sqrt(N)
    got = width(sd.two_level(scores, R))
    assert got > 1.2 * max(seeds_alone, scenarios_alone)
    assert got == pytest.approx(math.hypot(seeds_alone, scenarios_alone), rel=0.08)


def test_the_bootstrap_is_fixed_and_one_seed_falls_back_to_the_scenarios(effects):
    a, b = effects
    scores = 50.0 + a[:5, None] + b[None, :]
    assert sd.two_level(scores) == sd.two_level(scores)
    one = sd.across_seeds(scores[:1])
    assert (one.seeds, one.two_level) == (1, False)
    assert (one.mean, one.low, one.high) == bootstrap_ci(scores[0])
    assert sd.summary_row(one)[1:5:3] == ["1 seed", "scenarios (1 seed)"]


def test_iqm_spread_and_the_probability_that_a_seed_beats_another():
    seed_means = np.array([10.0, 11.0, 12.0, 13.0, 100.0])     # one seed far off
    scores = seed_means[:, None] + np.array([-1.0, 0.0, 1.0])
    s = sd.across_seeds(scores)
    assert s.iqm == pytest.approx(12.0)                          # the middle three
    assert s.mean == pytest.approx(29.2)
    assert (s.lowest, s.highest) == (10.0, 100.0)
    assert s.sd == pytest.approx(np.std(seed_means, ddof=1))
    other = np.array([11.5, 12.5])[:, None] + np.zeros(3)
    # A's seeds above 11.5: 12, 13, 100 (3 of 5); above 12.5: 13, 100 (2 of 5)
    assert sd.beat_probability(scores, other) == pytest.approx(5 / 10)
    assert sd.beat_probability(other, other) == pytest.approx(0.5)
    p = sd.pair_across(scores, other, "A", "B")
    assert p.mean == pytest.approx(29.2 - 12.0) and p.low < p.mean < p.high


def test_method_names_group_into_seeds():
    groups = sd.seed_groups(["mine seed 1", "greedy", "mine seed 0", "ATA-HRL", "ATA-HRL seed 3"])
    assert groups == {"mine": ["mine seed 0", "mine seed 1"], "greedy": ["greedy"],
                      "ATA-HRL (one run)": ["ATA-HRL"], "ATA-HRL": ["ATA-HRL seed 3"]}
    assert sd.split_seed("w/o.C seed 12") == ("w/o.C", 12)
    assert sd.split_seed("seedling") == ("seedling", None)


def write_results(path, scores: dict[str, np.ndarray]):
    path.mkdir(parents=True, exist_ok=True)
    with open(path / "results.csv", "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["method", "setting", "uncertainty", "scenario", "seed", "score",
                    "upper_bound", "fraction_of_u", "classified_share"])
        for method, values in scores.items():
            for i, v in enumerate(values):
                w.writerow([method, "a", "medium", 1000 + i, 0, v, 100, v / 100, 0.5])
    return path


def test_report_prints_the_across_seed_tables(cli, tmp_path):
    gen = np.random.default_rng(3)
    base = gen.normal(40, 5, 30)
    folder = write_results(tmp_path / "eval", {
        **{f"mine seed {s}": base + 3 * s + 1 for s in range(3)}, "greedy": base})
    res = read_results(folder)
    assert sd.has_seeds(res)
    tables = sd.seed_tables(res)
    summary, pairs = tables
    assert [r[:3] for r in summary.rows] == [["mine", "3 seeds", "30"],
                                             ["greedy", "1 seed", "30"]]
    assert pairs.rows[0][0] == "mine - greedy" and pairs.rows[0][-1] == "1.00"
    out = cli("report", folder, "--no-figures").output
    assert "across training seeds" in out and "3 seeds" in out
    assert "across training seeds" in (folder / "report.md").read_text()


def test_compare_against_published_seeds_groups_both_sides(tmp_path):
    gen = np.random.default_rng(5)
    base = gen.normal(40, 5, 20)
    mine = read_results(write_results(tmp_path / "mine", {
        f"mine seed {s}": base + s for s in range(2)}))
    theirs = read_results(write_results(tmp_path / "pub", {
        **{f"ATA-HRL seed {s}": base + 0.5 + 2 * s for s in range(5)}, "greedy": base - 9}))
    summary, pairs = sd.published_tables(mine, theirs, ["ATA-HRL", "greedy"])
    assert [r[:2] for r in summary.rows] == [["mine", "2 seeds"],
                                             ["ATA-HRL (published)", "5 seeds"],
                                             ["greedy (published)", "1 seed"]]
    # mine's seeds 40+0, 40+1 against ATA-HRL's 40.5, 42.5, ...: seed 1 beats one of five
    assert [(r[0], r[1], r[-1]) for r in pairs.rows] == [("mine - ATA-HRL", "2 / 5", "0.10"),
                                                         ("mine - greedy", "2 / 1", "1.00")]


def test_a_folder_of_seeds_reports_its_evaluation_across_seeds(tmp_path):
    from ata.results.seed_curves import SeedLogs, eval_tables, paired_rows
    base = np.random.default_rng(9).normal(40, 5, 25)
    write_results(tmp_path / "eval", {**{f"mine seed {s}": base + 1 + s for s in range(3)},
                                      "greedy": base})
    seeds = SeedLogs(tmp_path, [0, 1, 2], [], [])
    header, rows = paired_rows(seeds, tmp_path / "eval")
    assert [r[0] for r in rows] == ["0", "1", "2", "mean over seeds", "IQM over seeds"]
    assert rows[3][3] == "3 x 25" and rows[3][4].startswith("+2.00 [")
    summary, pairs = eval_tables(seeds)
    assert summary.rows[0][:2] == ["mine", "3 seeds"] and pairs.rows[0][0] == "mine - greedy"


def test_report_markdown_gives_the_across_seed_tables(cli, tmp_path):
    base = np.random.default_rng(4).normal(40, 5, 20)
    folder = write_results(tmp_path / "eval", {**{f"mine seed {s}": base + 2 + s
                                                  for s in range(4)}, "greedy": base})
    out = cli("report", folder, "--markdown").output
    assert f"| mine (4 seeds) | {base.mean() + 3.5:.1f} [" in out and "| greedy (1 seed) | " in out
    assert "| mine - greedy | +3.5 [" in out and "; P 1.00 |" in out
    assert "| mine seed" not in out          # the seeds' rows are read across seeds alone


def test_compare_published_prints_the_across_seed_tables(cli, tmp_path, monkeypatch):
    from ata.published import sets
    base = np.random.default_rng(6).normal(40, 5, 15)
    mine = write_results(tmp_path / "mine", {f"mine seed {s}": base + 2 + s for s in range(3)})
    theirs = read_results(write_results(tmp_path / "pub", {"ATA-HRL": base, "greedy": base - 4}))
    monkeypatch.setattr(sets, "read_published", lambda name: (theirs, {}, "SET"))
    monkeypatch.setattr(sets, "check_pairing", lambda *a: None)
    out = cli("compare", mine, "published", "--base", "ATA-HRL").output
    assert "A - B across training seeds (B published)" in out
    assert "mine - ATA-HRL" in out and "3 / 1" in out and "mine - greedy" not in out
    assert "across training seeds" not in cli("compare", mine, "published", "--power").output


def test_the_across_seed_reference_is_ata_hrl_by_its_seeds(tmp_path):
    from ata.results.report import summarize
    base = np.random.default_rng(8).normal(40, 5, 10)
    res = read_results(write_results(tmp_path / "eval", {
        "greedy": base, **{f"ATA-HRL seed {s}": base + 5 + s for s in range(2)}}))
    report = summarize(res)
    assert report.reference == "greedy"          # the per-method tables: no plain ATA-HRL row
    assert report.seeds[1].rows[0][0] == "ATA-HRL - greedy"
    assert summarize(res, "greedy").seeds[1].rows[0][0] == "greedy - ATA-HRL"


def test_beside_its_seeds_a_plain_run_keeps_its_own_row_and_a_pair_name_means_the_seeds(tmp_path):
    base = np.random.default_rng(11).normal(40, 5, 12)
    res = read_results(write_results(tmp_path / "eval", {
        "ATA-HRL": base + 20, **{f"ATA-HRL seed {s}": base + 2 + s for s in range(3)},
        "greedy": base}))
    lines = "\n".join(sd.seed_markdown(res, [("ATA-HRL", "greedy"),
                                             ("ATA-HRL (one run)", "greedy")]))
    assert "| ATA-HRL (one run) | " in lines and "| ATA-HRL (3 seeds) | " in lines
    # the seeds' mean gap is +3 (2, 3, 4), the plain run's +20: each pair reads its own rows
    assert "| ATA-HRL - greedy | +3.0 [" in lines
    assert "| ATA-HRL (one run) - greedy | +20.0 [" in lines
    assert sd.seed_tables(res, "ATA-HRL")[1].rows[0][0] == "ATA-HRL - ATA-HRL (one run)"


def test_the_figures_draw_the_plain_methods_and_leave_the_seeds_to_the_tables(tmp_path,
                                                                              monkeypatch):
    from ata.results import report as rp
    base = np.random.default_rng(12).normal(40, 5, 10)
    res = read_results(write_results(tmp_path / "eval", {
        "ATA-HRL": base + 9, **{f"ATA-HRL seed {s}": base + s for s in range(2)},
        "w/o.AUX": base + 4, "greedy": base}))
    drawn = {}

    def keep(fig, out, stem, **kw):
        drawn[stem] = [t.get_text() for ax in fig.axes for t in
                       (ax.get_legend().get_texts() if ax.get_legend() else ax.get_yticklabels())]
        return []
    monkeypatch.setattr(rp, "save_figure", keep)
    report = rp.summarize(res, "ATA-HRL")
    rp.figures(report, tmp_path, rp.paired_differences(res, "greedy", 200))
    assert drawn["fig_setting_a"] == ["ATA-HRL", "w/o.AUX", "greedy"]
    assert drawn["fig_ablations"] == ["ATA-HRL", "w/o.AUX"]
    assert "ATA-HRL seed 0" not in drawn["fig_paired"] and "ATA-HRL" in drawn["fig_paired"]
    # the seeds are drawn together, in fig_seeds, beside the plain run of their name
    assert drawn["fig_seeds"] == ["ATA-HRL (2 seeds)", "the plain run (default weights)"]


def test_fig_seeds_draws_the_two_level_interval_each_seed_and_the_plain_run(tmp_path):
    from ata.results.report import pyplot
    from ata.results.seed_figure import seeds_figure
    gen = np.random.default_rng(5)
    base = gen.normal(40, 5, 12)
    res = read_results(write_results(tmp_path / "eval", {
        "mine": base + 9, **{f"mine seed {s}": base + 3 * s + gen.normal(0, 1, 12)
                             for s in range(3)}, "greedy": base}))
    plt = pyplot()
    fig = seeds_figure(plt, res, 500)
    [ax] = fig.axes
    [bar] = ax.containers                         # one method with seeds, one level
    (_, y), (_, y_high) = bar.lines[2][0].get_segments()[0]
    scores = sd.seed_matrix(res, [f"mine seed {s}" for s in range(3)], "a", "medium")[0]
    st = sd.across_seeds(scores, resamples=500)
    assert (y, y_high) == pytest.approx((st.low, st.high))
    assert st.high - st.low > 2 * (bootstrap_ci(scores[0], 500)[2] - scores[0].mean())
    from matplotlib.collections import PathCollection
    dots = [c.get_offsets()[:, 1] for c in ax.collections
            if isinstance(c, PathCollection) and len(c.get_offsets())]
    assert sorted(np.concatenate(dots)) == pytest.approx(sorted([*scores.mean(1),
                                                                 (base + 9).mean()]))
    plt.close(fig)
    res = read_results(write_results(tmp_path / "plain", {"mine": base, "greedy": base}))
    assert seeds_figure(plt, res) is None
