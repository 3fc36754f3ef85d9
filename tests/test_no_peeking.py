"""No peeking by construction: a decision-maker's generator shares no stream with the world's,
nothing it receives holds the root seed, a reconstructor sees no world state, and an evaluation
may run under a seed kept secret from every file it writes."""

from __future__ import annotations

import dataclasses
import json
import math
import tomllib

import numpy as np
import pytest

from _support import flat
from ata import hookimpl
from ata.core.errors import MissionError
from ata.core.kernel import Simulation
from ata.core.mission import seed_hash
from ata.core.rng import BatchRNG, StreamRNG, decision_rng
from ata.core.state import DecisionView
from ata.model.team import HumanConstants, RobotConstants
from ata.experiment import evaluate as ev
from ata.results import rows as rep
from ata.runtime.executors import SerialExecutor
from ata.session import BASELINE_MISSION, load_session
from ata.plugins.policies.greedy import GreedyPolicy

SEED = 8_675_309_123_456_789
"""A root seed no other number in a run is likely to equal."""


def small(*extra: str, seed: int = SEED):
    return load_session(str(BASELINE_MISSION), [f"mission.seed={seed}", "mission.scenarios=40",
                                                "mission.batch_size=40", *extra])


# --- the decision-makers' generator ------------------------------------------------------------

class DrawsTheOutcomeStreamName:
    """A greedy policy that, at t = 0, draws from the outcome stream's name in its context."""

    def __init__(self, mission):
        self.greedy = GreedyPolicy(GreedyPolicy.Settings(), mission)
        self.drawn = None

    @hookimpl
    def ata_initial_allocation(self, ctx):
        self.drawn = ctx.rng.uniform("tasks.outcome", 0, (ctx.sizes.tasks,))
        return self.greedy.ata_initial_allocation(ctx)

    @hookimpl
    def ata_reallocate(self, ctx, active):
        return self.greedy.ata_reallocate(ctx, active)


def test_a_world_stream_name_in_the_context_draws_numbers_independent_of_the_world():
    s = small()
    policy = DrawsTheOutcomeStreamName(s.mission)
    sim = Simulation(s.mission, s.registry, np.arange(40),
                     overrides={"initial": policy, "reallocation": policy})
    sim.reset()
    sim.step_epoch()
    outcome = sim.sim.groups["tasks"].outcome_u            # the world's (40, 60)
    drawn = policy.drawn
    assert drawn.shape == outcome.shape == (40, 60)
    assert not np.isin(drawn, outcome).any()
    corr = np.corrcoef(drawn.ravel(), outcome.ravel())[0, 1]
    assert abs(corr) < 4 / math.sqrt(drawn.size)          # 2400 POIs: |r| < 0.082
    # and it is a generator like the world's, of its own: uniform, reproducible
    assert abs(drawn.mean() - 0.5) < 4 * math.sqrt(1 / 12 / drawn.size)
    np.testing.assert_array_equal(
        drawn, decision_rng(SEED, np.arange(40)).uniform("tasks.outcome", 0, (60,)))


def test_decision_keys_depend_on_seed_and_scenario_and_batches_alone():
    ids = np.arange(30)
    full = decision_rng(SEED, ids)
    assert isinstance(full, StreamRNG) and not isinstance(full, BatchRNG)
    assert not hasattr(full, "root_seed") and not hasattr(full, "scenario_ids")
    u = full.uniform("a", 0, (5,))
    np.testing.assert_array_equal(decision_rng(SEED, ids[[7, 2]]).uniform("a", 0, (5,)),
                                  u[[7, 2]])
    np.testing.assert_array_equal(full.subset(np.array([4])).uniform("a", 0, (5,)), u[[4]])
    assert not np.array_equal(decision_rng(SEED + 1, ids).uniform("a", 0, (5,)), u)
    assert len({tuple(k) for k in full.keys.tolist()}) == 30
    world = BatchRNG(SEED, ids)
    assert not {tuple(k) for k in full.keys.tolist()} & {tuple(k) for k in world.keys.tolist()}


# --- nothing reachable holds the seed ----------------------------------------------------------

