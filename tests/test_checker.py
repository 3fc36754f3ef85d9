"""The plugin checker (ata.testing.check_component): built-ins pass, broken components fail,
and so does a decision-maker that peeks at the world's future."""

import numpy as np
import pytest

from _support import running_world
from ata import hookimpl
from ata.core.state import Allocation
from ata.plugins.ata_hrl.components import AttentionITA, AuxReconstructor, CTRPolicy
from ata.plugins.conditions import Always, Never, OnEvent
from ata.plugins.policies.greedy import GreedyPolicy
from ata.plugins.policies.keep import Keep
from ata.plugins.policies.milp import MilpPolicy
from ata.plugins.policies.random_policy import RandomPolicy
from ata.plugins.reconstructors import ArrivalReconstructor, IdentityReconstructor
from ata.plugins.tr_pomdp.policy import TRPOMDPPolicy
from ata.plugins.uncertainty.attribute_change import AttributeChange
from ata.plugins.uncertainty.fatigue_noise import FatigueNoise
from ata.plugins.uncertainty.latency import Latency
from ata.plugins.uncertainty.robot_failure import RobotFailure
from ata.testing import check_component


@pytest.mark.parametrize("kind, factory, settings", [
    ("injector", FatigueNoise, {"variance": 0.3}),
    ("perturbation", AttributeChange, {"probability": 0.5}),
    ("perturbation", RobotFailure, {"probability": 0.5}),
    ("injector", Latency, {"probability": 0.5}),
    ("policy", GreedyPolicy, None),
    ("policy", RandomPolicy, None),
    ("condition", Never, None),
    ("condition", Always, None),
    ("condition", OnEvent, None),
])
def test_builtins_pass(kind, factory, settings):
    check_component(kind, factory, settings=settings)


@pytest.mark.parametrize("kind, factory, settings", [
    ("policy", Keep, None),
    ("policy", MilpPolicy, None),
    ("policy", AttentionITA, None),
    ("policy", CTRPolicy, None),
    ("condition", CTRPolicy, None),
    ("policy", TRPOMDPPolicy, None),
    ("reconstructor", IdentityReconstructor, None),
    ("reconstructor", ArrivalReconstructor, None),
    ("reconstructor", AuxReconstructor, None),
])
def test_every_builtin_decision_maker_passes_the_integrity_check(kind, factory, settings):
    # (greedy, random and the conditions are checked above)
    check_component(kind, factory, settings=settings)


class SharedGeneratorNoise:
    """Breaks the contract: one generator for the whole batch."""

    def __init__(self, settings, mission):
        self.gen = np.random.default_rng(0)

    @hookimpl
    def ata_inject(self, sim, obs):
        obs["humans"].features[:] += self.gen.normal(size=obs["humans"].features.shape)


def test_batch_dependent_injector_fails():
    with pytest.raises(AssertionError, match="depends? on (the|its) batch"):
        check_component("injector", SharedGeneratorNoise)


class OutOfRangePolicy:
    def __init__(self, settings, mission):
        pass

    @hookimpl
    def ata_initial_allocation(self, ctx):
        B, P = ctx.reallocatable.shape
        robot = np.full((B, P), ctx.sizes.robots)          # one past the last robot
        return Allocation(robot, np.full((B, P), -1), np.full((B, P), -1))

    @hookimpl
    def ata_reallocate(self, ctx, active):
        return ctx.previous


def test_illegal_allocation_fails():
    with pytest.raises(AssertionError, match="robot values must lie in"):
        check_component("policy", OutOfRangePolicy)


class InitialOnly:
    """Robot 0 for every POI, autonomous, onboard: an initial allocation and nothing else."""

    def __init__(self, settings, mission):
        self.calls = 0

    @hookimpl
    def ata_initial_allocation(self, ctx):
        B, P = ctx.reallocatable.shape
        minus = np.full((B, P), -1)
        return Allocation(np.zeros((B, P), dtype=np.int64), minus, minus.copy())


def test_a_policy_that_only_makes_the_initial_allocation_can_be_checked():
    check_component("policy", InitialOnly)


class FloatInitial(InitialOnly):
    @hookimpl
    def ata_initial_allocation(self, ctx):
        alloc = super().ata_initial_allocation(ctx)
        return Allocation(alloc.robot + 0.7, alloc.navigator, alloc.classifier)


def test_an_allocation_of_floats_fails_the_check():
    with pytest.raises(AssertionError, match="robot has dtype float64"):
        check_component("policy", FloatInitial)


class ReallocateOnly:
    """Moves every reallocatable POI to robot 0: a reallocation without an initial allocation."""

    def __init__(self, settings, mission):
        pass

    @hookimpl
    def ata_reallocate(self, ctx, active):
        robot = np.where(ctx.reallocatable, 0, ctx.previous.robot)
        return Allocation(robot, ctx.previous.navigator, ctx.previous.classifier)


def test_a_policy_that_only_reallocates_can_be_checked():
    check_component("policy", ReallocateOnly)


def test_a_policy_with_no_decision_hook_fails_the_check():
    class Nothing:
        def __init__(self, settings, mission):
            pass

    with pytest.raises(AssertionError, match="implements neither ata_initial_allocation nor "
                                             "ata_reallocate"):
        check_component("policy", Nothing)


