"""`ata eval`: suites, validation before work, held-out seeds, executors that cannot change a
number, the MILP solution cache. `ata report`'s tests are in test_report_figures.py."""

from __future__ import annotations

import csv
import json
import math
import tomllib
from pathlib import Path

import numpy as np
import pytest

from _support import flat, tiny_data
from ata.experiment import evaluate as ev
from ata.published.sets import DROPPED
from ata.runtime.cache import cache_dir, run_cache
from ata.core.errors import MissionError
from ata.runtime.executors import ProcessExecutor, SerialExecutor
from ata import hookimpl
from ata.core.kernel import Simulation
from ata.session import BASELINE_MISSION, load_session
from ata.experiment.runner import run_mission
from ata.plugins.policies import milp as M

ROOT = Path(__file__).resolve().parent.parent
RANDOM_MISSION = ROOT / "examples" / "missions" / "random_baseline.toml"
HRL_MISSION = ROOT / "examples" / "missions" / "ata_hrl_a.toml"
PAPER_SUITE = ROOT / "examples" / "paper_suite.toml"

SUITE = f"""\
[suite]
name = "tiny"
settings = ["a"]
uncertainty = ["low", "high"]
scenarios = 4

[[method]]
name = "greedy"
mission = "{BASELINE_MISSION}"

[[method]]
name = "random"
mission = "{RANDOM_MISSION}"
"""


@pytest.fixture(autouse=True)
def _isolated(tmp_path, monkeypatch):
    monkeypatch.setenv("ATA_CACHE", str(tmp_path / "cache"))
    monkeypatch.setenv("ATA_RUNS", str(tmp_path / "runs"))


@pytest.fixture
def suite(tmp_path):
    path = tmp_path / "suite.toml"
    path.write_text(SUITE, encoding="utf-8")
    return path


def read_csv(path):
    with open(path, newline="", encoding="utf-8") as f:
        reader = csv.DictReader(f)
        return reader.fieldnames, list(reader)


def without_wall(rows):
    return [{k: v for k, v in r.items() if k != "wall_s"} for r in rows]


# -- results.csv --------------------------------------------------------------------------------
def test_results_schema_and_run_folder(cli, suite, tmp_path):
    out = tmp_path / "out"
    res = cli("eval", suite, "--executor", "serial", "--no-cache", "--out", out, "-q")
    assert res.exit_code == 0, res.output
    header, rows = read_csv(out / "results.csv")
    assert header[:len(ev.CORE_COLUMNS)] == ev.CORE_COLUMNS
    assert header == ev.CORE_COLUMNS + sorted(set(header) - set(ev.CORE_COLUMNS))
    assert len(rows) == 2 * 1 * 2 * 4                    # methods x settings x levels x scenarios
    keys = [(r["method"], r["setting"], r["uncertainty"], int(r["scenario"])) for r in rows]
    order = {"greedy": 0, "random": 1, "low": 0, "high": 1}
    assert keys == sorted(keys, key=lambda k: (order[k[0]], k[1], order[k[2]], k[3]))
    for r in rows:
        score, ub = float(r["score"]), float(r["upper_bound"])
        assert ub > 0 and math.isclose(float(r["fraction_of_u"]), score / ub)
        assert 0.0 <= float(r["classified_share"]) <= 1.0
        assert int(r["reallocations"]) >= 0 and float(r["wall_s"]) > 0
        assert int(r["seed"]) == 0 and int(r["scenario"]) >= ev.EVAL_FIRST_SCENARIO
    assert {r["method"] for r in rows if int(r["reallocations"]) > 0} <= {"greedy"}
    missions = sorted(p.name for p in (out / "missions").iterdir())
    assert missions == [f"{m}__a__{lv}.resolved.toml" for m in ("greedy", "random")
                        for lv in ("high", "low")]
    plugins = tomllib.loads((out / "plugins.toml").read_text())
    assert "ata" in plugins and "policy random" in plugins["components"]
    meta = json.loads((out / "eval.json").read_text())
    assert meta["rows"] == 16 and meta["wall_s"] > 0
    assert set(meta["method_wall_s"]) == {"greedy", "random"}
    assert meta["suites"][0]["content"]["suite"]["name"] == "tiny"
    assert meta["arguments"]["executor"] == {"executor": "serial"}
    # without --chunk-size, the units are of the default size
    assert meta["arguments"]["chunk_size"] == ev.DEFAULT_CHUNK == 250
    # a resolved mission reruns with `ata run` to the very same scores
    session = load_session(str(out / "missions" / "greedy__a__high.resolved.toml"))
    again = run_mission(session)
    expected = [float(r["score"]) for r in rows
                if r["method"] == "greedy" and r["uncertainty"] == "high"]
    assert again.total.tolist() == expected
    assert "P(greedy beats)" in flat(res.output)


