"""`ata site`: the results page. Its numbers are `ata report`'s; a set is "reproduced" only with
a rerun of this set on this code that found its rows identical; the page holds no path, date or
link out of its folder; and the page checked in under docs/site is what the command builds from
the shipped set now (its HTML and JSON byte for byte; the figures by name, since their bytes
depend on matplotlib's version: the browser test loads them)."""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest

from ata.core.errors import MissionError
from ata.published.sets import publish
from ata.results.report import summarize
from ata.site import REPORTED, REPRODUCED, build_site, tier, verify
from ata.site.board import build_board
from ata.site.sources import load_source
from ata.site.verify import installed_code
from _support import greedy_pair_suite

ROOT = Path(__file__).resolve().parent.parent
SHIPPED = ROOT / "docs" / "site"
IMAGES = (".png",)

SUITE = greedy_pair_suite(2, "always")


@pytest.fixture(scope="module")
def tiny(tmp_path_factory):
    """A two-method evaluation and the set published from it."""
    from ata.experiment.evaluate import evaluate_suites
    root = tmp_path_factory.mktemp("tiny")
    (root / "suite.toml").write_text(SUITE)
    evaluate_suites([str(root / "suite.toml")], root / "eval", executor="serial")
    publish(root / "eval", root / "tinyset")
    return root


def test_the_shipped_page_is_what_ata_site_builds_from_the_shipped_set_now(tmp_path):
    shipped = json.loads((SHIPPED / "site.json").read_text())
    site = build_site(["published"], tmp_path / "site", verified=[SHIPPED / "verified.json"],
                      draw_figures=False, command=shipped["command"])
    built = {p.name for p in site.out.iterdir()}
    held = {p.name for p in SHIPPED.iterdir()}
    assert {n for n in held if not n.endswith(IMAGES)} == built, \
        f"rebuild the page: {shipped['command']} (docs/site.md)"
    figures = re.findall(r'<img src="([^"]+)\.png"', (site.out / "index.html").read_text())
    assert figures and {n for n in held if n.endswith(IMAGES)} == \
        {f + ext for f in figures for ext in IMAGES}
    stale = [n for n in sorted(built) if (site.out / n).read_bytes() != (SHIPPED / n).read_bytes()]
    assert not stale, f"{stale} differ from what {shipped['command']} builds now (docs/site.md)"


def test_the_leaderboards_numbers_are_ata_reports(tiny):
    source = load_source(tiny / "eval")
    board = build_board([source], "greedy")
    report = summarize(source.results, "greedy")
    cells = {(c.method, c.setting, c.level): c for c in report.cells}
    assert len(board.entries) == len(cells) == 2
    for e in board.entries:
        c = cells[(e.method, e.setting, e.level)]
        assert (e.mean, e.low, e.high, e.fraction_of_u) == (c.mean, c.low, c.high,
                                                            c.fraction_of_u)
        if e.method == "greedy":
            assert e.paired_n == 0 and e.unpaired == "the base"
        else:   # method - base is the report's reference - method turned round
            assert e.paired_n == 2 and e.diff[0] == pytest.approx(-c.diff[0])
            assert (e.diff[1], e.diff[2]) == pytest.approx((-c.diff[2], -c.diff[1]))
            assert e.beats == pytest.approx(1 - c.beats)


def test_a_set_is_reproduced_only_by_a_rerun_of_it_on_this_code(tiny):
    source = load_source(f"published:{tiny / 'tinyset'}")
    assert tier(source, [])[0] == REPORTED
    record = verify(source, 1)
    assert record["identical"] and record["cells"] == 2 and not record["differ"]
    name, used, why = tier(source, [record])
    assert (name, used) == (REPRODUCED, record) and "identical" in why
    other = dict(record, code={m: {k: "0" * 16 for k in c} for m, c in record["code"].items()})
    assert tier(source, [other])[0] == REPORTED                # another code ran the rerun
    assert tier(source, [dict(record, rows_sha256="0" * 64)])[0] == REPORTED   # another set
    assert tier(source, [dict(record, identical=False)])[0] == REPORTED
    assert record["code"] == installed_code(source)
    source.seed_public = False                                  # nobody else can rerun it
    assert tier(source, [record])[:1] + ("secret" in tier(source, [record])[2],) == \
        (REPORTED, True)
    folder = load_source(tiny / "eval")
    assert tier(folder, [record])[0] == REPORTED                # a folder is as it reports
    with pytest.raises(MissionError, match="published set"):
        verify(folder, 1)


