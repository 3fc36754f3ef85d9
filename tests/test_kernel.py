"""The kernel's contract: hook order within an epoch, the allocation it keeps legal, and the
record and event trace it keeps. Tiny hand-built scenarios; inline test components passed as
slot overrides; expected values worked out by hand in the comments.

Conventions as in test_dynamics.py: robots start at the base (1000, 1000); kind 1 = ground,
difficulty 0 = low (15 points); quality 1 = Medium; robot type 0 = UAV (8 m/s).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from _support import assert_trace
from ata.session import BASELINE_MISSION
from ata import hookimpl
from ata.core.errors import ContractError
from ata.core.kernel import Simulation
from ata.session import load_session
from ata.core.state import Allocation

BASE = 1000.0


# --- inline components and helpers ----------------------------------------------------------------

def alloc(shape, robot, navigator, classifier):
    return Allocation(*(np.broadcast_to(np.asarray(x, dtype=np.int64), shape).copy()
                        for x in (robot, navigator, classifier)))


class Fixed:
    """Allocate fixed per-POI triples at t = 0 and at every reallocation."""

    def __init__(self, robot, navigator, classifier):
        self.triples = (robot, navigator, classifier)
        self.calls = []

    @hookimpl
    def ata_initial_allocation(self, ctx):
        self.calls.append(("initial", ctx.epoch))
        return alloc(ctx.reallocatable.shape, *self.triples)

    @hookimpl
    def ata_reallocate(self, ctx, active):
        self.calls.append(("reallocate", ctx.epoch, active.tolist()))
        return alloc(ctx.reallocatable.shape, *self.triples)


class Condition:
    """Reallocate the scenarios listed for each epoch: {epoch: [bool per scenario]}."""

    def __init__(self, plan, calls=None):
        self.plan = plan
        self.calls = [] if calls is None else calls

    @hookimpl
    def ata_should_reallocate(self, ctx):
        self.calls.append(("condition", ctx.epoch))
        return np.asarray(self.plan.get(ctx.epoch, [False] * ctx.reallocatable.shape[0]))


def session(*, humans=1, robots=1, tasks=2, batch=1, condition="never", extra=()):
    """A tiny mission with no uncertainty and free reallocation (the re-tasking cost of the model
    section 3a has its own tests in test_dynamics.py)."""
    return load_session(str(BASELINE_MISSION), ["mission.setting='custom'", f"mission.humans={humans}",
                               "human.rebrief_s=0", "robot.replan_s=0",
                               f"mission.robots={robots}", f"mission.tasks={tasks}",
                               "mission.uncertainty='none'", f"mission.scenarios={batch}",
                               f"mission.batch_size={batch}", f"components.condition='{condition}'",
                               *extra])


def simulation(s, overrides, batch=1, trace=True):
    return Simulation(s.mission, s.registry, list(range(batch)), trace=trace,
                      overrides=overrides)


def place(sim, tasks, types=None):
    """tasks: (dx, dy) per POI, all ground/low, outcome_u 0 (every classification is won)."""
    t, r = sim.sim.groups["tasks"], sim.sim.groups["robots"]
    for p, (dx, dy) in enumerate(tasks):
        t.pos[:, p] = (BASE + dx, BASE + dy)
        t.est_kind[:, p] = t.true_kind[:, p] = 1
        t.est_diff[:, p] = t.true_diff[:, p] = 0
        t.outcome_u[:, p] = 0.0
    types = [0] * r.type.shape[1] if types is None else types
    r.type[:] = types
    r.speed[:] = np.where(np.asarray(types) == 0, 8.0, 3.0)


# --- hook order -----------------------------------------------------------------------------------

class Recorder:
    """Fills the injector slot; records every phase hook it is called on."""

    def __init__(self, calls):
        self.calls = calls

    @hookimpl
    def ata_setup(self, sim):
        self.calls.append(("setup", sorted(sim.groups)))

    @hookimpl
    def ata_inherent(self, sim, inherent):
        self.calls.append(("inherent", sorted(inherent)))

    @hookimpl
    def ata_observe(self, sim, obs):
        self.calls.append(("observe", sim.epoch, sim.now, sorted(obs)))

    @hookimpl
    def ata_inject(self, sim, obs):
        self.calls.append(("inject", sim.epoch))

    @hookimpl
    def ata_reconstruct(self, sim, obs, inherent, out):
        self.calls.append(("reconstruct", sim.epoch, sorted(out)))

    @hookimpl
    def ata_allocation_changed(self, sim, changed):
        self.calls.append(("changed", sim.epoch, int(changed.sum())))

    @hookimpl
    def ata_advance(self, sim, t0, t1):
        self.calls.append(("advance", t0, t1))

    @hookimpl
    def ata_epoch_end(self, sim, epoch):
        self.calls.append(("epoch_end", epoch))

    @hookimpl
    def ata_episode_end(self, sim):
        self.calls.append(("episode_end",))


class RecordingPolicy:
    """Initial: everything to robot 0, auto, onboard; at a reallocation, every POI to human 0 as
    classifier. Records what it is called with."""

    def __init__(self, calls):
        self.calls = calls

    @hookimpl
    def ata_initial_allocation(self, ctx):
        self.calls.append(("initial", ctx.epoch, ctx.time, ctx.previous is None,
                           sorted(ctx.reconstructed)))
        return alloc(ctx.reallocatable.shape, 0, -1, -1)

    @hookimpl
    def ata_reallocate(self, ctx, active):
        self.calls.append(("reallocate", ctx.epoch, active.tolist(),
                           ctx.previous.stack().tolist()))
        return alloc(ctx.reallocatable.shape, 0, -1, 0)


def test_hook_call_order_within_epochs_and_episode():
    # The default mission lists four injectors; one override instance fills the whole list and
    # is registered once, so each phase calls it once. The robot barely moves (0.01 m/s), so at
    # t = 60 its first leg is under way and the other POI is still reallocatable: the
    # reallocation at epoch 1 changes exactly one POI. Three epochs: 0, 1 (reallocate), 2 (not).
    calls = []
    s = session(extra=["mission.horizon_s=180", "robot.uav_speed=0.01", "robot.ugv_speed=0.01"])
    policy = RecordingPolicy(calls)
    sim = simulation(s, {"injectors": Recorder(calls), "initial": policy,
                         "reallocation": policy, "condition": Condition({1: [True]}, calls)})
    record = sim.run()
    assert record is sim.sim.record

    def ticks(k):
        return [("advance", 60.0 * k + 10.0 * j, 60.0 * k + 10.0 * (j + 1)) for j in range(6)]

    groups = ["humans", "robots", "tasks"]
    expected = [
        # the models run before the injector slot: their groups and tables exist already
        ("setup", groups), ("inherent", groups),
        ("observe", 0, 0.0, groups), ("inject", 0),
        # the recorder (an injector) runs before the identity reconstructor fills `out`
        ("reconstruct", 0, []),
        ("initial", 0, 0.0, True, groups), ("changed", 0, 2), *ticks(0), ("epoch_end", 0),
        ("observe", 1, 60.0, groups), ("inject", 1), ("reconstruct", 1, []),
        ("condition", 1), ("reallocate", 1, [True], [[[0, -1, -1], [0, -1, -1]]]),
        ("changed", 1, 1), *ticks(1), ("epoch_end", 1),
        # epoch 2: the condition says no: no reallocation, no change
        ("observe", 2, 120.0, groups), ("inject", 2), ("reconstruct", 2, []),
        ("condition", 2), *ticks(2), ("epoch_end", 2),
        ("episode_end",)]
    assert calls == expected
    np.testing.assert_array_equal(record.reallocated, [[False, True, False]])
    # exactly one of the two POIs (the one whose leg was not under way) took the new classifier
    assert sorted(record.allocations[0, 1, :, 2].tolist()) == [-1, 0]
    np.testing.assert_array_equal(record.allocations[0, 2], record.allocations[0, 1])
    assert sim.sim.trace == [("allocate", 0, 1), ("reallocate", 1, 1, 1)]


def test_one_policy_instance_can_fill_the_initial_and_the_reallocation_slot():
    policy = Fixed([0, 0], [-1, -1], [-1, -1])
    s = session(condition="always", extra=["mission.horizon_s=180"])
    sim = simulation(s, {"initial": policy, "reallocation": policy})
    sim.run()
    assert policy.calls == [("initial", 0), ("reallocate", 1, [True]), ("reallocate", 2, [True])]
    assert [e for e in sim.sim.trace if e[0] != "capture"] == [
        ("allocate", 0, 1), ("reallocate", 1, 1, 0), ("reallocate", 2, 1, 0)]


def test_no_trace_unless_asked():
    s = session(extra=["mission.horizon_s=60"])
    sim = simulation(s, {"initial": Fixed([0, 0], [-1, -1], [-1, -1])}, trace=False)
    sim.run()
    assert sim.sim.trace is None


# --- malformed decisions --------------------------------------------------------------------------

class Bad:
    """Returns the given allocation maker's result (for B, P) at t = 0 or at a reallocation."""

    def __init__(self, make):
        self.make = make

    @hookimpl
    def ata_initial_allocation(self, ctx):
        return self.make(*ctx.reallocatable.shape)

    @hookimpl
    def ata_reallocate(self, ctx, active):
        return self.make(*ctx.reallocatable.shape)


