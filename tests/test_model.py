"""The domain library (ata/model) and the typed channel its constants travel by: the team models
publish their constants, policies read them from their context, a custom model is priced by what
it publishes, and one that publishes nothing makes greedy fail with an error naming the type."""

from __future__ import annotations

import numpy as np
import pytest

from ata import hookimpl
from ata.core.errors import ContractError
from ata.core.kernel import Simulation
from ata.core.state import Channel
from ata.session import BASELINE_MISSION, load_session
from ata.model.retask import RetaskCost, retask_cost
from ata.model.team import HumanConstants, RobotConstants
from ata.plugins.humans import HumanModel
from ata.plugins.robots import RobotModel

SMALL = ["mission.setting='custom'", "mission.humans=3", "mission.robots=4", "mission.tasks=12",
         "mission.scenarios=2", "mission.batch_size=2", "components.condition='always'"]


def test_a_channel_holds_one_value_per_type_and_names_the_missing_publisher():
    channel = Channel()
    human = HumanConstants(rebrief_s=5.0)
    channel.publish(human)
    assert channel.get(HumanConstants) is human
    with pytest.raises(ValueError, match="HumanConstants is published already"):
        channel.publish(HumanConstants())
    with pytest.raises(ContractError) as err:
        channel.get(RobotConstants)
    assert str(err.value) == ("no RobotConstants was published: the robot model (slot "
                              "robot_model) publishes it (sim.publish in ata_setup); published: "
                              "HumanConstants")

    class Wider(RobotConstants):
        """A custom robot model's constants: found when the base type is asked for."""

    wider = Wider(capture_s=4.0)
    channel.publish(wider)
    assert channel.get(RobotConstants) is wider


def test_the_team_models_hold_the_model_defaults_once():
    assert HumanModel(HumanModel.Settings(), None).constants == HumanConstants()
    assert RobotModel(RobotModel.Settings(), None).constants == RobotConstants()
    assert HumanConstants() == HumanConstants(0.4, 1.0, 300.0, 0.25, 0.1, 30.0, 20.0)
    assert RobotConstants() == RobotConstants(3.0, 10.0, (2.0 / 3.0, 1.0, 1.5))


def test_the_built_in_models_publish_their_settings_to_every_context():
    s = load_session(str(BASELINE_MISSION), [*SMALL, "human.rebrief_s=45", "human.window_s=120",
                                             "human.sa_drop=0.5", "robot.capture_s=5",
                                             "robot.replan_s=7"])
    sim = Simulation(s.mission, s.registry, [0, 1])
    sim.reset()
    human = HumanConstants(fatigue_floor=0.4, window_s=120.0, sa_drop=0.5,
                           sa_recovery_per_min=0.1, switch_cost_s=30.0, rebrief_s=45.0)
    robot = RobotConstants(capture_s=5.0, replan_s=7.0, skill_speed=(2.0 / 3.0, 1.0, 1.5))
    assert sim.sim.published(HumanConstants) == human
    assert sim.sim.published(RobotConstants) == robot
    ctx = sim.begin_epoch()
    assert ctx.published(HumanConstants) == human
    assert ctx.take(np.array([1])).published(RobotConstants) == robot
    # the re-brief, and the SA it loses (0.5 * 30 s), and the robots' hold
    assert retask_cost(ctx) == RetaskCost(rebrief_s=45.0, replan_s=7.0, human_seconds=60.0)


def test_the_retasking_cost_of_published_constants():
    assert RetaskCost.of(HumanConstants(), RobotConstants()) == RetaskCost(20.0, 10.0, 27.5)
    # no re-brief: no SA lost either; free when the robots do not hold
    free = RetaskCost.of(HumanConstants(rebrief_s=0.0), RobotConstants(replan_s=0.0))
    assert free == RetaskCost(0.0, 0.0, 0.0) and free.free
    assert not RetaskCost.of(HumanConstants(rebrief_s=0.0), RobotConstants()).free


class _Unpublished:
    """The simulation as a custom model sees it, but its `publish` drops the value."""

    def __init__(self, sim):
        self._sim = sim

    def __getattr__(self, name):
        return getattr(self._sim, name)

    def publish(self, value) -> None:
        pass


class SilentHumans(HumanModel):
    """A custom human model (the built-in one's dynamics) that publishes no constants."""

    @hookimpl
    def ata_setup(self, sim):
        super().ata_setup(_Unpublished(sim))


class RenamedHumans(HumanModel):
    """A custom human model whose re-brief lasts 45 s (a setting of its own name): it
    publishes that in its constants."""

    @hookimpl
    def ata_setup(self, sim):
        super().ata_setup(_Unpublished(sim))
        sim.publish(HumanConstants(rebrief_s=45.0))


def _run_with_humans(model_cls):
    s = load_session(str(BASELINE_MISSION), SMALL)
    humans = model_cls(HumanModel.Settings(), s.mission)
    return Simulation(s.mission, s.registry, [0, 1], overrides={"human_model": humans})


def test_greedy_fails_loudly_with_a_team_model_that_publishes_nothing():
    sim = _run_with_humans(SilentHumans)
    with pytest.raises(ContractError, match=r"no HumanConstants was published: the human model "
                                            r"\(slot human_model\) publishes it"):
        sim.run()


def test_greedy_prices_a_custom_model_by_what_it_publishes():
    sim = _run_with_humans(RenamedHumans)
    sim.reset()
    sim.step_epoch()
    ctx = sim.begin_epoch()
    assert retask_cost(ctx) == RetaskCost(rebrief_s=45.0, replan_s=10.0, human_seconds=52.5)
    sim.end_epoch(*sim.decide(ctx))