def test_the_page_names_the_tier_beside_every_row_and_holds_no_path_or_link_out(tiny, tmp_path):
    set_spec = f"published:{tiny / 'tinyset'}"
    record = verify(load_source(set_spec), 1)
    (tmp_path / "rec.json").write_text(json.dumps([record]))
    site = build_site([set_spec, str(tiny / "eval")], tmp_path / "site",
                      verified=[tmp_path / "rec.json"])
    index = (site.out / "index.html").read_text()
    rows = re.findall(r"<tr><td class=\"text\" data-v=\"(\w+)\"><span class=\"tier", index)
    # one board of 4 rows: each set's two methods, each beside its set's tier
    assert sorted(rows) == [REPORTED] * 2 + [REPRODUCED] * 2
    for page in site.out.glob("*.html"):
        text = page.read_text()
        assert str(tiny) not in text and "/tmp" not in text, page.name
        for target in re.findall(r'(?:src|href)="([^"#]+)', text):
            assert "://" not in target and (site.out / target).is_file(), (page.name, target)
    data = json.loads((site.out / "site.json").read_text())
    assert [s["tier"] for s in data["sets"]] == [REPRODUCED, REPORTED]
    # the folder's methods are paired with the set's greedy (the same model, the same scenarios)
    paired = {r["method"]: r["paired_scenarios"] for r in data["rows"]}
    assert paired == {"greedy": 0, "always": 2, "greedy [eval]": 2, "always [eval]": 2}
    assert [r["diff_to_base"][0] for r in data["rows"] if r["method"] == "greedy [eval]"] == [0]
    assert json.loads((site.out / "verified.json").read_text()) == [record]


def test_the_command_builds_a_page_and_refuses_a_folder_that_is_not_one(tiny, tmp_path, cli):
    r = cli("site", str(tiny / "eval"), "-o", tmp_path / "page", "--no-figures")
    assert r.exit_code == 0, r.output
    assert "eval: reported" in r.output and (tmp_path / "page" / "index.html").is_file()
    r = cli("site", str(tiny / "eval"), "-o", tmp_path / "page", "--no-figures", "--base",
            "always")
    assert r.exit_code == 0, r.output                            # a page is rebuilt in place
    assert "method &minus; always" in (tmp_path / "page" / "index.html").read_text()
    r = cli("run", "builtin:greedy", "-n", "1", "-o", tmp_path / "page")   # a page is no run's
    assert r.exit_code == 2 and "folder of a results page (site.json)" in r.output
    (tmp_path / "other").mkdir()
    (tmp_path / "other" / "notes.txt").write_text("mine")
    r = cli("site", str(tiny / "eval"), "-o", tmp_path / "other", "--no-figures")
    assert r.exit_code == 2 and "not a results page" in r.output
    assert (tmp_path / "other" / "notes.txt").read_text() == "mine"
    r = cli("site", str(tiny / "eval"), "-o", tmp_path / "x", "--base", "nobody")
    assert r.exit_code == 2 and "no method 'nobody'" in r.output
    r = cli("site", str(tiny / "eval"), "-o", tmp_path / "x", "--verify", "1")
    assert r.exit_code == 2 and "no published set" in r.output


SEEDED = """[suite]
settings = ["a"]
uncertainty = ["high"]
scenarios = 4
seed = 0

[[method]]
name = "greedy"
mission = "builtin:greedy"

[[method]]
name = "mine"
mission = "builtin:greedy"
set = ["components.condition=always"]

[[method]]
name = "mine seed 0"
mission = "builtin:greedy"
set = ["components.condition=never"]

[[method]]
name = "mine seed 1"
mission = "builtin:greedy"
set = ["components.condition=always"]

[[method]]
name = "mine seed 2"
mission = "builtin:greedy"
set = ["components.reconstructors=['filter']"]
"""


