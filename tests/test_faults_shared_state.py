"""check_component fails a component that changes what every other component reads in the
host's process: a table of ata.model edited in place, a function of the kernel or the world's
generator patched (at import, before any check ran)."""

import pytest

from ata import hookimpl
from ata.core import rng
from ata.model import tables
from ata.plugins.policies.greedy import GreedyPolicy
from ata.testing import check_component


class NormalisingGreedy(GreedyPolicy):
    """Greedy that 'normalises' the points table in place: an honest mistake."""

    name = "normalising_greedy"

    @hookimpl
    def ata_initial_allocation(self, ctx):
        tables.POINTS /= tables.POINTS.max()
        return super().ata_initial_allocation(ctx)


class PlainGreedy(GreedyPolicy):
    name = "plain_greedy"


def test_a_table_edited_in_place_fails_the_check():
    before = tables.POINTS.copy()
    try:
        with pytest.raises(AssertionError, match="ata.model.tables.POINTS"):
            check_component("policy", NormalisingGreedy, name="normalising_greedy", seed=3)
    finally:
        tables.POINTS[:] = before        # the runs are forked: this process keeps its table
    assert (tables.POINTS == before).all()


def test_a_patched_generator_fails_the_check(monkeypatch):
    def resalted(self, streams, salt):     # a check that switches the integrity test off
        return self
    monkeypatch.setattr(rng.BatchRNG, "resalted", resalted)
    with pytest.raises(AssertionError, match="ata.core.rng.BatchRNG.resalted"):
        check_component("policy", PlainGreedy, name="plain_greedy", seed=3)


def test_an_edited_table_before_the_check_fails_it(monkeypatch):
    monkeypatch.setitem(vars(tables), "P_RC", tables.P_RC * 0 + 1.0)
    with pytest.raises(AssertionError, match="ata.model.tables.P_RC"):
        check_component("policy", PlainGreedy, name="plain_greedy", seed=3)


def test_an_honest_component_passes():
    check_component("policy", PlainGreedy, name="plain_greedy", seed=3)


def test_a_component_that_raises_fails_its_check_in_one_line(cli, tmp_path):
    policy = tmp_path / "raising.py"
    policy.write_text("from ata import hookimpl\n"
                      "from ata.plugins.policies.greedy import GreedyPolicy\n\n\n"
                      "class Raising(GreedyPolicy):\n    name = 'raising'\n\n"
                      "    @hookimpl\n    def ata_initial_allocation(self, ctx):\n"
                      "        raise ValueError('my bug')\n")
    result = cli("check", "--component", "policy", f"{policy}:Raising")
    assert result.exit_code == 1
    text = " ".join(result.output.split())
    assert "failed: policy 'raising' raised ValueError: my bug" in text
    assert "Traceback" not in result.output


def test_the_check_mission_has_no_fixed_shape():
    from ata.testing import check_team
    shapes = {tuple(check_team(seed).values()) for seed in range(40)}
    assert len(shapes) > 20
    assert {s[1] for s in shapes} == {2, 3, 4} and len({s[3] for s in shapes}) > 4
