"""Every hook of ata.core.hookspecs, exercised through small components declared inline in the test.

In the manner of pluggy's own tests: a fresh plugin manager per test (`get_plugin_manager(extra=
[...])` with no entry points), small plugins inline, and exact assertions. The built-in task,
human and robot models provide the world; the components under test are the test's own.
"""

from __future__ import annotations

import re
from typing import Any

from types import SimpleNamespace

import numpy as np
import pytest

from ata import hookimpl
from ata.core.errors import ContractError, MissionError
from ata.core.kernel import Simulation
from ata.core.mission import validate
from ata.core.registry import Register, collect_components, get_plugin_manager
from ata.session import Session
from ata.experiment.runner import run_mission
from ata.core.state import Allocation
from ata.model import fatigue

SMALL = {"setting": "custom", "humans": 2, "robots": 2, "tasks": 6, "uncertainty": "none",
         "horizon_s": 120.0, "epoch_s": 60.0, "tick_s": 30.0}
"""Two epochs of two ticks each."""


def registry_with(*components: tuple[str, str, Any]) -> Register:
    """A fresh plugin manager whose one extra package plugin registers `components`."""

    class Package:
        @hookimpl
        def ata_register_components(self, register):
            for kind, name, factory in components:
                register(kind, name, factory)

    return collect_components(get_plugin_manager(entry_points=False, extra=[Package()]))


def simulation(registry: Register, mission: dict | None = None, n: int = 2,
               **slots: Any) -> Simulation:
    raw = {"mission": {**SMALL, **(mission or {})},
           "components": {"injectors": [], "initial": "to_robot_0", "condition": "never",
                          "reallocation": "to_robot_0", **slots}}
    return Simulation(validate(raw, registry), registry, np.arange(n))


def component(cls):
    """A factory for a settings-free component: factory(settings, mission) -> instance."""
    return lambda settings, mission: cls()


class ToRobot0:
    """Every task to robot 0, driven autonomously, classified onboard."""

    @hookimpl
    def ata_initial_allocation(self, ctx):
        B, P = ctx.reallocatable.shape
        return Allocation(np.zeros((B, P), int), np.full((B, P), -1), np.full((B, P), -1))

    @hookimpl
    def ata_reallocate(self, ctx, active):
        return self.ata_initial_allocation(ctx)


BASE = ("policy", "to_robot_0", component(ToRobot0))


# --- start-up ----------------------------------------------------------------------------------

def test_ata_register_components_registers_by_name():
    class Noop:
        def __init__(self, settings, mission):
            pass

    class Package:
        @hookimpl
        def ata_register_components(self, register):
            register("injector", "noop", Noop)

    package = Package()
    pm = get_plugin_manager(entry_points=False, extra=[package])
    registry = collect_components(pm)
    info = registry.get("injector", "noop", "test")
    assert (info.kind, info.name, info.factory) == ("injector", "noop", Noop)
    assert info.plugin == pm.get_name(package)
    assert "noop" in registry.names("injector")
    assert "latency" in registry.names("injector")      # the built-ins are there too


@pytest.mark.parametrize("kind, name, message", [
    ("widget", "w", "unknown component kind 'widget'; kinds: task_model, human_model"),
    ("injector", "latency", "component name 'latency' is already registered (injector) by "
                            "ata.plugins.uncertainty.latency"),
])
def test_ata_register_components_rejects_bad_registrations(kind, name, message):
    class Package:
        @hookimpl
        def ata_register_components(self, register):
            register(kind, name, object)

    pm = get_plugin_manager(entry_points=False, extra=[Package()])
    with pytest.raises(ValueError, match=re.escape(message)):
        collect_components(pm)


# --- the phases, in order ----------------------------------------------------------------------

class Recorder:
    """Records every phase hook it sees, with what it saw."""

    def __init__(self):
        self.events: list[tuple] = []

    @hookimpl
    def ata_setup(self, sim):
        self.events.append(("setup", sim.batch_size))

    @hookimpl
    def ata_inherent(self, sim, inherent):
        self.events.append(("inherent", tuple(sorted(inherent))))

    @hookimpl
    def ata_observe(self, sim, obs):
        self.events.append(("observe", sim.epoch, sim.now, tuple(sorted(obs))))

    @hookimpl
    def ata_inject(self, sim, obs):
        self.events.append(("inject", sim.epoch))

    @hookimpl
    def ata_reconstruct(self, sim, obs, inherent, out):
        self.events.append(("reconstruct", sim.epoch))

    @hookimpl
    def ata_allocation_changed(self, sim, changed):
        self.events.append(("allocation_changed", sim.epoch, int(changed.sum())))

    @hookimpl
    def ata_advance(self, sim, t0, t1):
        self.events.append(("advance", t0, t1))

    @hookimpl
    def ata_epoch_end(self, sim, epoch):
        self.events.append(("epoch_end", epoch))

    @hookimpl
    def ata_episode_end(self, sim):
        self.events.append(("episode_end",))