def test_plain_mission_is_one_method(cli, tmp_path):
    out = tmp_path / "out"
    res = cli("eval", BASELINE_MISSION, RANDOM_MISSION, "-e", "serial", "--no-cache",
              "--scenarios", 3, "--out", out, "-q")
    assert res.exit_code == 0, res.output
    _, rows = read_csv(out / "results.csv")
    assert [(r["method"], r["setting"], r["uncertainty"]) for r in rows] == \
        [("greedy", "a", "medium")] * 3 + [("random", "a", "medium")] * 3


def test_filters(cli, suite, tmp_path):
    out = tmp_path / "out"
    res = cli("eval", suite, "-e", "serial", "--no-cache", "--methods", "random",
              "--levels", "high", "--scenarios", 2, "--out", out, "-q")
    assert res.exit_code == 0, res.output
    _, rows = read_csv(out / "results.csv")
    assert {(r["method"], r["uncertainty"]) for r in rows} == {("random", "high")}
    assert len(rows) == 2


def test_methods_names_a_method_whose_name_holds_commas(suite):
    text = suite.read_text().replace('name = "random"', 'name = "random, seed 2, x"')
    suite.write_text(text)
    _, jobs = ev.plan([str(suite)], methods=["greedy", "random", "seed 2", "x"], validate=False)
    assert {j.method for j in jobs} == {"greedy", "random, seed 2, x"}
    with pytest.raises(MissionError, match="unknown method 'random'"):
        ev.plan([str(suite)], methods=["random", "seed 2"], validate=False)


# -- executors ----------------------------------------------------------------------------------
def _rows(executor, suite, chunk_size, scenarios=5):
    _, jobs = ev.plan([str(suite)], scenarios=scenarios)
    with executor:
        return ev.evaluate(jobs, executor, chunk_size=chunk_size).rows


def test_rows_identical_across_executors_and_chunks(suite):
    serial = _rows(SerialExecutor(), suite, chunk_size=5)
    assert len(serial) == 20
    assert without_wall(_rows(SerialExecutor(), suite, chunk_size=2)) == without_wall(serial)
    assert without_wall(_rows(ProcessExecutor(2), suite, chunk_size=3)) == without_wall(serial)


def test_run_is_a_one_job_plan_of_the_eval_runner(cli, tmp_path, monkeypatch):
    """`ata run` and `ata eval` go through the same units (ata.experiment.units.run_unit): the
    same scenarios give the same rows on every executor and chunking."""
    from ata.experiment import units

    seen = []
    real = units.run_unit
    monkeypatch.setattr(units, "run_unit", lambda unit, **kw: seen.append(unit) or real(unit, **kw))
    _, jobs = ev.plan([str(BASELINE_MISSION)], scenarios=6)
    evaluated = ev.evaluate(jobs, SerialExecutor(), chunk_size=4).rows
    assert [u.ids.size for u in seen] == [4, 2]
    seen.clear()
    session = jobs[0].session
    result = run_mission(session)                       # serial: one batch, in this process
    assert [u.ids.size for u in seen] == [6]
    monkeypatch.setattr(units, "run_unit", real)        # a worker must find it by name
    with ProcessExecutor(2) as executor:
        parallel = run_mission(session, workers=2, executor=executor)
    for r in (result, parallel):
        assert r.scenario.tolist() == [row["scenario"] for row in evaluated]
        assert r.total.tolist() == [row["score"] for row in evaluated]
    out = tmp_path / "run"
    res = cli("run", BASELINE_MISSION, "--set", "mission.scenarios=3", "-e", "bogus",
              "-o", out, "-q")
    assert res.exit_code == 2 and "unknown executor 'bogus'" in res.output
    assert not (out / "plan.json").exists()


