"""The holes an author who means well can fall into, closed: what a decision-maker receives is a
read-only copy, it gets no world object from any hook, a published value cannot carry live
state, and the checker catches a policy that reads the hidden fatigue curves or draws from a
global generator, naming the cause."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pytest

from _support import running_world
from ata import hookimpl
from ata.core.errors import ContractError
from ata.core.kernel import Simulation
from ata.core.rng import BatchRNG
from ata.core.state import Allocation, EpisodeOutcome, SimState, read_only
from ata.session import BASELINE_MISSION, load_session
from ata.plugins.humans import HumanModel
from ata.plugins.policies.greedy import GreedyPolicy
from ata.testing import check_component


def session(*extra: str):
    return load_session(str(BASELINE_MISSION), [
        "mission.setting='custom'", "mission.humans=3", "mission.robots=4", "mission.tasks=10",
        "mission.horizon_s=600.0", "mission.scenarios=3", "mission.uncertainty='high'",
        "components.condition='always'", *extra])


def started(policy_class, *slots):
    """A simulation of `session()` with one instance of `policy_class` in `slots`, its first
    epoch run."""
    s = session()
    policy = policy_class(GreedyPolicy.Settings(), s.mission)
    sim = Simulation(s.mission, s.registry, [0, 1, 2],
                     overrides={slot: policy for slot in slots})
    sim.reset()
    sim.step_epoch()
    return sim


class EditsInPlace(GreedyPolicy):
    """Reallocates by writing into the allocation in force and handing it back."""

    @hookimpl
    def ata_reallocate(self, ctx, active):
        ctx.previous.robot[:] = 0
        return ctx.previous


def test_a_policy_editing_the_allocation_in_force_in_place_is_stopped():
    sim = started(EditsInPlace, "initial", "reallocation")
    before = sim.sim.allocation.stack().copy()
    with pytest.raises(ValueError, match="read-only"):
        sim.step_epoch()
    np.testing.assert_array_equal(sim.sim.allocation.stack(), before)


class KeepsWhatItReturned(GreedyPolicy):
    """Returns its own arrays, then edits them at the next condition: the kernel copied them."""

    returned: Allocation | None = None

    @hookimpl
    def ata_initial_allocation(self, ctx):
        self.returned = super().ata_initial_allocation(ctx)
        return self.returned

    @hookimpl
    def ata_should_reallocate(self, ctx):
        self.returned.robot[:] = 0
        return np.zeros(ctx.reallocatable.shape[0], dtype=bool)


def test_a_policy_editing_an_allocation_it_returned_changes_nothing_in_force():
    sim = started(KeepsWhatItReturned, "initial", "condition")
    before = sim.sim.allocation.stack().copy()
    assert (before[..., 0] != 0).any()
    sim.step_epoch()
    np.testing.assert_array_equal(sim.sim.allocation.stack(), before)


def test_every_array_a_decision_maker_receives_is_a_read_only_copy():
    s = session()
    sim = Simulation(s.mission, s.registry, [0, 1, 2])
    sim.reset()
    sim.step_epoch()
    ctx = sim.begin_epoch()
    arrays = [ctx.previous.robot, ctx.previous.navigator, ctx.previous.classifier,
              ctx.reallocatable, *ctx.reconstructed.values()]
    for obs in (ctx.inherent, ctx.observed):
        arrays += [t.features for t in obs.values()] + [t.mask for t in obs.values()]
        arrays += [t.holds for t in obs.values() if t.holds is not None]
        arrays += list(obs.extras.values())
    assert len(arrays) > 10
    assert not any(a.flags.writeable for a in arrays)
    assert not np.shares_memory(ctx.previous.robot, sim.sim.allocation.robot)


class EndsWithTheWorld(GreedyPolicy):
    """A decision-maker implementing ata_episode_end, the hook that hands a component `sim`."""

    @hookimpl
    def ata_episode_end(self, sim):
        self.rng = sim.rng


def test_a_decision_maker_gets_no_world_at_the_end_of_an_episode():
    s = session()
    with pytest.raises(ContractError, match="implements ata_episode_end, which hands it the "
                                            "world's state and generator.*through "
                                            "ata_episode_scored"):
        Simulation(s.mission, s.registry, [0], overrides={"initial": EndsWithTheWorld(
            GreedyPolicy.Settings(), s.mission)})


class Scored(GreedyPolicy):
    """Learns each episode's score the honest way, and adds a column."""

    outcomes: list = []

    @hookimpl
    def ata_episode_scored(self, episode):
        Scored.outcomes.append(episode)
        episode.metrics["my_column"] = episode.total * 0 + 1.0