MALFORMED = [
    (lambda B, P: alloc((B, P + 1), 0, -1, -1), r"robot has shape \(1, 3\), expected \(1, 2\)"),
    (lambda B, P: Allocation(np.zeros((B, P), int), np.full((P,), -1), np.full((B, P), -1)),
     r"navigator has shape \(2,\), expected \(1, 2\)"),
    (lambda B, P: alloc((B, P), [0, 1], -1, -1), r"robot values must lie in \[0, 1\)"),
    (lambda B, P: alloc((B, P), 0, [-1, -2], -1), r"navigator values must lie in \[-1, 1\)"),
    (lambda B, P: alloc((B, P), 0, -1, [1, -1]), r"classifier values must lie in \[-1, 1\)"),
]


@pytest.mark.parametrize("make, message", MALFORMED)
def test_malformed_initial_allocation_raises_a_value_error_naming_the_slot(make, message):
    # one human, one robot, two POIs: robot must be 0, navigator and classifier -1 or 0
    sim = simulation(session(), {"initial": Bad(make)})
    sim.reset()
    with pytest.raises(ContractError, match=r"^initial policy 'Bad': " + message):
        sim.step_epoch()
    assert sim.sim.allocation is None


@pytest.mark.parametrize("make, message", MALFORMED)
def test_malformed_reallocation_raises_a_value_error_naming_the_slot(make, message):
    sim = simulation(session(condition="always"),
                     {"initial": Fixed([0, 0], [-1, -1], [-1, -1]), "reallocation": Bad(make)})
    sim.reset()
    sim.step_epoch()
    with pytest.raises(ContractError, match=r"^reallocation policy 'Bad': " + message):
        sim.step_epoch()
    # the allocation in force is untouched
    np.testing.assert_array_equal(sim.sim.allocation.stack(), [[[0, -1, -1], [0, -1, -1]]])