def test_every_method_of_the_paper_suite_gives_the_same_rows_on_any_executor_and_chunk():
    """The determinism contract for every built-in method: each method of the paper suite, in
    setting (a) at high uncertainty, gives the same rows (but for their times) serially in one
    unit of 3 scenarios and on 2 worker processes in units of 2 and 1."""
    _, jobs = ev.plan([str(PAPER_SUITE)], scenarios=3, settings=["a"], levels=["high"])
    assert len(jobs) == 32          # 11 methods and 21 training seeds
    # a training seed runs the code of its method: one seed each is enough here
    jobs = [j for j in jobs if " seed " not in j.method or j.method.endswith(" seed 0")]
    assert len(jobs) == 16

    def rows(executor, chunk):
        with executor:
            got = ev.evaluate(jobs, executor, chunk_size=chunk).rows
        # without the times (the columns published rows leave out); repr: a nan (a column a
        # method does not fill) equals itself
        return [{k: repr(v) for k, v in r.items() if k not in DROPPED} for r in got]

    serial = rows(SerialExecutor(), 3)
    assert len(serial) == 48 and len({r["score"] for r in serial}) > 30   # rows that differ
    assert rows(ProcessExecutor(2), 2) == serial


@pytest.mark.ray
def test_rows_identical_on_ray(suite):
    pytest.importorskip("ray")
    from ata.runtime.executors import RayExecutor

    serial = _rows(SerialExecutor(), suite, chunk_size=5, scenarios=3)
    assert without_wall(_rows(RayExecutor(workers=2), suite, chunk_size=2, scenarios=3)) == \
        without_wall(serial)


def test_missing_ray_is_a_clear_error(cli, suite, monkeypatch):
    import builtins

    real_import = builtins.__import__

    def no_ray(name, *args, **kwargs):
        if name == "ray":
            raise ImportError("no ray here")
        return real_import(name, *args, **kwargs)

    monkeypatch.setattr(builtins, "__import__", no_ray)
    res = cli("eval", suite, "--executor", "ray", "--no-cache", "-q")
    assert res.exit_code == 2
    assert "pip install 'ata[ray]'" in flat(res.output)


# -- validation before work ---------------------------------------------------------------------
def _bad_suite(tmp_path, method: str) -> Path:
    path = tmp_path / "bad_suite.toml"
    path.write_text(SUITE + method, encoding="utf-8")
    return path


@pytest.mark.parametrize("method, expected", [
    (f'[[method]]\nname = "typo"\nmission = "{BASELINE_MISSION}"\n'
     'set = ["components.initial=\'greedyy\'"]\n', "unknown policy 'greedyy'"),
    (f'[[method]]\nname = "ATA-HRL"\nmission = "{HRL_MISSION}"\n'
     'set = ["attention.checkpoint=\'/nonexistent.pt\'"]\n',
     "/nonexistent.pt: checkpoint: no such checkpoint"),
])
def test_bad_method_fails_before_any_work(cli, tmp_path, method, expected):
    suite = _bad_suite(tmp_path, method)
    out = tmp_path / "out"
    res = cli("eval", suite, "-e", "serial", "--out", out, "-q")
    assert res.exit_code == 2, res.output
    text = flat(res.output)
    assert str(suite) in text and "method" in text and expected in text
    assert "Traceback" not in res.output
    assert not (out / "results.csv").exists() and not out.exists()


