"""The published rows that ship with ata (ata/published/paper, the paper suite's rows) are what
this code makes: a sample of them, every method and every cell, rerun here is identical."""

import pytest

from ata.experiment.published import PUBLISHED, read_published
from ata.testing import check_published_rows

_, MANIFEST, _ = read_published("published")
METHODS = list(MANIFEST["methods"])
CELLS = sorted({c for entry in MANIFEST["methods"].values() for c in entry["cells"]})


def test_the_paper_set_ships_every_method_and_cell_of_the_suite():
    assert (PUBLISHED / "paper" / "manifest.json").is_file()
    assert len(METHODS) == 11 and len(CELLS) == 6
    for method, entry in MANIFEST["methods"].items():
        assert sorted(entry["cells"]) == CELLS, method
        for cell, info in entry["cells"].items():
            assert info["scenarios"][1] == 500, (method, cell)


def test_one_scenario_of_every_method_rerun_is_identical():
    # each method in one cell of setting (a), the levels taken in turn: one scenario each (the
    # first of the cell's rows); the slow test below reruns every cell, (b)'s included
    levels = [c for c in CELLS if c.startswith("a/")]
    cells = {m: [levels[i % len(levels)]] for i, m in enumerate(METHODS)}
    check_published_rows("published", per_cell=1, cells=cells)


@pytest.mark.slow
def test_two_scenarios_of_every_method_and_cell_rerun_are_identical():
    check_published_rows("published", per_cell=2)