def test_a_policy_returning_no_allocation_breaks_the_contract():
    sim = simulation(session(), {"initial": Bad(lambda B, P: (np.zeros((B, P)),) * 3)})
    sim.reset()
    with pytest.raises(ContractError, match="initial policy 'Bad' returned tuple, not an "
                                            "Allocation"):
        sim.step_epoch()


def test_an_allocation_of_floats_is_refused_not_truncated():
    # 0.9 would silently become robot 0 under astype(int)
    sim = simulation(session(), {"initial": Bad(lambda B, P: Allocation(
        np.full((B, P), 0.9), np.full((B, P), -1), np.full((B, P), -1)))})
    sim.reset()
    with pytest.raises(ContractError, match=r"^initial policy 'Bad': robot has dtype float64; "
                                            "an allocation holds integer indices"):
        sim.step_epoch()
    assert sim.sim.allocation is None


def test_a_condition_of_the_wrong_shape_raises_a_value_error():
    sim = simulation(session(), {"initial": Fixed([0, 0], [-1, -1], [-1, -1]),
                                 "condition": Condition({1: [True, True]})})
    sim.reset()
    sim.step_epoch()
    with pytest.raises(ContractError, match=r"condition policy 'Condition' returned shape \(2,\), "
                                         r"expected \(1,\)"):
        sim.step_epoch()


# --- the allocation the kernel keeps --------------------------------------------------------------