def reachable(value, seen=None):
    """Every object reachable from `value` through attributes, fields, items and slots."""
    seen = set() if seen is None else seen
    if id(value) in seen or isinstance(value, (str, bytes, type)) or callable(value) \
            and not hasattr(value, "__dict__"):
        return
    seen.add(id(value))
    yield value
    if isinstance(value, np.ndarray) or np.isscalar(value) or value is None:
        return
    children = []
    if isinstance(value, dict) or hasattr(value, "items") and hasattr(value, "keys"):
        children += list(value.keys()) + list(value.values())
    if isinstance(value, (list, tuple, set, frozenset)):
        children += list(value)
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        children += [getattr(value, f.name) for f in dataclasses.fields(value)]
    children += list(getattr(value, "__dict__", {}).values())
    for slot in getattr(type(value), "__slots__", ()):
        if hasattr(value, slot):
            children.append(getattr(value, slot))
    for child in children:
        yield from reachable(child, seen)


def holds_seed(value) -> bool:
    if isinstance(value, np.ndarray):
        return value.dtype.kind in "iu" and bool((value.astype(object) == SEED).any())
    return isinstance(value, (int, np.integer)) and not isinstance(value, bool) \
        and int(value) == SEED


class Witness:
    """Keeps every context, reconstructor view and factory mission it is handed."""

    missions: list = []

    def __init__(self, settings, mission):
        Witness.missions.append(mission)
        self.greedy = GreedyPolicy(GreedyPolicy.Settings(), mission)
        self.seen: list = []

    @hookimpl
    def ata_reconstruct(self, sim, obs, inherent, out):
        self.seen.append(sim)

    @hookimpl
    def ata_initial_allocation(self, ctx):
        self.seen.append(ctx)
        return self.greedy.ata_initial_allocation(ctx)

    @hookimpl
    def ata_should_reallocate(self, ctx):
        self.seen.append(ctx)
        return np.ones(ctx.reallocatable.shape[0], bool)

    @hookimpl
    def ata_reallocate(self, ctx, active):
        self.seen.append(ctx)
        return self.greedy.ata_reallocate(ctx, active)


class Contributes:
    @hookimpl
    def ata_register_components(self, register):
        for kind in ("policy", "condition", "reconstructor"):
            register(kind, "witness", Witness)


def test_no_field_reachable_from_what_a_decision_maker_receives_equals_the_root_seed():
    s = load_session(str(BASELINE_MISSION), [
        f"mission.seed={SEED}", "mission.scenarios=3", "mission.horizon_s=300.0",
        "components.initial='witness'", "components.condition='witness'",
        "components.reallocation='witness'", "components.reconstructors=['witness']"],
        extra=(Contributes(),))
    Witness.missions = []
    sim = Simulation(s.mission, s.registry, np.arange(3))
    sim.run()
    witness = sim.slot_component["initial"]
    # 5 epochs: 5 reconstructions, the initial allocation, 4 conditions and reallocations
    assert len(witness.seen) == 14 and len(Witness.missions) == 1
    assert sum(isinstance(x, DecisionView) for x in witness.seen) == 5
    assert Witness.missions[0].settings.seed is None
    found = [type(x).__name__ for x in reachable((witness.seen, Witness.missions))
             if holds_seed(x)]
    assert found == []
    # the world's side does hold it (the simulation's mission): the walk would have found it
    assert any(holds_seed(x) for x in reachable(sim))


def test_a_reconstructor_sees_no_world():
    s = small("mission.scenarios=2", "mission.batch_size=2")
    sim = Simulation(s.mission, s.registry, np.arange(2))
    sim.reset()
    sim.step_epoch()
    view = DecisionView(sim.sim, sim.decision_rng)
    assert view.rng is sim.decision_rng and view.epoch == 1 and view.batch_size == 2
    assert view.allocation is not sim.sim.allocation
    np.testing.assert_array_equal(view.allocation.stack(), sim.sim.allocation.stack())
    for name in ("groups", "params", "group", "record", "queue"):
        with pytest.raises(AttributeError, match=f"a reconstructor sees no '{name}'"):
            getattr(view, name)


def test_team_model_constants_and_decision_settings_reach_the_context_read_only():
    s = small("human.rebrief_s=7.5", "robot.replan_s=3.0", "greedy.human_time_cost=0.05")
    sim = Simulation(s.mission, s.registry, np.arange(2))
    sim.reset()
    ctx = sim.begin_epoch()
    assert ctx.published(HumanConstants).rebrief_s == 7.5
    assert ctx.published(RobotConstants).replan_s == 3.0
    assert set(ctx.settings) == {"greedy", "on_event", "identity"}
    assert ctx.settings["greedy"].human_time_cost == 0.05
    # a policy that writes them changes no component's settings, and no published constant
    ctx.settings["greedy"].human_time_cost = 0.0
    assert sim.pm.get_plugin("initial:greedy").s.human_time_cost == 0.05
    with pytest.raises(TypeError):
        ctx.settings["greedy"] = None
    with pytest.raises(dataclasses.FrozenInstanceError):
        ctx.published(RobotConstants).replan_s = 0.0


