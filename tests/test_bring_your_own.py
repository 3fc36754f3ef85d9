"""Bring your own method: a policy in a file named by a mission, checked from the command line,
paired against published rows without rerunning them, and never resumed stale after an edit."""

import gzip
import json
import shutil
from pathlib import Path

import pytest

from ata.core import kernel
from ata.core.errors import MissionError
from ata.published import sets as published
from ata.experiment.reproduce import rerun_sample
from ata.session import load_session

EXAMPLE = Path(__file__).resolve().parent.parent / "examples" / "policies" / "nearest_capable.py"

SUITE = """[suite]
name = "{name}"
settings = ["a"]
uncertainty = ["low"]
scenarios = 3
{methods}"""
REFERENCES = """[[method]]
name = "greedy (600 s/episode)"
mission = "builtin:greedy"
set = ["mission.horizon_s=600.0"]
[[method]]
name = "random"
mission = "random.toml"
"""
MINE = """[[method]]
name = "nearest"
mission = "mine.toml"
"""
MISSION = """[mission]
name = "mine"
horizon_s = 600.0

[components]
initial = "./my_policy.py:NearestCapable"
reallocation = "./my_policy.py:NearestCapable"

[nearest_capable]
any_type = false
"""
RANDOM = """[mission]
name = "random"
horizon_s = 600.0

[components]
initial = "random"
condition = "never"
"""


@pytest.fixture
def workspace(tmp_path, monkeypatch):
    """A fresh folder: a policy file, a mission naming it, and two tiny suites (the
    references, short missions of 600 s; mine)."""
    monkeypatch.chdir(tmp_path)
    shutil.copy(EXAMPLE, tmp_path / "my_policy.py")
    (tmp_path / "mine.toml").write_text(MISSION)
    (tmp_path / "random.toml").write_text(RANDOM)
    (tmp_path / "refs.toml").write_text(SUITE.format(name="refs", methods=REFERENCES))
    (tmp_path / "mine_suite.toml").write_text(SUITE.format(name="mine", methods=MINE))
    return tmp_path


@pytest.fixture
def published_fixture(workspace, cli):
    """The reference methods evaluated on 3 scenarios and published (the fixture the real,
    shipped rows will replace)."""
    r = cli("eval", "refs.toml", "-o", "refs", "-e", "serial", "-q")
    assert r.exit_code == 0, r.output
    r = cli("publish", "refs", "-o", "pub")
    assert r.exit_code == 0, r.output
    return workspace / "pub"


def test_a_policy_in_a_file_from_check_to_a_paired_table_then_edited(published_fixture, cli,
                                                                      monkeypatch):
    root = published_fixture.parent
    r = cli("check", "--component", "policy", "./my_policy.py:NearestCapable", "--seed", "3")
    assert r.exit_code == 0, r.output
    assert "policy nearest_capable" in r.output and "keeps the contract" in r.output

    # worker processes resolve the file again (a spawned process, as every worker)
    r = cli("eval", "mine_suite.toml", "-o", "mine", "-e", "process", "-w", "2", "-q")
    assert r.exit_code == 0, r.output
    resolved = (root / "mine" / "missions" / "nearest__a__low.resolved.toml").read_text()
    digest = published.hashlib.sha256((root / "my_policy.py").read_bytes()).hexdigest()
    assert f'sha256 = "{digest}"' in resolved and 'initial = "nearest_capable"' in resolved
    code = (root / "mine" / "plugins.toml").read_text()
    assert "policy nearest_capable" in code

    # the paired table runs nothing: no simulation may start
    def no_runs(*args, **kwargs):
        raise AssertionError("a published row was rerun")
    with monkeypatch.context() as patched:
        patched.setattr(kernel.Simulation, "run", no_runs)
        r = cli("compare", "mine", "published:pub")
        full = cli("compare", "mine", "published:pub", "--full")
    assert r.exit_code == 0, r.output
    assert "none rerun" in r.output and f"pub@{published.__version__}" in r.output
    # one table: every method against the first published one (no greedy among them)
    assert "setting a, low uncertainty: score, 3 paired scenarios, against greedy (600 " \
        "s/episode)" in " ".join(r.output.split())
    assert [x.split("│")[1].strip() for x in r.output.splitlines() if x.startswith("│")] == \
        ["nearest", "greedy (600 s/episode)", "random"]
    # --full: nearest against each published method
    assert full.exit_code == 0, full.output
    for base in ("greedy (600 s/episode)", "random"):
        line = next(x for x in full.output.splitlines() if f"nearest - {base}" in x)
        assert "│      3 │" in line        # 3 paired scenarios

    # the policy edited: the same --out refuses, naming it and --force
    text = (root / "my_policy.py").read_text()
    (root / "my_policy.py").write_text(text.replace("any_type: bool = param(False",
                                                    "any_type: bool = param(True"))
    r = cli("eval", "mine_suite.toml", "-o", "mine", "-e", "serial", "-q")
    assert r.exit_code == 2
    assert "other code of policy nearest_capable" in r.output and "--force" in r.output
    r = cli("eval", "mine_suite.toml", "-o", "mine", "-e", "serial", "-q", "--force")
    assert r.exit_code == 0, r.output
    assert digest not in (root / "mine" / "missions" / "nearest__a__low.resolved.toml").read_text()


