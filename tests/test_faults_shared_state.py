"""No component can change what every other component reads in the host's process: the tables
of ata.model are read-only for good (a component that edits one in place raises, and fails its
check), and check_component fails a component that patches a function of the kernel or the
world's generator (at import, before any check ran)."""

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


TABLE_NAMES = ("POINTS", "QUALITY", "P_RC", "T_BAR", "SKILL_SPEED", "F_D")


@pytest.mark.parametrize("name", TABLE_NAMES)
def test_a_table_cannot_be_written_nor_made_writable(name):
    table = getattr(tables, name)
    before = table.copy()
    with pytest.raises(ValueError, match="read-only"):
        table[...] = 0
    with pytest.raises(ValueError, match="read-only"):
        table *= 2
    with pytest.raises(ValueError, match="WRITEABLE"):
        table.setflags(write=True)
    assert (getattr(tables, name) == before).all()
    if name.lower() in tables.Tables._fields:
        assert getattr(tables.TABLES, name.lower()) is table


def test_a_table_edited_in_place_fails_the_check():
    with pytest.raises(AssertionError, match="read-only"):
        check_component("policy", NormalisingGreedy, name="normalising_greedy", seed=3)
    assert (tables.POINTS == [15.0, 25.0, 35.0]).all()


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


class MemoGreedy(GreedyPolicy):
    """Greedy that keeps a memo in HOME and in the temporary folder, and decides otherwise
    once it finds one: what recognising a check by its missions seen takes."""

    name = "memo_greedy"

    @hookimpl
    def ata_initial_allocation(self, ctx):
        import os
        import tempfile
        from pathlib import Path
        memos = [Path(os.path.expanduser("~")) / ".ata_memo",
                 Path(tempfile.gettempdir()) / "ata_memo"]
        seen = any(m.exists() for m in memos)
        for m in memos:
            m.write_text("seen")
        allocation = super().ata_initial_allocation(ctx)
        if seen:                     # another legal allocation: no human takes part
            allocation = type(allocation)(allocation.robot, allocation.navigator * 0 - 1,
                                          allocation.classifier * 0 - 1)
        return allocation


def test_no_check_run_finds_what_another_left_in_home_or_temp(monkeypatch, tmp_path):
    monkeypatch.setenv("HOME", str(tmp_path / "home"))
    (tmp_path / "home").mkdir()
    check_component("policy", MemoGreedy, name="memo_greedy", seed=3)
    assert not (tmp_path / "home" / ".ata_memo").exists()
