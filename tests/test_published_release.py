"""A published set belongs to a release (issue 61, item 3): `ata publish` writes the ata release,
the model revision, whether its seed is public and whether its methods ran isolated into the
manifest; the set is shown as NAME@RELEASE; rows of another release are not paired with it (one
message naming both); a manifest written before sets named their release is still read."""

import json

import pytest

from _support import assert_user_error, flat
from ata import __version__
from ata.published import sets as published
from ata.runtime.machine import MODEL_REVISION, provenance

SUITE = """[suite]
name = "refs"
settings = ["a"]
uncertainty = ["low"]
scenarios = 3

[[method]]
name = "random"
mission = "random.toml"
"""
RANDOM = """[mission]
name = "random"
horizon_s = 600.0

[components]
initial = "random"
condition = "never"
"""


@pytest.fixture
def pub(cli, tmp_path, monkeypatch):
    """A tiny evaluation (one method, 3 scenarios of 600 s) and its published set, in a fresh
    working folder: (the evaluation, the set)."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "random.toml").write_text(RANDOM, encoding="utf-8")
    (tmp_path / "refs.toml").write_text(SUITE, encoding="utf-8")
    r = cli("eval", "refs.toml", "-o", "refs", "-e", "serial", "-q")
    assert r.exit_code == 0, r.output
    r = cli("publish", "refs", "-o", "pub")
    assert r.exit_code == 0, r.output
    return tmp_path / "refs", tmp_path / "pub"


def manifest_of(folder):
    return json.loads((folder / "manifest.json").read_text(encoding="utf-8"))


def write_manifest(folder, manifest):
    (folder / "manifest.json").write_text(json.dumps(manifest, indent=1) + "\n",
                                          encoding="utf-8")


def test_publish_names_the_set_by_its_release(pub):
    refs, folder = pub
    m = manifest_of(folder)
    made = json.loads((refs / "provenance.json").read_text(encoding="utf-8"))
    assert m["release"] == __version__ and m["model_revision"] == MODEL_REVISION == 3
    assert m["seed_public"] is True and m["isolated"] is False
    assert m["commit"] == (made["checkout"] or {}).get("commit")
    assert m["packages"] == made["packages"]
    assert list(m)[:3] == ["format", "release", "model_revision"]
    assert published.set_name(folder, m) == f"pub@{__version__}"
    # no path of this machine: the folder relative to the working folder
    assert published.describe(folder, m) == (f"pub@{__version__} (pub; model revision 3; "
                                             "public seed)")
    assert provenance()["model_revision"] == MODEL_REVISION


def test_the_shipped_set_says_its_release_without_a_machine_path():
    _, m, folder = published.read_published("published")
    revision = "model revision 3; " if "model_revision" in m else ""   # until published again
    assert published.describe(folder, m) == (f"paper@{published.release(m)} (published:paper; "
                                              f"{revision}public seed)")
    assert published.shown(folder) == "published:paper"


def test_rows_of_another_release_are_not_paired(pub, cli):
    refs, folder = pub
    m = manifest_of(folder)
    m["release"] = "0.1.0"
    write_manifest(folder, m)
    r = cli("compare", "refs", "published:pub")
    assert_user_error(r, f"the rows of refs were made with ata {__version__}, the published "
                         "set pub@0.1.0 (pub) with ata 0.1.0: rows of two releases are not "
                         "paired")
    # a suite's method read from the set: the evaluation is of this release
    (folder.parent / "vs.toml").write_text(
        SUITE.replace("random.toml", "published:pub:random"), encoding="utf-8")
    r = cli("eval", "vs.toml", "-o", "vs", "-e", "serial", "-q")
    assert_user_error(r, "published random is of the set pub@0.1.0 (pub), made with ata "
                         f"0.1.0; this is ata {__version__}: rows of two releases are not "
                         "paired")
    # the same set at this release pairs
    m["release"] = __version__
    write_manifest(folder, m)
    r = cli("compare", "refs", "published:pub")
    assert r.exit_code == 0, r.output
    assert f"pub@{__version__} (pub; model revision 3; public seed)" in flat(r.output)


def test_a_manifest_from_before_releases_reads_its_ata_version(pub, cli):
    refs, folder = pub
    m = manifest_of(folder)
    for key in ("release", "model_revision", "seed_public", "isolated", "commit", "dirty",
                "packages"):
        m.pop(key)
    m["ata"] = __version__
    write_manifest(folder, m)
    assert published.release(m) == __version__ and published.seed_public(m)
    r = cli("compare", "refs", "published:pub")
    assert r.exit_code == 0, r.output
    assert f"pub@{__version__} (pub; public seed)" in flat(r.output)
    # a secret seed's cells say so without the flag
    next(iter(m["methods"]["random"]["cells"].values()))["seed"] = "secret:" + "ab" * 8
    assert not published.seed_public(m)
    m["ata"] = "0.1.0"                       # its ata is its release
    write_manifest(folder, m)
    assert_user_error(cli("compare", "refs", "published:pub"), "pub@0.1.0", "ata 0.1.0",
                      f"ata {__version__}")


def test_rows_of_another_version_are_published_only_on_this_code(pub, cli):
    refs, _ = pub
    text = (refs / "plugins.toml").read_text(encoding="utf-8")
    assert f'ata = "{__version__}"' in text
    (refs / "plugins.toml").write_text(text.replace(f'ata = "{__version__}"', 'ata = "0.1.0"',
                                                    1), encoding="utf-8")
    # the same code: the rows are this release's
    r = cli("publish", "refs", "-o", "pub2")
    assert r.exit_code == 0, r.output
    m = json.loads((refs.parent / "pub2" / "manifest.json").read_text(encoding="utf-8"))
    assert (m["release"], m["made_with"]) == (__version__, "0.1.0")
    # other code: refused, naming both versions
    text = (refs / "plugins.toml").read_text(encoding="utf-8")
    digest = text.split('"policy random" = "')[-1].split('"')[0]
    (refs / "plugins.toml").write_text(text.replace(digest, "0" * 16), encoding="utf-8")
    assert_user_error(cli("publish", "refs", "-o", "pub3"),
                      f"was evaluated with ata 0.1.0 and this is ata {__version__}, whose "
                      "code of random differs (policy random)")


def test_a_report_names_the_sets_its_rows_were_read_from(pub, cli):
    _, folder = pub
    (folder.parent / "vs.toml").write_text(
        SUITE.replace("random.toml", "published:pub:random"), encoding="utf-8")
    r = cli("eval", "vs.toml", "-o", "vs", "-e", "serial", "-q")
    assert r.exit_code == 0, r.output
    r = cli("report", "vs", "--no-figures")
    assert r.exit_code == 0, r.output
    assert (f"published rows read: random: pub@{__version__} (pub; model revision 3; public "
            "seed)") in flat(r.output)
    assert str(folder) not in r.output                  # no path of this machine


def test_the_run_summary_names_weights_without_a_machine_path(cli, tmp_path, monkeypatch):
    """A checkpoint named by an absolute path (a training folder's resolved mission names its
    best.pt so) is shown relative to the working folder, as the user would name it."""
    import shutil
    from ata.runtime.inputs import WEIGHTS
    monkeypatch.chdir(tmp_path)
    (tmp_path / "train").mkdir()
    shutil.copy(WEIGHTS / "ata_hrl_a.pt", tmp_path / "train" / "best.pt")
    path = (tmp_path / "train" / "best.pt").resolve()
    (tmp_path / "m.toml").write_text(
        '[mission]\nname = "m"\nscenarios = 1\nhorizon_s = 600.0\n[components]\n'
        'initial = "attention"\ncondition = "ctr"\nreallocation = "ctr"\n'
        f'[attention]\ncheckpoint = "{path}"\n[ctr]\ncheckpoint = "{path}"\n', encoding="utf-8")
    r = cli("run", "m.toml", "-q", "-o", "out")
    assert r.exit_code == 0, r.output
    assert "weights train/best.pt (read by attention, ctr)" in flat(r.output)
    assert str(tmp_path) not in r.output and str(path) not in r.output


def test_a_set_of_several_training_seeds_lists_them(cli, tmp_path, monkeypatch):
    """Rows of 'NAME seed S' methods (a suite's `seeds`, or a folder of seeds) are one method
    across its seeds: the manifest lists each such method's seeds; a one-run method has none."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "random.toml").write_text(RANDOM, encoding="utf-8")
    (tmp_path / "refs.toml").write_text(
        SUITE.replace('scenarios = 3', 'scenarios = 2') + 'seeds = [2, 0]\n'
        'set = ["mission.name=\'random-{seed}\'"]\n\n[[method]]\nname = "one"\n'
        'mission = "random.toml"\n', encoding="utf-8")
    r = cli("eval", "refs.toml", "-o", "refs", "-e", "serial", "-q")
    assert r.exit_code == 0, r.output
    r = cli("publish", "refs", "-o", "pub")
    assert r.exit_code == 0, r.output
    m = manifest_of(tmp_path / "pub")
    assert m["seeds"] == {"random": [0, 2]}
    assert set(m["methods"]) == {"random seed 0", "random seed 2", "one"}