def test_the_end_of_an_episode_a_decision_maker_sees_holds_no_world_object():
    s = session()
    Scored.outcomes = []
    policy = Scored(GreedyPolicy.Settings(), s.mission)
    sim = Simulation(s.mission, s.registry, [0, 1, 2],
                     overrides={"initial": policy, "reallocation": policy})
    record = sim.run()
    (outcome,) = Scored.outcomes
    assert isinstance(outcome, EpisodeOutcome)
    np.testing.assert_array_equal(outcome.total, record.total)
    assert not outcome.r_perf.flags.writeable
    assert record.metrics["my_column"].tolist() == [1.0, 1.0, 1.0]
    fields = [getattr(outcome, f) for f in vars(outcome)]
    assert not any(isinstance(x, (SimState, BatchRNG, Simulation)) for x in fields)


@dataclass(frozen=True)
class TrueFatigue:
    """Frozen, but its array is the human model's own: every policy would read the truth."""

    onset: np.ndarray


class PublishesALiveArray(HumanModel):
    @hookimpl
    def ata_setup(self, sim):
        super().ata_setup(sim)
        sim.publish(TrueFatigue(self.state.fatigue_onset))


class PublishesACopy(HumanModel):
    @hookimpl
    def ata_setup(self, sim):
        super().ata_setup(sim)
        sim.publish(TrueFatigue(read_only(self.state.fatigue_onset[:, :1] * 0)))


def test_a_team_model_publishing_a_live_array_fails_the_check():
    with pytest.raises(AssertionError, match="broke the kernel's contract: published "
                                             "TrueFatigue: onset is a live array"):
        check_component("human_model", PublishesALiveArray)
    check_component("human_model", PublishesACopy)


def test_a_published_list_or_object_is_refused():
    from ata.core.channel import Channel
    for value, what in ((TrueFatigue([1, 2]), "onset is a list"),
                        (TrueFatigue(np.zeros(2)), "onset is a live array")):
        with pytest.raises(ContractError, match=what):
            Channel().publish(value)


class ReadsTheFatigueCurves:
    """Finds the human model's state up the call stack and splits the POIs' classifications
    among the humans in proportion to when each one's fatigue sets in: curves no observation
    shows at t = 0. (A split, not one human, so that redrawing the curves moves some POI almost
    surely: the human whose fatigue sets in last stays the same one redraw in two with two
    humans, and six scenarios let that pass the check in about one run in two hundred.)"""

    def __init__(self, settings, mission):
        pass

    @hookimpl
    def ata_initial_allocation(self, ctx):
        onset = np.asarray(running_world().groups["humans"].fatigue_onset, dtype=float)
        B, P = ctx.reallocatable.shape
        edges = np.floor(np.cumsum(onset, axis=1) / onset.sum(axis=1, keepdims=True) * P)
        share = (np.arange(P)[None, :, None] >= edges[:, None, :]).sum(axis=2)
        classifier = np.minimum(share, onset.shape[1] - 1).astype(np.int64)
        return Allocation(np.arange(B * P).reshape(B, P) % ctx.sizes.robots,
                          np.full((B, P), -1), classifier)


def test_a_policy_reading_the_true_fatigue_curves_fails_the_check():
    with pytest.raises(AssertionError, match=r"decides from what it cannot observe: .* with "
                                             r"the unseen draws \(humans\.fatigue_onset\) "
                                             r"drawn again"):
        check_component("policy", ReadsTheFatigueCurves)


class GlobalRandom:
    """Draws its robots from numpy's global generator: not peeking, but not reproducible."""

    def __init__(self, settings, mission):
        pass

    @hookimpl
    def ata_initial_allocation(self, ctx):
        B, P = ctx.reallocatable.shape
        return Allocation(np.random.randint(0, ctx.sizes.robots, (B, P)), np.full((B, P), -1),
                          np.full((B, P), -1))


def test_a_policy_drawing_from_the_global_generator_is_told_it_is_not_deterministic():
    with pytest.raises(AssertionError) as err:
        check_component("policy", GlobalRandom)
    message = str(err.value)
    assert "is not deterministic: run twice on the same scenarios, with nothing redrawn" in message
    assert "numpy's global np.random" in message and "cannot observe" not in message