def test_phase_hooks_are_called_once_per_phase_in_order():
    recorder = Recorder()
    registry = registry_with(BASE, ("injector", "recorder", lambda s, m: recorder))
    simulation(registry, injectors=["recorder"]).run()
    groups = ("humans", "robots", "tasks")
    assert recorder.events == [
        ("setup", 2), ("inherent", groups),
        ("observe", 0, 0.0, groups), ("inject", 0), ("reconstruct", 0),
        ("allocation_changed", 0, 2 * 6),
        ("advance", 0.0, 30.0), ("advance", 30.0, 60.0), ("epoch_end", 0),
        ("observe", 1, 60.0, groups), ("inject", 1), ("reconstruct", 1),
        ("advance", 60.0, 90.0), ("advance", 90.0, 120.0), ("epoch_end", 1),
        ("episode_end",),
    ]


def test_ata_setup_and_ata_inherent_per_scenario():
    class Probe:
        @hookimpl
        def ata_setup(self, sim):
            self.state = sim.own("probe", SimpleNamespace(draw=sim.rng.uniform("probe", 0, (3,))))

        @hookimpl
        def ata_inherent(self, sim, inherent):
            inherent.add("probe", ("draw",), sim.group("probe").draw[..., None])

    registry = registry_with(BASE, ("injector", "probe", component(Probe)))
    sim = simulation(registry, injectors=["probe"], n=3)
    inherent = sim.reset()
    assert sorted(inherent) == ["humans", "probe", "robots", "tasks"]
    draws = inherent["probe"].col("draw")
    assert draws.shape == (3, 3)
    assert np.array_equal(draws, sim.sim.groups["probe"].draw)
    # scenario 2's numbers do not depend on the batch it is in
    alone = Simulation(sim.mission, registry, [2])
    assert np.array_equal(alone.reset()["probe"].col("draw")[0], draws[2])


def test_ata_observe_writes_the_true_state():
    seen = []

    class Clock:
        @hookimpl
        def ata_observe(self, sim, obs):
            obs.add("clock", ("now",), np.full((sim.batch_size, 1, 1), sim.now))

    class Capture(ToRobot0):
        @hookimpl
        def ata_initial_allocation(self, ctx):
            seen.append(ctx)
            return super().ata_initial_allocation(ctx)

    registry = registry_with(("injector", "clock", component(Clock)),
                             ("policy", "capture", component(Capture)), BASE)
    sim = simulation(registry, injectors=["clock"], initial="capture")
    sim.reset()
    sim.step_epoch()
    (ctx,) = seen
    assert sim.last_truth["clock"].col("now").tolist() == [[0.0], [0.0]]
    assert ctx.observed["clock"].col("now").tolist() == [[0.0], [0.0]]
    assert ctx.observed["clock"] is not sim.last_truth["clock"]   # the observation is a copy
    assert not hasattr(ctx, "truth")                              # policies never see it


@pytest.mark.parametrize("order, expected", [(["set_half", "double"], 1.0),
                                             (["double", "set_half"], 0.5)])
def test_ata_inject_runs_in_listed_order_on_a_copy(order, expected):
    class SetHalf:
        @hookimpl
        def ata_inject(self, obs):
            obs["humans"].set("fatigue", 0.5)

    class Double:
        @hookimpl
        def ata_inject(self, obs):
            obs["humans"].set("fatigue", 2 * obs["humans"].col("fatigue"))

    registry = registry_with(BASE, ("injector", "set_half", component(SetHalf)),
                             ("injector", "double", component(Double)))
    sim = simulation(registry, injectors=order)
    sim.reset()
    sim.step_epoch()
    ctx = sim.last_context
    assert np.all(ctx.observed["humans"].col("fatigue") == expected)
    # the truth is untouched: F_f of the initial working hours, on each human's own curve
    h = sim.sim.groups["humans"]
    assert np.array_equal(sim.last_truth["humans"].col("fatigue"),
                          fatigue.individual(h.t0_h, h.fatigue_onset, h.fatigue_slope, 0.4))