def test_reallocation_keeps_committed_and_captured_triples_and_inactive_scenarios():
    # Two identical scenarios, one UAV, one human (medium skill), three POIs (ground, low):
    #   POI 0: 80 m east: captured at 13;
    #   POI 1: 560 m east: from POI 0 480 m, leg 13 .. 13 + 60 + 3 = 76 (under way at t = 60);
    #   POI 2: 800 m west: from POI 0 880 m (so not the nearest after POI 0): open at t = 60.
    # At epoch 1 the condition reallocates scenario 0 only, and the policy asks for every POI
    # to be navigated and classified by human 0. Only POI 2 of scenario 0 may change.
    policy = Fixed([0, 0, 0], [0, 0, 0], [0, 0, 0])
    sim = simulation(session(tasks=3, batch=2),
                     {"initial": Fixed([0, 0, 0], [-1, -1, -1], [-1, -1, -1]),
                      "reallocation": policy, "condition": Condition({1: [True, False]})}, batch=2)
    sim.reset()
    place(sim, [(80, 0), (560, 0), (-800, 0)])
    h = sim.sim.groups["humans"]
    h.skill[:] = 1
    h.eta[:], h.lam[:], h.t0_h[:] = 0.5, 0.5, 0.0
    for _ in range(5):
        sim.step_epoch()
    rec = sim.sim.record
    np.testing.assert_array_equal(rec.reallocated[:, :5], [[False, True, False, False, False],
                                                          [False] * 5])
    auto = [[0, -1, -1]] * 3
    np.testing.assert_array_equal(rec.allocations[0, 0], auto)
    np.testing.assert_array_equal(rec.allocations[0, 1], [[0, -1, -1], [0, -1, -1], [0, 0, 0]])
    np.testing.assert_array_equal(rec.allocations[0, 4], [[0, -1, -1], [0, -1, -1], [0, 0, 0]])
    np.testing.assert_array_equal(rec.allocations[1, :5], [auto] * 5)
    # the policy was asked once, for the batch, with active = [True, False]
    assert policy.calls == [("reallocate", 1, [True, False])]
    # Scenario 0: POI 2's leg is navigated by the human: robot free at 76, ready at 76, the
    # human (first item, no switch) takes it from 76: 1360 m / 8 + 3 = 173 -> 249; then the
    # human classifies it from 249 (same robot, no switch): t_bar[Medium, low] = 35 -> 284.
    # Scenario 1: the same leg driven autonomously, onboard classification at 249.
    assert_trace(sim.sim.trace, [
        ("allocate", 0, 2),
        ("capture", 13.0, 0, 0, 0, 1), ("capture", 13.0, 1, 0, 0, 1),
        ("reallocate", 1, 1, 1),
        ("capture", 76.0, 0, 0, 1, 1), ("capture", 76.0, 1, 0, 1, 1),
        ("start", "nav", 76.0, 0, 0, 0, 249.0),
        ("capture", 249.0, 0, 0, 2, 1), ("capture", 249.0, 1, 0, 2, 1),
        ("start", "classify", 249.0, 0, 0, 2, 284.0)])
    # points: POI 0 (13 s) and POI 1 (76 s) onboard, P_rc[Medium, low] = 0.6 > 0: 15 each;
    # POI 2: scenario 1 onboard at 249 (epoch 4), scenario 0 by the human at 284 (epoch 4)
    np.testing.assert_array_equal(rec.r_perf[:, :5], [[15, 15, 0, 0, 15], [15, 15, 0, 0, 15]])


def test_reallocation_that_changes_nothing_is_still_recorded():
    # 'always' with a policy that proposes the allocation in force: reallocated flags set at
    # every epoch from 1, zero changes in the trace, the allocation history constant.
    policy = Fixed([0, 0], [-1, -1], [-1, -1])
    sim = simulation(session(condition="always"),
                     {"initial": Fixed([0, 0], [-1, -1], [-1, -1]), "reallocation": policy})
    sim.reset()
    place(sim, [(80, 0), (160, 0)])
    for _ in range(3):
        sim.step_epoch()
    assert_trace(sim.sim.trace, [("allocate", 0, 1), ("capture", 13.0, 0, 0, 0, 1),
                                 ("capture", 26.0, 0, 0, 1, 1),
                                 ("reallocate", 1, 1, 0), ("reallocate", 2, 1, 0)])
    np.testing.assert_array_equal(sim.sim.record.reallocated[0, :4], [False, True, True, False])
    np.testing.assert_array_equal(sim.sim.record.allocations[0, :3], [[[0, -1, -1]] * 2] * 3)
    # both POIs captured at 13 and 26 (epoch 0): 15 points each
    assert sim.sim.record.r_perf[0, 0] == 30.0
    assert math.isclose(sim.sim.record.total[0], 30.0)


def test_a_reallocation_cancels_a_robots_wait_for_its_old_navigator():
    # Two UAVs and one human. Robot 0's leg to POI 0 (560 m east) is navigated by the human
    # from 0 to 73. Robot 1 waits for the same human for POI 1 (160 m west). At epoch 1 the
    # policy makes POI 1 autonomous: robot 1 stops waiting and leaves at once (t = 60):
    # 160/8 + 3 = 23 -> captures at 83, and the human never navigates it.
    policy = Fixed([0, 1], [0, -1], [-1, -1])
    sim = simulation(session(robots=2, condition="always"),
                     {"initial": Fixed([0, 1], [0, 0], [-1, -1]), "reallocation": policy})
    sim.reset()
    place(sim, [(560, 0), (-160, 0)])
    h = sim.sim.groups["humans"]
    h.skill[:] = 1
    for _ in range(3):
        sim.step_epoch()
    assert_trace(sim.sim.trace, [
        ("allocate", 0, 1), ("start", "nav", 0.0, 0, 0, 0, 73.0),
        ("reallocate", 1, 1, 1), ("capture", 73.0, 0, 0, 0, 1), ("capture", 83.0, 0, 1, 1, 1),
        ("reallocate", 2, 1, 0)])
    np.testing.assert_array_equal(sim.sim.record.allocations[0, :3, 1],
                                  [[1, 0, -1], [1, -1, -1], [1, -1, -1]])


