"""Team state with one owner per group: each model owns typed state, other components see it
read-only, and work passes between models through queues (issue: a core that is only the
kernel)."""

from __future__ import annotations

import numpy as np
import pytest

from ata import hookimpl
from ata.core.kernel import Simulation
from ata.core.queues import Queue, last_per_key
from ata.core.state import ReadOnlyState
from ata.session import BASELINE_MISSION, load_session
from ata.plugins.humans import HumanState
from ata.plugins.robots import RobotState
from ata.plugins.tasks import TaskState


def test_queue_takes_every_row_in_the_order_put_then_is_empty():
    q = Queue("demo")
    assert q.take() is None and len(q) == 0
    q.put(b=[0, 1], x=[10.0, 11.0])
    q.put(b=[2], x=12.0)
    q.put(b=np.zeros(0, dtype=int), x=np.zeros(0))      # nothing: not kept
    assert len(q) == 3
    rows = q.take()
    assert rows["b"].tolist() == [0, 1, 2] and rows["x"].tolist() == [10.0, 11.0, 12.0]
    assert q.take() is None and len(q) == 0


def test_queue_refuses_other_columns_and_ragged_rows():
    q = Queue("demo")
    q.put(b=[0], x=[1.0])
    with pytest.raises(ValueError, match="takes columns b, x"):
        q.put(b=[0], y=[1.0])
    with pytest.raises(ValueError, match="column 'x' has shape"):
        q.put(b=[0, 1, 2], x=[1.0, 2.0])


def test_last_per_key_keeps_the_latest_row_of_each_key():
    b = np.array([0, 1, 0, 0, 1])
    r = np.array([2, 2, 3, 2, 2])
    assert sorted(last_per_key(b, r).tolist()) == [2, 3, 4]
    assert last_per_key(np.zeros(0, int), np.zeros(0, int)).size == 0
    assert last_per_key(np.array([4]), np.array([1])).tolist() == [0]


def test_last_per_key_orders_by_the_keys_as_a_lexicographic_sort_does():
    rng = np.random.default_rng(3)
    for n in (2, 7, 50):
        b, r = rng.integers(0, 4, n), rng.integers(0, 5, n)
        # reference: the last row of each (b, r) in (b, r) order
        last = {}
        for i, key in enumerate(zip(b.tolist(), r.tolist())):
            last[key] = i
        assert last_per_key(b, r).tolist() == [last[k] for k in sorted(last)]


def test_each_group_has_one_typed_owner_and_others_read_it_only():
    s = load_session(overrides=["mission.scenarios=2"])
    sim = Simulation(s.mission, s.registry, [0, 1])
    sim.reset()
    state = sim.sim
    assert isinstance(state.groups["tasks"], TaskState)
    assert isinstance(state.groups["humans"], HumanState)
    assert isinstance(state.groups["robots"], RobotState)
    view = state.group("robots")
    assert isinstance(view, ReadOnlyState)
    assert np.array_equal(view.fail_time, state.groups["robots"].fail_time)
    with pytest.raises(ValueError, match="read-only"):
        view.fail_time[0, 0] = 0.0
    with pytest.raises(AttributeError, match="written by its owner only"):
        view.fail_time = np.zeros(3)
    with pytest.raises(ValueError, match="has an owner already"):
        state.own("robots", object())
    with pytest.raises(KeyError, match="no group 'drones'"):
        state.group("drones")


def test_a_perturbation_that_writes_a_models_arrays_is_stopped():
    class Sabotage:
        @hookimpl
        def ata_setup(self, sim):
            sim.group("robots").fail_time[:] = 0.0

    s = load_session(overrides=["mission.scenarios=2"])
    sim = Simulation(s.mission, s.registry, [0, 1], overrides={"perturbations": Sabotage()})
    with pytest.raises(ValueError, match="read-only"):
        sim.reset()


class QueueSpy:
    """Counts the rows put into each queue over an episode (wraps Queue.put)."""

    def __init__(self, sim):
        self.rows: dict[str, int] = {}
        real = sim.sim.queue

        def queue(name):
            q = real(name)
            if not getattr(q, "_spied", False):
                put = q.put

                def counted(**columns):
                    n = max(np.atleast_1d(np.asarray(v)).shape[0] for v in columns.values())
                    self.rows[name] = self.rows.get(name, 0) + n
                    put(**columns)
                q.put, q._spied = counted, True
            return q
        sim.sim.queue = queue


def test_the_work_between_models_is_what_the_queues_carried():
    s = load_session(overrides=["mission.scenarios=8", "mission.uncertainty=high"])
    sim = Simulation(s.mission, s.registry, list(range(8)))
    spy = QueueSpy(sim)
    record = sim.run()
    t, h, r = (sim.sim.groups[g] for g in ("tasks", "humans", "robots"))
    captured = np.isfinite(t.capture_time)
    assert captured.sum() > 0
    assert spy.rows["tasks.captured"] == captured.sum() == r.visited.sum()
    human_cls = record.metrics["human_classifications"].sum()
    assert human_cls > 0
    # every human classification came back through tasks.classified; the ones still waiting at
    # the horizon never left the human model's pending list, or humans.classify itself (images
    # captured in the last tick, never taken)
    assert spy.rows["tasks.classified"] == human_cls
    waiting = np.isfinite(h.cls_ready).sum() + len(sim.sim.queues["humans.classify"])
    assert spy.rows["humans.classify"] == human_cls + waiting
    assert spy.rows["robots.failure"] == np.isfinite(r.fail_time).sum() > 0
    assert spy.rows["tasks.attribute_change"] == record.metrics["attribute_changes"].sum() > 0
    assert spy.rows.get("robots.leg_started", 0) > 0
    # the task and robot models took all their work by the end (the humans may be left with
    # items that came in the last tick, never started)
    for name in ("tasks.captured", "tasks.classified", "tasks.attribute_change",
                 "robots.failure", "robots.leg_started"):
        assert len(sim.sim.queues[name]) == 0, name


def test_a_context_carries_its_settings_and_generator_into_a_sub_batch_and_no_mission():
    s = load_session(str(BASELINE_MISSION), ["mission.scenarios=3", "mission.batch_size=3"])
    sim = Simulation(s.mission, s.registry, [0, 1, 2])
    sim.reset()
    ctx = sim.begin_epoch()
    sub = ctx.take(np.array([2]))
    assert sub.settings is ctx.settings and sub.channel is ctx.channel
    np.testing.assert_array_equal(sub.rng.uniform("x", 0, (4,)), ctx.rng.uniform("x", 0, (4,))[[2]])
    np.testing.assert_array_equal(sub.reallocatable, ctx.reallocatable[[2]])
    with pytest.raises(AttributeError, match="DecisionContext has no field 'params': the "
                                             "decision context carries no mission"):
        ctx.params
    with pytest.raises(AttributeError, match="has no attribute 'mission'"):
        ctx.mission