def test_ata_reconstruct_outputs_reach_the_policies():
    calls = []

    class Doubler:
        @hookimpl
        def ata_reconstruct(self, sim, obs, inherent, out):
            calls.append(sorted(inherent))
            out["fatigue_x2"] = 2 * obs["humans"].col("fatigue")[..., None]

    registry = registry_with(BASE, ("reconstructor", "doubler", component(Doubler)))
    sim = simulation(registry, reconstructors=["identity", "doubler"])
    sim.reset()
    sim.step_epoch()
    ctx = sim.last_context
    assert calls == [["humans", "robots", "tasks"]]
    assert sorted(ctx.reconstructed) == ["fatigue_x2", "humans", "robots", "tasks"]
    assert np.array_equal(ctx.reconstructed["fatigue_x2"][..., 0],
                          2 * ctx.observed["humans"].col("fatigue"))


# --- decisions ---------------------------------------------------------------------------------

def test_ata_initial_allocation_is_the_allocation_in_force():
    class RoundRobin:
        @hookimpl
        def ata_initial_allocation(self, ctx):
            B, P = ctx.reallocatable.shape
            robot = np.broadcast_to(np.arange(P) % ctx.sizes.robots, (B, P)).copy()
            return Allocation(robot, np.full((B, P), -1), np.full((B, P), 1))

    registry = registry_with(BASE, ("policy", "round_robin", component(RoundRobin)))
    sim = simulation(registry, initial="round_robin")
    sim.run()
    assert sim.sim.allocation.robot.tolist() == [[0, 1, 0, 1, 0, 1]] * 2
    assert sim.sim.allocation.classifier.tolist() == [[1] * 6] * 2
    assert sim.sim.record.allocations[:, 0, :, 0].tolist() == [[0, 1, 0, 1, 0, 1]] * 2


def test_ata_initial_allocation_must_return_an_allocation():
    class Nothing:
        @hookimpl
        def ata_initial_allocation(self, ctx):
            return None

    registry = registry_with(BASE, ("policy", "nothing", component(Nothing)))
    sim = simulation(registry, initial="nothing")
    sim.reset()
    with pytest.raises(ContractError, match="initial policy 'nothing' returned NoneType, not an "
                                        "Allocation"):
        sim.step_epoch()


def test_a_component_without_the_slot_hook_cannot_fill_the_slot():
    class NoDecision:
        pass

    registry = registry_with(BASE, ("policy", "no_decision", component(NoDecision)))
    with pytest.raises(MissionError, match="component 'no_decision' cannot fill this slot: it "
                                           "implements no ata_initial_allocation"):
        simulation(registry, initial="no_decision")


class Scenario0AtEpoch2:
    """Reallocate scenario 0 at epoch 2 only; remembers the epochs it was asked at."""

    def __init__(self):
        self.asked: list[int] = []

    @hookimpl
    def ata_should_reallocate(self, ctx):
        self.asked.append(ctx.epoch)
        return np.array([ctx.epoch == 2] + [False] * (ctx.reallocatable.shape[0] - 1))


class AllToRobot1:
    """Reallocation: every task to robot 1; remembers what it was called with."""

    def __init__(self):
        self.calls: list[tuple] = []

    @hookimpl
    def ata_reallocate(self, ctx, active):
        self.calls.append((ctx.epoch, active.tolist(), ctx.reallocatable.copy(),
                           ctx.previous.copy()))
        B, P = ctx.reallocatable.shape
        return Allocation(np.ones((B, P), int), np.full((B, P), -1), np.full((B, P), -1))


def four_epochs(*extra):
    condition, policy = Scenario0AtEpoch2(), AllToRobot1()
    registry = registry_with(BASE, ("condition", "scenario_0_at_2", lambda s, m: condition),
                             ("policy", "all_to_robot_1", lambda s, m: policy), *extra)
    sim = simulation(registry, mission={"horizon_s": 240.0}, condition="scenario_0_at_2",
                     reallocation="all_to_robot_1",
                     injectors=[name for _, name, _ in extra])
    sim.run()
    return sim, condition, policy


