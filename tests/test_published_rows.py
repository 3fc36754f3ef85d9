"""The published rows that ship with ata (ata/published/paper, the paper suite's rows) are what
this code makes: a sample of them, every method and every cell, rerun here is identical."""

import pytest

from ata.published.sets import PUBLISHED, read_published
from ata.testing import check_published_rows

_, MANIFEST, _ = read_published("published")
METHODS = list(MANIFEST["methods"])
CELLS = sorted({c for entry in MANIFEST["methods"].values() for c in entry["cells"]})


def test_the_paper_set_ships_every_method_and_cell_of_the_suite():
    assert (PUBLISHED / "paper" / "manifest.json").is_file()
    plain = [m for m in METHODS if " seed " not in m]
    assert len(plain) == 11 and len(CELLS) == 6
    # every learned method from several training seeds, each seed's rows under its own name
    seeds = MANIFEST["seeds"]
    assert all(len(seeds[m]) >= 5 for m in ("ATA-HRL", "w/o.AUX", "w/o.C"))
    assert all(len(seeds[m]) >= 3 for m in ("TR-POMDP", "AtRL-TR"))
    assert sorted(METHODS) == sorted(plain + [f"{m} seed {s}" for m, ss in seeds.items()
                                              for s in ss])
    for method, entry in MANIFEST["methods"].items():
        assert sorted(entry["cells"]) == CELLS, method
        for cell, info in entry["cells"].items():
            assert info["scenarios"][1] == 500, (method, cell)


def test_the_paper_set_belongs_to_this_release():
    """Named by release (paper@RELEASE): a version bump publishes it again (ata publish). A
    manifest from before sets named their release reads as its ata version's (sets.release)."""
    from ata import __version__
    from ata.published.sets import release, seed_public
    from ata.runtime.machine import MODEL_REVISION
    assert release(MANIFEST) == __version__, "publish the set again with this release"
    assert MANIFEST.get("model_revision", MODEL_REVISION) == MODEL_REVISION
    assert seed_public(MANIFEST)                     # seed 0, in examples/paper_suite.toml
    assert not MANIFEST.get("isolated", False)


def test_one_scenario_of_every_method_rerun_is_identical():
    # each method in one cell of setting (a), the levels taken in turn: one scenario each (the
    # first of the cell's rows); the slow test below reruns every cell, (b)'s included
    levels = [c for c in CELLS if c.startswith("a/")]
    cells = {m: [levels[i % len(levels)]] for i, m in enumerate(METHODS)}
    check_published_rows("published", per_cell=1, cells=cells)


@pytest.mark.slow
def test_two_scenarios_of_every_method_and_cell_rerun_are_identical():
    check_published_rows("published", per_cell=2)


def test_each_cell_records_the_weights_it_read_and_they_are_the_installed_ones():
    from ata.published.sets import mission_inputs
    for method, entry in MANIFEST["methods"].items():
        for cell, info in entry["cells"].items():
            assert mission_inputs(info["mission"]) == info["inputs"], (method, cell)
    cells = MANIFEST["methods"]["ATA-HRL"]["cells"]
    assert cells["a/low"]["inputs"] != cells["b/low"]["inputs"]     # (a)'s and (b)'s weights


def test_a_suite_reads_a_published_method_in_both_settings_without_running_it(tmp_path, cli):
    suite = tmp_path / "suite.toml"
    suite.write_text('[suite]\nsettings = ["a", "b"]\nuncertainty = ["high"]\nscenarios = 2\n'
                     'seed = 0\n[[method]]\nname = "ATA-HRL"\nmission = "published:ATA-HRL"\n')
    r = cli("eval", suite, "-o", tmp_path / "out", "-e", "serial", "-q")
    assert r.exit_code == 0, r.output
    rows, _, _ = read_published("published")
    mine = (tmp_path / "out" / "results.csv").read_text().splitlines()
    assert len(mine) == 5
    for setting in ("a", "b"):
        sel = rows.select("ATA-HRL", setting, "high")
        first = rows.columns["score"][sel][:2]
        got = [float(line.split(",")[5]) for line in mine[1:] if line.split(",")[1] == setting]
        assert got == list(first), setting
