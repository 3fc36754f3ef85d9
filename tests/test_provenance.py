"""Every run folder says what made its rows: ata's version, the git commit of a checkout (and
whether its tree was dirty), the versions of the packages that compute results, the machine;
`ata report` shows it."""

import json
from importlib import metadata
from pathlib import Path

import ata
from ata import __version__
from ata.runtime import machine


def test_a_run_folder_records_its_provenance_and_the_report_shows_it(cli, tmp_path):
    out = tmp_path / "run"
    result = cli("run", "builtin:greedy", "-n", "2", "--set", "mission.horizon_s=600", "-q",
                 "-o", str(out))
    assert result.exit_code == 0, result.output
    info = json.loads((out / machine.PROVENANCE).read_text())
    assert info["ata"] == __version__
    assert info["packages"]["numpy"] == metadata.version("numpy")
    assert set(info["packages"]) == set(machine.PACKAGES) & set(info["packages"])
    assert info["machine"]["cores"] >= 1
    here = machine.checkout()
    assert info["checkout"] == here or (here and info["checkout"]["commit"] == here["commit"])
    report = cli("report", str(out), "--no-figures")
    assert report.exit_code == 0, report.output
    assert f"made with: ata {__version__}" in " ".join(report.output.split())


def test_an_evaluation_folder_records_it_too(cli, tmp_path):
    out = tmp_path / "eval"
    mission = tmp_path / "greedy.toml"
    mission.write_text((Path(ata.__file__).parent / "missions" / "greedy.toml").read_text())
    result = cli("eval", str(mission), "-n", "2", "-e", "serial", "-q", "--no-cache",
                 "-o", str(out))
    assert result.exit_code == 0, result.output
    assert json.loads((out / machine.PROVENANCE).read_text())["ata"] == __version__