@pytest.fixture(scope="module")
def seeded(tmp_path_factory):
    """An evaluation with three 'training seeds' of a method beside its plain run."""
    from ata.experiment.evaluate import evaluate_suites
    root = tmp_path_factory.mktemp("seeded")
    (root / "suite.toml").write_text(SEEDED)
    evaluate_suites([str(root / "suite.toml")], root / "eval", executor="serial")
    return root / "eval"


def test_a_methods_seeds_are_one_leaderboard_row_across_seeds_and_a_page_of_each_seed(
        seeded, tmp_path):
    from ata.results.rows import beat_probability
    from ata.results.seeds import across_seeds, pair_across, seed_matrix
    site = build_site([str(seeded)], tmp_path / "site", draw_figures=False)
    seeds = ["mine seed 0", "mine seed 1", "mine seed 2"]
    [row] = site.board.seeded
    assert (row.label, row.methods, row.seeds) == ("mine (3 seeds)", seeds, [0, 1, 2])
    res = load_source(seeded).results
    mine, base = seed_matrix(res, seeds, "a", "high", also=[(res, ["greedy"])])
    assert mine.shape == (3, 4) and len(set(map(tuple, mine))) > 1      # the seeds differ
    assert row.stats == across_seeds(mine, "mine (3 seeds)", "a", "high")
    assert row.pair == pair_across(mine, base, "mine (3 seeds)", "greedy", "a", "high")
    # P(beats greedy) is each seed's share of scenarios where it scores more, over the seeds
    assert row.beats == pytest.approx(np.mean([beat_probability(m, base[0]) for m in mine]))
    plain = seed_matrix(res, ["mine"], "a", "high")[0]
    assert row.default == pair_across(mine, plain, "mine (3 seeds)", "mine", "a", "high")
    index = (site.out / "index.html").read_text()
    board = index[index.index('id="table-a-high"'):]
    linked = re.findall(r'<a href="([^"]+)">([^<]+)</a>', board[:board.index("</table>")])
    # the plain runs and the seeds as one row: no seed's own row
    assert sorted(name for _, name in linked) == ["greedy", "mine", "mine (3 seeds)"]
    assert board.count('<tr class="seeds">') == 1
    page = dict((name, href) for href, name in linked)["mine (3 seeds)"]
    text = (site.out / page).read_text()
    for seed in seeds:           # each seed's row, linked to its own page
        assert re.search(rf'<a href="(method-[^"]+)">{seed}</a>', text)
    for href in re.findall(r'href="([^"#]+)"', text):
        assert (site.out / href).is_file(), href
    [across] = json.loads((site.out / "site.json").read_text())["across_seeds"]
    assert (across["seeds"], across["scenarios"], across["seed_methods"]) == (3, 4, seeds)
    assert across["mean"] == pytest.approx(mine.mean())
    assert across["diff_to_base"][0] == pytest.approx(mine.mean() - base.mean())


def test_a_second_set_s_seeds_keep_their_method_s_name_on_the_page(seeded, tmp_path):
    from ata.results import seeds as sd
    from ata.site.board import labels, merged
    sources = [load_source(seeded), load_source(seeded)]
    sources[1].name = "again"
    names = labels(sources)
    assert names[(1, "mine seed 2")] == "mine [again] seed 2"
    assert names[(1, "mine")] == "mine [again]"
    # the figures read the merged rows: each set's seeds are one method there
    assert {k: len(v) for k, v in sd.seeded(merged(sources).methods).items()} == \
        {"mine": 3, "mine [again]": 3}
    site = build_site([str(seeded), str(seeded)], tmp_path / "site", draw_figures=False)
    assert [g.label for g in site.board.seeded] == ["mine (3 seeds)", "mine (3 seeds) [eval-2]"]


def test_a_set_without_seeds_has_no_row_across_seeds(tiny, tmp_path):
    site = build_site([str(tiny / "eval")], tmp_path / "site", draw_figures=False)
    assert site.board.seeded == [] and not [f for f in site.files if f.startswith("seeds-")]
    assert json.loads((site.out / "site.json").read_text())["across_seeds"] == []