# --- peeking ------------------------------------------------------------------------------------

def outcome_allocation(ctx, u):
    """Robot 0 drives and classifies onboard every POI whose classification will succeed (its
    outcome uniform below 1/2, roughly), robot 1 with human 0 classifying the others."""
    B, P = ctx.reallocatable.shape
    good = u[:, :P] < 0.5
    return Allocation(np.where(good, 0, 1), np.full((B, P), -1), np.where(good, -1, 0))


class PeeksThroughTheKernel:
    """Deliberately peeking: finds the running Simulation up the call stack and reads the
    world's outcome stream, as no context lets it."""

    def __init__(self, settings, mission):
        pass

    @hookimpl
    def ata_initial_allocation(self, ctx):
        world = running_world().rng
        return outcome_allocation(ctx, world.uniform("tasks.outcome", 0, (ctx.sizes.tasks,)))


def test_a_policy_reading_the_outcome_stream_fails_the_integrity_check():
    with pytest.raises(AssertionError) as err:
        check_component("policy", PeeksThroughTheKernel)
    message = " ".join(str(err.value).split())
    assert message.startswith("policy 'under_test' decides from what it cannot observe: in "
                              "scenario 0, at epoch 0, its initial allocation for POI ")
    # its own decision changed the allocation in force, which it sees from epoch 1
    assert "with the unseen draws (tasks.outcome) drawn again; what it observed was the same " \
           "in both runs before epoch 1" in message


class PeeksThroughTheOldContext:
    """Written against the context of old, which carried the mission: rebuilds the world's
    generator from the root seed."""

    def __init__(self, settings, mission):
        pass

    @hookimpl
    def ata_initial_allocation(self, ctx):
        from ata.core.rng import BatchRNG
        seed = ctx.params["mission"].settings.seed
        world = BatchRNG(seed, np.arange(ctx.reallocatable.shape[0]))
        return outcome_allocation(ctx, world.uniform("tasks.outcome", 0, (ctx.sizes.tasks,)))


def test_a_policy_reading_the_seed_from_its_context_fails_with_a_clear_message():
    with pytest.raises(AssertionError, match="raised AttributeError: DecisionContext has no "
                                             "field 'params': the decision context carries no "
                                             "mission"):
        check_component("policy", PeeksThroughTheOldContext)


class PeeksAtSetup:
    """A policy implementing ata_setup, the hook that hands a component the world."""

    def __init__(self, settings, mission):
        self.u = None

    @hookimpl
    def ata_setup(self, sim):
        self.u = sim.rng.uniform("tasks.outcome", 0, (sim.sizes.tasks,))

    @hookimpl
    def ata_initial_allocation(self, ctx):
        return outcome_allocation(ctx, self.u)


def test_a_policy_implementing_a_world_hook_is_refused():
    with pytest.raises(AssertionError, match="broke the kernel's contract: initial component "
                                             "'under_test' implements ata_setup, which hands "
                                             "it the world's state and generator"):
        check_component("policy", PeeksAtSetup)


class DrawsFromAWorldStreamName:
    """Names the outcome stream in its own generator: honest, and blind to the outcomes."""

    def __init__(self, settings, mission):
        pass

    @hookimpl
    def ata_initial_allocation(self, ctx):
        return outcome_allocation(ctx, ctx.rng.uniform("tasks.outcome", 0, (ctx.sizes.tasks,)))


def test_a_policy_naming_a_world_stream_in_its_own_generator_passes():
    check_component("policy", DrawsFromAWorldStreamName)


class ReconstructsFromTheOutcomes:
    """A reconstructor that reads the outcomes through the kernel: its estimate changes."""

    def __init__(self, settings, mission):
        pass

    @hookimpl
    def ata_reconstruct(self, sim, obs, inherent, out):
        tasks = running_world().groups["tasks"]
        out["will_succeed"] = (tasks.outcome_u < 0.5)[..., None].astype(float)


def test_a_reconstructor_reading_the_outcomes_fails_the_integrity_check():
    with pytest.raises(AssertionError, match="reconstructor 'under_test' decides from what it "
                                             "cannot observe: in scenario 0, at epoch 0, its "
                                             "reconstructed 'will_succeed' at row "):
        check_component("reconstructor", ReconstructsFromTheOutcomes)


class ForeseesFailures:
    """A condition that reallocates an epoch before a robot fails, reading the failure times
    through the kernel: nothing it observes shows them yet."""

    def __init__(self, settings, mission):
        pass

    @hookimpl
    def ata_should_reallocate(self, ctx):
        fail = running_world().groups["robots"].fail_time
        soon = (fail > ctx.time) & (fail <= ctx.time + ctx.clock.epoch_s)
        return soon.any(axis=1)


def test_a_condition_foreseeing_failures_fails_the_integrity_check():
    with pytest.raises(AssertionError, match=r"condition 'under_test' decides from what it "
                                             r"cannot observe: in scenario \d+, at epoch \d+, "
                                             r"its condition was (True|False) as the world drew "
                                             r"it and (True|False) with the unseen draws "
                                             r"\(robot_failure\.\w+\) drawn again"):
        check_component("condition", ForeseesFailures)