@pytest.mark.parametrize("text, expected", [
    ('[suite]\nlevels = ["low"]\n[[method]]\nname = "g"\nmission = "builtin:greedy"\n',
     "[suite] key 'levels': unknown key"),
    ('[suite]\n[[method]]\nname = "g"\nmission = "builtin:greedy"\ncolour = 1\n',
     "[[method]] 'g' key 'colour': unknown key"),
    ('[suite]\n[[method]]\nname = "g"\nmission = "builtin:greedy"\nset = ["mission.seed=3"]\n',
     "sets mission.seed itself"),
    ('[suite]\n[[method]]\nname = "g"\nmission = "nowhere.toml"\n', "no such mission file"),
    ('[suite]\n[[method]]\nname = "g"\nmission = "builtin:greedy"\n'
     '[[method]]\nname = "g"\nmission = "builtin:greedy"\n', "is defined twice"),
    ('[suite]\nsettings = ["a"]\n[[method]]\nname = "g"\nmission = "builtin:greedy"\n'
     '[method.setting.b]\nset = []\n', "for setting 'b', which it does not run at"),
    ('[suite]\nname = "x"\n', "one or more [[method]] tables"),
    ('title = "x"\n', "neither a suite"),
])
def test_suite_errors(cli, tmp_path, text, expected):
    path = tmp_path / "s.toml"
    path.write_text(text, encoding="utf-8")
    res = cli("eval", path, "-e", "serial", "--no-cache", "-q", "--out", tmp_path / "out")
    assert res.exit_code == 2, res.output
    assert expected in flat(res.output) and str(path) in flat(res.output)
    assert not (tmp_path / "out").exists()


def test_per_setting_overrides(tmp_path):
    path = tmp_path / "s.toml"
    path.write_text('[suite]\nsettings = ["a", "b"]\nuncertainty = ["low"]\nscenarios = 2\n'
                    '[[method]]\nname = "g"\nmission = "builtin:greedy"\n'
                    '[method.setting.b]\nset = ["greedy.human_time_cost=0.5"]\n',
                    encoding="utf-8")
    _, jobs = ev.plan([str(path)], validate=False)
    costs = {j.setting: j.mission.component_settings["greedy"].human_time_cost for j in jobs}
    assert costs["b"] == 0.5 and costs["a"] != 0.5
    assert {j.mission.sizes.tasks for j in jobs} == {60, 130}


# -- held-out scenarios -------------------------------------------------------------------------
class TrainedOn:
    """A reconstructor that claims its weights saw scenarios 0..99 of seed 7."""

    def __init__(self, settings, mission):
        pass

    @hookimpl
    def ata_trained_on(self):
        return [(7, 0, 100)]

    @hookimpl
    def ata_reconstruct(self, sim, obs, inherent, out):
        pass


def test_evaluation_refuses_the_scenarios_a_component_was_trained_on(suite):
    # evaluation ids start at 2**40, where no trainer may draw (ata.training.TRAINING_ID_LIMIT)
    from ata.training import TRAINING_ID_LIMIT
    assert ev.EVAL_FIRST_SCENARIO == TRAINING_ID_LIMIT
    for seed in (0, 12345):
        _, jobs = ev.plan([str(suite)], seed=seed, scenarios=3)
        for job in jobs:
            assert ev.eval_range(job.mission) == (seed, ev.EVAL_FIRST_SCENARIO,
                                                  ev.EVAL_FIRST_SCENARIO + 3)
    # the check asks every component what it was trained on
    extra = type("Plugin", (), {"ata_register_components": hookimpl(
        lambda self, register: register("reconstructor", "trained_on", TrainedOn))})()
    for first, refused in ((5, True), (100, False), (2 ** 40, False)):
        session = load_session(str(BASELINE_MISSION), ["mission.seed=7",
                                                       f"mission.first_scenario={first}",
                                                       "components.reconstructors="
                                                       "['trained_on']"], extra=(extra,))
        sim = Simulation(session.mission.replace(scenarios=1), session.registry, [first])
        if refused:
            with pytest.raises(MissionError, match="held out"):
                ev.check_held_out(session.mission, sim)
        else:
            ev.check_held_out(session.mission, sim)
    # another seed's pairs are not the trained ones
    session = load_session(str(BASELINE_MISSION), ["mission.seed=8", "mission.first_scenario=5",
                                                   "components.reconstructors=['trained_on']"],
                           extra=(extra,))
    ev.check_held_out(session.mission, Simulation(session.mission.replace(scenarios=1),
                                                  session.registry, [5]))