def test_pairing_refuses_other_scenarios_or_other_reference_code(published_fixture, cli):
    root = published_fixture.parent
    r = cli("eval", "mine_suite.toml", "-o", "other_seed", "-e", "serial", "-q", "--seed", "7")
    assert r.exit_code == 0, r.output
    r = cli("compare", "other_seed", "published:pub")
    assert r.exit_code == 2
    assert "ran other scenarios than the published" in r.output and "seed 7, ids" in r.output

    r = cli("eval", "mine_suite.toml", "-o", "mine", "-e", "serial", "-q")
    assert r.exit_code == 0, r.output
    manifest = json.loads((published_fixture / "manifest.json").read_text())
    manifest["methods"]["random"]["code"]["policy random"] = "0" * 16
    (published_fixture / "manifest.json").write_text(json.dumps(manifest))
    r = cli("compare", "mine", "published:pub", "--base", "random")
    assert r.exit_code == 2
    assert "made with other code than is installed now, of policy random" in r.output
    r = cli("compare", "mine", "published:no_such_set")
    assert r.exit_code == 2 and "no published rows 'no_such_set'" in r.output
    assert "shipped sets: paper" in r.output
    r = cli("compare", "mine", "published")      # the shipped paper set: mine is of 600 s
    assert r.exit_code == 2 and "ran in another model than the published ATA-HRL" in r.output
    assert root


def test_rerun_sample_finds_the_published_rows_identical_and_names_a_changed_one(
        published_fixture):
    assert rerun_sample(published_fixture, per_cell=2) == []
    rows = gzip.decompress((published_fixture / "rows.csv.gz").read_bytes()).decode()
    lines = rows.splitlines()
    header = lines[0].split(",")
    first = lines[1].split(",")
    first[header.index("score")] = "12345.0"
    lines[1] = ",".join(first)
    data = gzip.compress(("\n".join(lines) + "\n").encode())
    (published_fixture / "rows.csv.gz").write_bytes(data)
    manifest = json.loads((published_fixture / "manifest.json").read_text())
    with pytest.raises(MissionError, match="not the file its manifest describes"):
        published.read_published(published_fixture)
    manifest["rows_sha256"] = published.hashlib.sha256(data).hexdigest()
    (published_fixture / "manifest.json").write_text(json.dumps(manifest))
    found = rerun_sample(published_fixture, per_cell=1, methods=[first[0]])
    assert len(found) == 1 and "score 12345.0 published" in found[0], found
    from ata.testing import check_published_rows
    with pytest.raises(AssertionError, match="score 12345.0 published"):
        check_published_rows(str(published_fixture), per_cell=1, methods=[first[0]])


def test_references_are_resolved_or_refused_by_name(workspace):
    session = load_session("mine.toml")
    ref = session.mission.references["nearest_capable"]
    assert ref.source == f"{workspace / 'my_policy.py'}:NearestCapable" and ref.kind == "policy"
    assert session.versions()["policy nearest_capable"].endswith(ref.sha256[:16])
    (workspace / "resolved.toml").write_text(session.mission.to_toml())
    assert load_session("resolved.toml").mission.references["nearest_capable"] == ref

    bad = {"./nope.py:NearestCapable": "no such file",
           "./my_policy.py:Nope": "defines no class 'Nope'; its classes: NearestCapable",
           "no_such_module_xyz:Policy": "cannot be imported"}
    for value, message in bad.items():
        (workspace / "bad.toml").write_text(MISSION.replace("./my_policy.py:NearestCapable",
                                                            value, 1))
        with pytest.raises(MissionError, match=message):
            load_session("bad.toml")
    (workspace / "clash.py").write_text("class Greedy:\n    name = 'greedy'\n")
    (workspace / "bad.toml").write_text(
        "[components]\nreallocation = './clash.py:Greedy'\ninitial = 'greedy'\n")
    with pytest.raises(MissionError, match="named 'greedy', which the policy of"):
        load_session("bad.toml")
    (workspace / "my_policy.py").write_text((workspace / "my_policy.py").read_text() + "\n#\n")
    with pytest.raises(MissionError, match="has changed since this mission was resolved"):
        load_session("resolved.toml")


def test_run_takes_scenarios_and_a_one_method_report_has_no_empty_paired_columns(workspace,
                                                                                 cli):
    r = cli("run", "mine.toml", "-n", "2", "-o", "run", "-q")
    assert r.exit_code == 0, r.output
    assert "2 (ids 0..1" in r.output
    assert len((workspace / "run" / "results.csv").read_text().splitlines()) == 3
    r = cli("eval", "mine_suite.toml", "-o", "one", "-e", "serial")
    assert r.exit_code == 0, r.output
    assert "beats" not in r.output and "- method" not in r.output


