"""Both built-in trainers are the declared `ata.training.Trainer`, ATA-HRL's trainer is the
`Host` its phases are written against, the registry is the `Components` a mission's validation
reads (checked by a type checker where one is installed), and `Mission.replace` derives what
depends on the keys it replaces."""

import importlib.util
import subprocess
import sys
import textwrap

import pytest

from ata.session import build_trainer, load_session, training_mission_for
from ata.training import Trainer


@pytest.mark.parametrize("plugins", [["ctr", "aux"], ["trp"]])
def test_the_built_in_trainers_are_trainers(plugins):
    session = load_session(str(training_mission_for(plugins)))
    assert isinstance(build_trainer(session), Trainer)


@pytest.mark.skipif(importlib.util.find_spec("mypy") is None, reason="mypy is not installed")
def test_the_declared_protocols_hold_for_a_type_checker(tmp_path):
    # ATA-HRL's trainer is the Host of its phases, both built-in trainers are Trainers (their
    # methods' signatures too, which isinstance does not see) and their classes TrainerFactories
    # (a Settings, the constructor), the registry is the Components a mission's validation reads
    probe = tmp_path / "protocol_probe.py"
    probe.write_text(textwrap.dedent("""
        from ata.core.components import Components
        from ata.core.registry import Register
        from ata.plugins.ata_hrl.phases.host import Host
        from ata.plugins.ata_hrl.trainer import ATAHRLTrainer
        from ata.plugins.tr_pomdp.trainer import TRPOMDPTrainer
        from ata.training import Trainer, TrainerFactory


        def as_host(trainer: ATAHRLTrainer) -> Host:
            return trainer


        def as_trainers(a: ATAHRLTrainer, b: TRPOMDPTrainer) -> list[Trainer]:
            return [a, b]


        def as_factories() -> list[TrainerFactory]:
            return [ATAHRLTrainer, TRPOMDPTrainer]


        def as_components(registry: Register) -> Components:
            return registry
    """))
    done = subprocess.run([sys.executable, "-m", "mypy", "--ignore-missing-imports",
                           "--follow-imports=silent", "--no-incremental", str(probe)],
                          capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stdout + done.stderr


@pytest.mark.parametrize("level", ["none", "low", "medium", "high"])
@pytest.mark.parametrize("setting", ["a", "b"])
def test_mission_replace_derives_what_depends_on_what_it_replaces(setting, level):
    base = load_session("builtin:greedy").mission
    validated = load_session("builtin:greedy", [f"mission.setting='{setting}'",
                                                f"mission.uncertainty='{level}'"]).mission
    replaced = base.replace(setting=setting, uncertainty=level)
    assert replaced.settings == validated.settings
    assert replaced.sizes == validated.sizes
    assert (replaced.fatigue_variance, replaced.event_probability) == \
        (validated.fatigue_variance, validated.event_probability)