def test_ata_should_reallocate_decides_when():
    sim, condition, policy = four_epochs()
    assert condition.asked == [1, 2, 3]                      # never at t = 0
    assert sim.sim.record.reallocated.tolist() == [[False, False, True, False],
                                                   [False, False, False, False]]
    assert [c[:2] for c in policy.calls] == [(2, [True, False])]


def test_ata_reallocate_changes_only_active_scenarios_and_reallocatable_tasks():
    sim, _, policy = four_epochs()
    ((epoch, active, reallocatable, previous),) = policy.calls
    robots = sim.sim.record.allocations[:, :, :, 0]
    assert np.array_equal(robots[0, 2], np.where(reallocatable[0], 1, previous.robot[0]))
    assert np.array_equal(robots[1, 2], previous.robot[1])   # inactive: kept
    assert np.array_equal(robots[:, 3], robots[:, 2])
    assert robots[0, 2].tolist() != robots[0, 1].tolist()    # something did change


def test_ata_allocation_changed_gets_the_changed_tasks():
    class Changes:
        def __init__(self, settings, mission):
            self.seen = []

        @hookimpl
        def ata_allocation_changed(self, sim, changed):
            self.seen.append((sim.epoch, changed.copy(), sim.allocation.robot.copy()))

    instances = []

    def factory(settings, mission):
        instances.append(Changes(settings, mission))
        return instances[-1]

    sim, _, policy = four_epochs(("injector", "changes", factory))
    (changes,) = instances
    ((_, _, reallocatable, previous),) = policy.calls
    assert [s[0] for s in changes.seen] == [0, 2]
    assert changes.seen[0][1].all()                           # t = 0: every task
    expected = np.zeros((2, 6), dtype=bool)
    expected[0] = reallocatable[0] & (previous.robot[0] != 1)
    assert np.array_equal(changes.seen[1][1], expected)
    assert np.array_equal(changes.seen[1][2], sim.sim.record.allocations[:, 2, :, 0])


# --- tick --------------------------------------------------------------------------------------

def test_routing_is_a_setting_of_the_robot_model():
    from ata.plugins.robots import ROUTINGS, nearest
    registry = registry_with(BASE)
    sim = simulation(registry)
    model = sim.pm.get_plugin("robot_model:robot")
    assert model.next_targets is nearest and set(ROUTINGS) == {"nearest"}
    raw = {"mission": dict(SMALL), "robot": {"routing": "farthest"},
           "components": {"initial": "to_robot_0", "reallocation": "to_robot_0"}}
    with pytest.raises(MissionError, match=r"\[robot\] key 'routing': 'farthest' is not "
                                           r"allowed; choose one of 'nearest'"):
        validate(raw, registry)


def test_ata_advance_covers_the_horizon_tick_by_tick():
    class Stopwatch:
        def __init__(self):
            self.spans = []

        @hookimpl
        def ata_advance(self, t0, t1):
            self.spans.append((t0, t1))

    watch = Stopwatch()
    registry = registry_with(BASE, ("injector", "stopwatch", lambda s, m: watch))
    simulation(registry, mission={"horizon_s": 180.0}, injectors=["stopwatch"]).run()
    assert watch.spans == [(30.0 * k, 30.0 * (k + 1)) for k in range(6)]


# --- epoch end and episode end -----------------------------------------------------------------

def test_ata_epoch_end_records_each_epoch():
    class Points:
        @hookimpl
        def ata_epoch_end(self, sim, epoch):
            sim.record.r_perf[:, epoch] += 10.0 * (epoch + 1)

    plain = simulation(registry_with(BASE)).run()
    record = simulation(registry_with(BASE, ("injector", "points", component(Points))),
                        injectors=["points"]).run()
    assert (record.r_perf - plain.r_perf).tolist() == [[10.0, 20.0], [10.0, 20.0]]
    assert (record.total - plain.total).tolist() == [30.0, 30.0]


def test_ata_episode_end_metrics_reach_the_results():
    class Answer:
        @hookimpl
        def ata_episode_end(self, sim):
            sim.record.metrics["answer"] = 40.0 + sim.rng.scenario_ids

    registry = registry_with(BASE, ("injector", "answer", component(Answer)))
    mission = simulation(registry, injectors=["answer"]).mission.replace(scenarios=3,
                                                                        batch_size=2)
    result = run_mission(Session(mission=mission, registry=registry, pm=None))
    assert result.metrics["answer"].tolist() == [40.0, 41.0, 42.0]
    assert [row["answer"] for row in result.rows()] == [40.0, 41.0, 42.0]