def test_the_example_package_gives_the_same_policy_by_name_or_by_module(tmp_path,
                                                                       monkeypatch):
    """examples/third_party_policy: registered (as pip install -e would, lazily) its policy
    fills the mission by name; on Python's path, a mission names its class as module:Class."""
    import importlib

    from ata.core import mission as mission_mod
    from ata.core.registry import collect_components, get_plugin_manager

    package = EXAMPLE.parent.parent / "third_party_policy"
    monkeypatch.syspath_prepend(str(package))
    plugin = importlib.import_module("ata_nearest")
    registry = collect_components(get_plugin_manager(extra=[plugin]))
    raw = mission_mod.read_toml(package / "nearest_mission.toml")
    m = mission_mod.validate(raw, registry)
    assert m.slots.initial == "nearest_capable" and not m.references
    assert registry.get("policy", "nearest_capable", "").factory is plugin.NearestCapable

    (tmp_path / "by_module.toml").write_text(MISSION.replace("./my_policy.py:NearestCapable",
                                                             "ata_nearest.policy:NearestCapable"))
    session = load_session(str(tmp_path / "by_module.toml"))
    ref = session.mission.references["nearest_capable"]
    assert ref.source == "ata_nearest.policy:NearestCapable"
    assert session.mission.slots.initial == session.mission.slots.reallocation == ref.name
    assert session.code()["policy nearest_capable"]


def test_check_component_from_the_command_line_fails_with_what_broke(workspace, cli):
    (workspace / "noisy.py").write_text(
        "import numpy as np\nfrom ata import hookimpl\nfrom ata.core.state import Allocation\n\n"
        "class Noisy:\n    def __init__(self, settings, mission):\n        pass\n\n"
        "    @hookimpl\n    def ata_initial_allocation(self, ctx):\n"
        "        B, P = ctx.reallocatable.shape\n"
        "        robot = np.random.randint(0, ctx.sizes.robots, (B, P))\n"
        "        return Allocation(robot, np.full((B, P), -1), np.full((B, P), -1))\n")
    r = cli("check", "--component", "policy", "./noisy.py:Noisy", "--seed", "1")
    assert r.exit_code == 1
    assert "failed" in r.output and "policy 'Noisy' is not deterministic" in r.output
    r = cli("check", "--component", "policy", "./my_policy.py:NearestCapable",
            "--set", "nearest_capable.any_type=3")
    assert r.exit_code == 2 and "[nearest_capable] key 'any_type'" in r.output


def test_a_suite_names_published_methods_and_reads_their_rows(published_fixture, cli):
    root = published_fixture.parent
    (root / "vs.toml").write_text(SUITE.format(name="vs", methods=MINE) + """[[method]]
name = "greedy (600 s/episode)"
mission = "published:pub:greedy (600 s/episode)"
[[method]]
name = "random"
mission = "published:pub:random"
""")
    r = cli("eval", "vs.toml", "-o", "vs", "-e", "serial", "-q")
    assert r.exit_code == 0, r.output
    assert "nearest - method" in r.output          # the paired columns, against nearest
    mine, refs = ((root / d / "results.csv").read_text().splitlines() for d in ("vs", "refs"))
    header = mine[0].split(",")
    keep = [header.index(c) for c in ("method", "scenario", "score", "upper_bound",
                                      "reallocations")]
    def rows(lines):
        return {tuple(x.split(",")[k] for k in keep) for x in lines[1:]
                if not x.startswith("nearest")}
    assert rows(mine) == rows(refs) and len(rows(mine)) == 6
    assert all(x.split(",")[header.index("wall_s")] == "0.0" for x in mine[1:]
               if not x.startswith("nearest"))
    r = cli("eval", "vs.toml", "-o", "vs7", "-e", "serial", "-q", "--seed", "7")
    assert r.exit_code == 2 and "the evaluation asks for seed 7" in r.output
    (root / "vs.toml").write_text((root / "vs.toml").read_text().replace("pub:random",
                                                                        "pub:nope"))
    r = cli("eval", "vs.toml", "-o", "vs_bad", "-e", "serial", "-q")
    assert r.exit_code == 2 and "hold no method 'nope'" in r.output
    (root / "long.toml").write_text(MISSION.replace("horizon_s = 600.0", "horizon_s = 1200.0"))
    (root / "long_suite.toml").write_text(SUITE.format(name="long", methods=MINE.replace(
        "mine.toml", "long.toml")) + '[[method]]\nname = "g"\nmission = "published:pub:random"\n')
    r = cli("eval", "long_suite.toml", "-o", "long", "-e", "serial", "-q")
    assert r.exit_code == 2 and "runs in another model than the published random" in r.output
