"""The reference path: the `oracle` reconstructor hands the policies the true S, only a declared
reference receives it, and every table labels its results a reference."""

import numpy as np
import pytest

from ata import hookimpl
from ata.core.errors import ContractError
from ata.core.kernel import Simulation
from ata.results.compare import compare
from ata.results.report import summarize, table_rows
from ata.results.markdown import results_markdown
from ata.results.rows import read_results
from ata.session import BASELINE_MISSION, load_session
from ata.experiment.runner import run_mission, write_run
from ata.model import fatigue
from ata.plugins.reconstructors import OracleReconstructor
from ata.testing import check_component

GROUPS = {"fatigue": "humans", "robots": "robots", "tasks": "tasks"}


def session(*sets):
    return load_session(str(BASELINE_MISSION), ["mission.scenarios=4", "mission.batch_size=4",
                                                "mission.uncertainty='high'", *sets])


@pytest.mark.parametrize("channels", [["fatigue"], ["robots"], ["tasks"],
                                      ["fatigue", "robots", "tasks"]])
def test_oracle_hands_over_the_true_state_at_every_epoch(channels):
    s = session("components.reconstructors=['identity', 'oracle']",
                f"oracle.channels={channels!r}")
    sim = Simulation(s.mission, s.registry, np.arange(4))
    sim.reset()
    humans = sim.sim.group("humans")
    stale = {g: 0 for g in GROUPS.values()}
    for _ in range(sim.sim.clock.n_epochs):
        ctx = sim.begin_epoch()
        truth, observed = sim.last_truth, ctx.observed
        for channel, group in GROUPS.items():
            want = truth[group] if channel in channels else observed[group]
            assert np.array_equal(ctx.reconstructed[group], want.features), (channel, group)
            stale[group] += not np.array_equal(truth[group].features, observed[group].features)
        if "fatigue" in channels:
            onset, slope, weight = (ctx.reconstructed[k] for k in fatigue.BELIEF_KEYS)
            assert onset.shape == slope.shape == weight.shape == (4, 6, 1)   # setting (a): 6 humans
            assert np.array_equal(onset[..., 0], humans.fatigue_onset)
            assert np.array_equal(slope[..., 0], humans.fatigue_slope)
            assert (weight == 1).all()
            # the belief it hands over gives the true F_f now
            belief = fatigue.belief_from(ctx.reconstructed, None, None, 0.4)
            now = truth["humans"]
            assert np.array_equal(belief.at(now.col("working_time")), now.col("fatigue"))
        else:
            assert not set(fatigue.BELIEF_KEYS) & set(ctx.reconstructed)
        # the hidden curves stay out of the observed S
        assert set(truth.hidden) == set(fatigue.CURVE_KEYS) and observed.hidden == {}
        sim.end_epoch(*sim.decide(ctx))
    # the noise and the latency made every group differ from the truth some time
    assert all(stale.values()), stale


def test_a_mission_with_a_reference_says_so_in_every_row():
    with_oracle = run_mission(session("components.reconstructors=['identity', 'oracle']"))
    assert with_oracle.metrics["reference"].tolist() == [1.0] * 4
    assert "reference" not in run_mission(session()).metrics


class PeeksAtTheTruth:
    """Implements the reference hook without declaring itself a reference."""

    def __init__(self, settings, mission):
        pass

    @hookimpl
    def ata_reconstruct_reference(self, sim, truth, obs, inherent, out):
        out["peek"] = truth["humans"].features


def test_the_kernel_hands_the_truth_only_to_a_declared_reference():
    s = session()
    with pytest.raises(ContractError, match="implements ata_reconstruct_reference, which hands "
                                            "it the true state: only a reconstructor whose "
                                            "class declares reference = True"):
        Simulation(s.mission, s.registry, [0], overrides={"reconstructors": PeeksAtTheTruth(
            None, None)})

    class NotAReconstructor(PeeksAtTheTruth):
        reference = True

    with pytest.raises(ContractError, match="injectors component"):
        Simulation(s.mission, s.registry, [0],
                   overrides={"injectors": NotAReconstructor(None, None)})


def test_check_component_refuses_a_reference_as_a_method():
    with pytest.raises(AssertionError, match="is a reference: it reads the true state, so it "
                                             "is no method"):
        check_component("reconstructor", OracleReconstructor)
    check_component("reconstructor", OracleReconstructor, reference=True)
    with pytest.raises(AssertionError, match="is not a reference"):
        check_component("reconstructor", PeeksAtTheTruth, reference=True)


def test_tables_label_a_reference(tmp_path):
    for name, sets in (("greedy", []),
                       ("greedy_oracle", ["components.reconstructors=['identity', 'oracle']"])):
        s = session(f"mission.name='{name}'", *sets)
        write_run(tmp_path / name, s, run_mission(s))
    res = read_results([tmp_path / "greedy", tmp_path / "greedy_oracle"])
    assert [res.label(m) for m in res.methods] == ["greedy", "greedy_oracle (reference)"]
    header, rows = table_rows(summarize(res), "a", "high")
    assert [r[0] for r in rows] == ["greedy", "greedy_oracle (reference)"]
    assert "| greedy - greedy_oracle (reference) |" in results_markdown(res, [("greedy",
                                                                              "greedy_oracle")])
    (table,) = compare(res, None, ["score"])
    assert [r[0] for r in table.rows] == ["greedy_oracle (reference)"]