# -- the MILP cache -----------------------------------------------------------------------------
def same_solution(a: M.Solution, b: M.Solution) -> bool:
    triples = (a.triples is None and b.triples is None) or \
        (a.triples is not None and b.triples is not None and np.array_equal(a.triples, b.triples))
    return triples and (a.status, a.objective, a.bound, a.margin_scale, a.message,
                        a.problems) == (b.status, b.objective, b.bound, b.margin_scale,
                                        b.message, b.problems)


def test_milp_cache_equals_fresh_solve(tmp_path, monkeypatch):
    settings = M.MilpSettings()
    data = [tiny_data(s, P=5) for s in range(4)]
    policy = M.MilpPolicy(settings, None)
    fresh = policy.solve_all(data)                       # no cache set: solved
    assert cache_dir() is None
    with run_cache(tmp_path) as root:
        first = policy.solve_all(data)                   # solved and stored
        assert len(list((root / "milp").rglob("*.json"))) == 4

        def no_solving(*args, **kwargs):
            raise AssertionError("solved although cached")

        monkeypatch.setattr(M, "solve_scenario", no_solving)
        cached = policy.solve_all(data)                  # read back, nothing solved
    assert cache_dir() is None
    for f, a, c in zip(fresh, first, cached):
        assert same_solution(f, a) and same_solution(f, c)
    # the key: the scenario's data and the settings that shape the solution
    key = M.cache_key(data[0], settings)
    assert key == M.cache_key(tiny_data(0, P=5), M.MilpSettings(workers=4, chunk_size=3))
    assert key != M.cache_key(data[0], M.MilpSettings(mip_rel_gap=0.05))
    assert key != M.cache_key(data[1], settings)
    changed = tiny_data(0, P=5)
    changed.event_p = 0.4
    assert key != M.cache_key(changed, settings)


def test_milp_eval_rows_same_with_and_without_cache(cli, tmp_path):
    path = tmp_path / "s.toml"
    path.write_text(f'[suite]\nsettings = ["a"]\nuncertainty = ["medium"]\nscenarios = 3\n'
                    f'[[method]]\nname = "ITA-MILP"\n'
                    f'mission = "{ROOT / "examples" / "missions" / "milp_a.toml"}"\n',
                    encoding="utf-8")
    cache = tmp_path / "milp-cache"
    outs = []
    for i, flags in enumerate((["--no-cache"], ["--cache", cache], ["--cache", cache])):
        out = tmp_path / f"out{i}"
        res = cli("eval", path, "-e", "serial", "--out", out, "-q", *flags)
        assert res.exit_code == 0, res.output
        outs.append(read_csv(out / "results.csv")[1])
    assert len(list(cache.rglob("*.json"))) == 3
    strip = [[{k: v for k, v in r.items() if k not in ("wall_s", "milp_solve_s")} for r in rows]
             for rows in outs]
    assert strip[0] == strip[1] == strip[2]


def test_run_takes_a_cache_folder_too(cli, tmp_path):
    mission = ROOT / "examples" / "missions" / "milp_a.toml"
    cache = tmp_path / "milp-cache"
    scores = []
    for i, flags in enumerate(([], ["--cache", cache], ["--cache", cache])):
        out = tmp_path / f"run{i}"
        res = cli("run", mission, "--set", "mission.scenarios=2", "-o", out, "-q", *flags)
        assert res.exit_code == 0, res.output
        scores.append([r["score"] for r in read_csv(out / "results.csv")[1]])
        assert len(list(cache.rglob("*.json"))) == (0 if i == 0 else 2)
    assert scores[0] == scores[1] == scores[2]