def test_reallocatable_is_the_and_of_every_models_restriction():
    from ata.core.state import Observation
    obs = Observation()
    assert obs.reallocatable is None                      # no model has restricted it
    obs.restrict_reallocation(np.array([[True, True, False]]))
    obs.restrict_reallocation(np.array([[True, False, True]]))
    np.testing.assert_array_equal(obs.reallocatable, [[True, False, False]])
    copy = obs.copy()
    copy.restrict_reallocation(np.array([[False, False, False]]))
    np.testing.assert_array_equal(obs.reallocatable, [[True, False, False]])   # untouched
    np.testing.assert_array_equal(obs.take(np.array([0])).reallocatable, [[True, False, False]])


def test_reallocatable_is_read_off_what_the_rows_hold():
    from ata.core.state import Observation
    obs = Observation()
    obs.add("tasks", ["x"], np.zeros((2, 4, 1)))
    obs.add("robots", ["x"], np.zeros((2, 3, 1)))
    obs.hold("tasks", np.array([[-1, 1, -1, -1], [-1, -1, -1, 3]]), 4)     # captured
    obs.hold("robots", np.array([[2, -1, -1], [-1, 0, -1]]), 4)            # legs under way
    np.testing.assert_array_equal(obs.reallocatable, [[True, False, False, True],
                                                      [False, True, True, False]])
    obs.restrict_reallocation(np.array([[False, True, True, True], [True] * 4]))
    np.testing.assert_array_equal(obs.reallocatable, [[False, False, False, True],
                                                      [False, True, True, False]])
    # a stale row shows what it held when it was observed
    before = obs["robots"].copy()
    obs["robots"].holds = np.array([[-1, -1, -1], [-1, 2, -1]])
    obs["robots"].keep_rows(np.array([[True, False, False], [False, False, False]]), before)
    np.testing.assert_array_equal(obs["robots"].holds, [[2, -1, -1], [-1, 2, -1]])
    np.testing.assert_array_equal(obs.take(np.array([1])).reallocatable,
                                  [[True, True, False, False]])
    np.testing.assert_array_equal(obs.copy().reallocatable, obs.reallocatable)


class Everywhere(Fixed):
    """A policy that would also watch the world tick by tick."""

    @hookimpl
    def ata_advance(self, sim, t0, t1):
        pass


def test_a_decision_maker_implementing_a_world_hook_is_refused():
    with pytest.raises(ContractError, match="reallocation component 'Everywhere' implements "
                                            "ata_advance, which hands it the world's state"):
        simulation(session(), {"reallocation": Everywhere([0, 0], [-1, -1], [-1, -1])})


def test_a_change_a_stale_row_showed_possible_is_refused_counted_and_traced():
    # The scenario of the test above: at t = 60 POI 0 is captured and POI 1's leg is under
    # way. A stale observation shows all three open (as a stale task row and a stale robot row
    # would), and the policy moves every one to human 0: POI 2 changes, POIs 0 and 1 keep their
    # triples and count as refused.
    sim = simulation(session(tasks=3, condition="always"),
                     {"initial": Fixed([0, 0, 0], [-1, -1, -1], [-1, -1, -1]),
                      "reallocation": Fixed([0, 0, 0], [0, 0, 0], [0, 0, 0])})
    sim.reset()
    place(sim, [(80, 0), (560, 0), (-800, 0)])
    sim.sim.groups["humans"].skill[:] = 1
    sim.step_epoch()
    ctx = sim.begin_epoch()
    np.testing.assert_array_equal(ctx.reallocatable, [[False, False, True]])
    sim.shown = np.ones_like(ctx.reallocatable)       # what a stale S would show
    sim.end_epoch(*sim.decide(ctx))
    np.testing.assert_array_equal(sim.sim.record.allocations[0, 1],
                                  [[0, -1, -1], [0, -1, -1], [0, 0, 0]])
    assert ("refused", 1, 2) in sim.sim.trace
    while sim.sim.epoch < sim.sim.clock.n_epochs:
        sim.step_epoch()
    assert sim.end_episode().metrics["refused_changes"].tolist() == [2.0]
