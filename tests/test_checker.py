"""The plugin checker (ata.testing.check_component): built-ins pass, broken components fail."""

import numpy as np
import pytest

from ata import hookimpl
from ata.core.state import Allocation
from ata.plugins.conditions import Always, Never, OnEvent
from ata.plugins.policies.greedy import GreedyPolicy
from ata.plugins.policies.random_policy import RandomPolicy
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