# --- a secret seed -----------------------------------------------------------------------------

SECRET = 6_389_117_554_021_937


def test_a_mission_seed_from_the_environment_is_written_as_its_hash(monkeypatch):
    monkeypatch.setenv("ATA_EVAL_SEED", str(SECRET))
    s = load_session(str(BASELINE_MISSION), ["mission.seed='env:ATA_EVAL_SEED'"])
    m = s.mission
    assert m.settings.seed == SECRET and m.secret_seed
    assert m.seed_label == seed_hash(SECRET) == "secret:" + \
        __import__("hashlib").sha256(str(SECRET).encode()).hexdigest()[:16]
    text = m.to_toml()
    assert str(SECRET) not in text
    assert tomllib.loads(text)["mission"]["seed"] == m.seed_label
    assert m.public().settings.seed is None
    # the same scenarios as the seed given openly
    open_ = load_session(str(BASELINE_MISSION), [f"mission.seed={SECRET}"]).mission
    assert not open_.secret_seed and open_.seed_label == SECRET
    assert m.replace(seed=3).secret_seed is False


@pytest.mark.parametrize("value, env, expected", [
    ("'env:ATA_NO_SUCH'", None, "reads the environment variable 'ATA_NO_SUCH', which is not "
                                "set: export ATA_NO_SUCH=N"),
    ("'env:ATA_EVAL_SEED'", "twelve", "holds no integer"),
    ("'env:ATA_EVAL_SEED'", "12345", "must lie in [2**32, 2**63)"),
    (f"'{seed_hash(SECRET)}'", None, "is the hash of a secret seed, not a seed: give the seed "
                                     "again as 'env:NAME'"),
])
def test_secret_seed_errors_name_the_fix(monkeypatch, value, env, expected):
    monkeypatch.delenv("ATA_NO_SUCH", raising=False)
    if env is not None:
        monkeypatch.setenv("ATA_EVAL_SEED", env)
    with pytest.raises(MissionError) as err:
        load_session(str(BASELINE_MISSION), [f"mission.seed={value}"])
    assert "[mission] key 'seed'" in str(err.value) and expected in flat(str(err.value))


SUITE = f"""\
[suite]
name = "secret"
settings = ["a"]
uncertainty = ["low"]
scenarios = 2
seed = "env:ATA_EVAL_SEED"

[[method]]
name = "greedy"
mission = "{BASELINE_MISSION}"
set = ["mission.horizon_s=300.0"]
"""


def test_an_evaluation_under_a_secret_seed_writes_its_hash_never_the_seed(cli, tmp_path,
                                                                          monkeypatch):
    monkeypatch.setenv("ATA_CACHE", str(tmp_path / "cache"))
    monkeypatch.setenv("ATA_EVAL_SEED", str(SECRET))
    suite = tmp_path / "suite.toml"
    suite.write_text(SUITE, encoding="utf-8")
    out = tmp_path / "out"
    res = cli("eval", suite, "--executor", "serial", "--no-cache", "--out", out, "-q")
    assert res.exit_code == 0, res.output
    for path in out.rglob("*"):
        if path.is_file():
            assert str(SECRET) not in path.read_text(encoding="utf-8", errors="replace"), path
    label = seed_hash(SECRET)
    results = rep.read_results(out)
    assert list(results.columns["seed"]) == [label, label]
    assert json.loads((out / "eval.json").read_text())["jobs"][0]["seed"] == label
    resolved = next((out / "missions").glob("*.resolved.toml"))
    assert tomllib.loads(resolved.read_text())["mission"]["seed"] == label
    # the rows are those of the seed given openly, which a host may publish afterwards
    _, jobs = ev.plan([str(suite)], seed=SECRET)
    assert jobs[0].mission.settings.seed == SECRET and not jobs[0].mission.secret_seed
    openly = ev.evaluate(jobs, SerialExecutor())
    assert [r["score"] for r in openly.rows] == list(results.columns["score"])
    assert [r["seed"] for r in openly.rows] == [SECRET, SECRET]


def test_a_suite_seed_names_an_environment_variable_or_is_an_integer(tmp_path):
    path = tmp_path / "s.toml"
    path.write_text(SUITE.replace('"env:ATA_EVAL_SEED"', '"ATA_EVAL_SEED"'), encoding="utf-8")
    with pytest.raises(MissionError, match="must be an integer >= 0"):
        ev.load_suite(path)
