"""Limits at the edges (settings that size an allocation, huge integers, deep nesting, long or
hostile names) and the smaller faults an operator can cause: each one line and exit 2, or
working."""

from __future__ import annotations

import csv
import importlib
import pickle
import sys
import warnings

import numpy as np
import pytest

from _support import assert_user_error, flat, small_mission
from ata.runtime import folders
from ata.cli import terminal
from ata.results.rows import bootstrap_ci

SMALL = small_mission(2)


@pytest.fixture
def small(tmp_path):
    path = tmp_path / "small.toml"
    path.write_text(SMALL, encoding="utf-8")
    return path


# --- 6. limits ------------------------------------------------------------------------------------

@pytest.mark.parametrize("override, message", [
    ("mission.horizon_s=6e11", "[mission] key 'horizon_s': 600000000000.0 is above the maximum; "
                               "allowed: 1.0 to 86400.0"),
    ("mission.epoch_s=1", None),
])
def test_the_horizon_is_bounded_before_anything_is_allocated(cli, small, override, message):
    if message is None:                 # a day of one-second epochs: too many epochs
        result = cli("check", small, "--set", "mission.horizon_s=86400", "--set", override,
                     "--set", "mission.tick_s=1")
        assert_user_error(result, "[mission] key 'horizon_s': 86400 s is 86400 epochs of 1 s, "
                                  "more than 10,000")
    else:
        assert_user_error(cli("check", small, "--set", override), message)


def test_resamples_are_bounded_and_the_bootstrap_memory_is_not(cli, small, tmp_path):
    result = cli("report", tmp_path, "--resamples", 1_000_000_000)
    assert result.exit_code == 2 and "Traceback" not in result.output
    assert "--resamples" in result.output
    values = np.arange(50.0)
    # drawn in blocks: the same interval as one matrix
    from ata.results import rows as results
    whole = bootstrap_ci(values, 3000)
    old = results.BOOTSTRAP_BLOCK
    try:
        results.BOOTSTRAP_BLOCK = 50 * 7
        assert bootstrap_ci(values, 3000) == whole
    finally:
        results.BOOTSTRAP_BLOCK = old


@pytest.mark.parametrize("text, why", [
    ("[mission]\nseed = " + "9" * 5000 + "\n", "an integer of more than 20 digits: refused"),
    ("[mission]\nname = " + "[" * 5000 + "]" * 5000 + "\n",
     "values nested more than 16 deep: refused"),
    ("[mission]\nname = " + "{a=" * 3000 + "1" + "}" * 3000 + "\n",
     "values nested more than 16 deep: refused"),
    ("[mission]\nname = " + "[" * 40 + "]" * 40 + "\n", "values nested more than 16 deep"),
])
def test_huge_integers_and_deep_nesting_are_one_line(cli, tmp_path, text, why):
    path = tmp_path / "m.toml"
    path.write_text(text, encoding="utf-8")
    assert_user_error(cli("check", path), f"error: {path}: {why}")


def test_huge_integers_and_deep_nesting_in_set_and_the_gym_adapter(cli, small, tmp_path):
    assert_user_error(cli("check", small, "--set", "mission.seed=" + "9" * 5000),
                      "error: --set: mission.seed: an integer of more than 20 digits: refused")
    assert_user_error(cli("check", small, "--set", "mission.name=" + "[" * 5000 + "]" * 5000),
                      "error: --set: mission.name: values nested more than 16 deep: refused")
    pytest.importorskip("gymnasium")
    import ata.gym
    from ata.core.errors import MissionError
    path = tmp_path / "deep.toml"
    path.write_text("[mission]\nname = " + "[" * 5000 + "]" * 5000 + "\n", encoding="utf-8")
    with pytest.raises(MissionError, match="values nested more than 16 deep"):
        ata.gym.make(path)


def test_a_long_name_makes_a_short_folder_and_a_short_line(cli, small, tmp_path, monkeypatch):
    monkeypatch.setenv("ATA_RUNS", str(tmp_path / "runs"))
    name = "n" * 300
    result = cli("run", small, "-q", "--set", f'mission.name="{name}"')
    assert result.exit_code == 0, result.output
    (folder,) = (tmp_path / "runs").iterdir()
    assert len(folder.name) < 100 and folder.name.startswith("n" * folders.NAME_LIMIT + "-")
    assert name not in result.output
    huge = "x" * 2_000_000
    (tmp_path / "huge.toml").write_text(SMALL.replace('"small"', f'"{huge}"').replace(
        "tasks = 10", "tasks = 0"), encoding="utf-8")
    result = cli("run", tmp_path / "huge.toml", "-q")
    assert_user_error(result, "[mission] key 'tasks'")
    assert len(result.output) < 2000


def test_an_over_long_out_is_one_line(cli, small, tmp_path):
    out = tmp_path / ("x" * 300)
    assert_user_error(cli("run", small, "-q", "-o", out),
                      "a folder name of 300 bytes, more than the 255 a file name may hold")
    assert_user_error(cli("show", small, "-o", out), "a folder name of 300 bytes")


def test_terminal_text_loses_control_characters_and_length():
    assert terminal.plain("a\x1b[2K\rb") == "a\\x1b[2K\\x0db"
    assert terminal.plain("a\nb", newlines=False) == "a\\x0ab"
    long = terminal.plain("y" * 10_000)
    assert len(long) < 200 and "characters left out" in long


# --- 8. the smaller ones ----------------------------------------------------------------------------

def test_ansi_escapes_in_a_title_do_not_reach_the_terminal(cli, small, tmp_path):
    forged = "\x1b[2K\rsmall: score 999.0"
    small.write_text(SMALL.replace('name = "small"', f'name = "small"\ntitle = "{forged!s}"'
                                   .replace("\x1b", "\\u001b").replace("\r", "\\r")))
    result = cli("run", small, "-q", "-o", tmp_path / "out")
    assert result.exit_code == 0, result.output
    assert "\x1b" not in result.output and "\r" not in result.output
    assert "\\x1b[2K\\x0dsmall: score 999.0" in result.output


def test_a_results_file_saved_by_a_spreadsheet_is_read(cli, small, tmp_path):
    out = tmp_path / "run"
    assert cli("run", small, "-q", "-o", out).exit_code == 0
    path = out / "results.csv"
    text = path.read_text(encoding="utf-8")
    path.write_bytes(b"\xef\xbb\xbf" + text.replace("\n", "\r\n").encode("utf-8"))
    result = cli("report", out, "--no-figures")
    assert result.exit_code == 0, result.output
    with open(path, newline="", encoding="utf-8-sig") as f:
        assert len(list(csv.DictReader(f))) == 2


def test_runs_at_two_levels_are_labelled_with_both(cli, small, tmp_path):
    a, b = tmp_path / "a", tmp_path / "b"
    assert cli("run", small, "-q", "-o", a).exit_code == 0
    assert cli("run", small, "-q", "--set", "mission.uncertainty='high'", "-o", b).exit_code == 0
    result = cli("compare", a, b, "--full")
    assert result.exit_code == 0, result.output
    assert "setting custom, medium - high uncertainty: A - B, paired" in flat(result.output)
    compact = cli("compare", a, b)
    assert compact.exit_code == 0, compact.output
    assert "medium - high uncertainty" in flat(compact.output)


def test_a_lazy_plugin_that_registers_nothing_is_named(cli, small, tmp_path, monkeypatch):
    site = tmp_path / "site"
    site.mkdir()
    (site / "ata_promised.py").write_text("x = 1\n")
    info = site / "ata_promised-0.1.0.dist-info"
    info.mkdir()
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: ata-promised\nVersion: 0.1.0\n")
    (info / "entry_points.txt").write_text("[ata.components]\npolicy.promised = ata_promised\n")
    monkeypatch.syspath_prepend(str(site))
    monkeypatch.delitem(sys.modules, "ata_promised", raising=False)
    importlib.invalidate_caches()
    result = cli("check", small, "--set", "components.initial='promised'")
    assert_user_error(result, "policy 'promised' is declared by package ata-promised 0.1.0 "
                              "(entry point policy.promised = ata_promised, group "
                              "'ata.components'), but its plugin ata_promised registered no "
                              "policy of that name")
    assert "did you mean" not in result.output


def test_a_bad_milp_cache_entry_is_named_and_solved_again(small, tmp_path):
    import json

    from ata.session import load_session
    from ata.experiment.units import run_batch
    from ata.runtime.cache import run_cache
    session = load_session(str(small), ["components.initial='milp'",
                                               "components.condition='never'"])
    with run_cache(tmp_path / "cache"):
        first = run_batch(session.mission, session.registry, np.arange(1))
    (entry,) = (tmp_path / "cache" / "milp").rglob("*.json")
    rec = json.loads(entry.read_text())
    rec["triples"] = [[99, 99, 99]] * len(rec["triples"])
    entry.write_text(json.dumps(rec))
    with run_cache(tmp_path / "cache"), pytest.warns(RuntimeWarning,
                                                     match=f"cache entry {entry} names a robot"):
        again = run_batch(session.mission, session.registry, np.arange(1))
    assert again["total"].tolist() == first["total"].tolist()
    assert json.loads(entry.read_text())["triples"] != rec["triples"]         # rewritten


def test_show_animate_caps_its_frames():
    from types import SimpleNamespace

    from ata.viz.animate import MAX_FRAMES, frame_epochs
    long = SimpleNamespace(epoch_times=np.arange(720) * 60.0)
    picked = frame_epochs(long)
    assert len(picked) <= MAX_FRAMES + 1 and picked[0] == 0 and picked[-1] == 719
    short = SimpleNamespace(epoch_times=np.arange(30) * 60.0)
    assert frame_epochs(short).tolist() == list(range(30))


def test_the_gym_adapter_checks_overrides_and_num_envs():
    pytest.importorskip("gymnasium")
    import ata.gym
    with pytest.raises(TypeError, match="not one string: overrides=\\['mission.seed=3'\\]"):
        ata.gym.make(None, overrides="mission.seed=3")
    for bad, error in ((2.5, TypeError), ("4", TypeError), (True, TypeError), (0, ValueError),
                       (10**9, ValueError)):
        with pytest.raises(error, match="num_envs"):
            ata.gym.make_vec(None, num_envs=bad)


def test_a_plain_pickle_as_a_checkpoint_is_one_line_without_torch_warnings(cli, small, tmp_path):
    pytest.importorskip("torch")
    path = tmp_path / "plain.pkl"
    path.write_bytes(pickle.dumps({"a": 1}, protocol=4))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        result = cli("check", small, "--set", "components.initial='attention'",
                     "--set", f"attention.checkpoint='{path}'")
    assert_user_error(result, f"error: {path}: checkpoint: cannot be read as a checkpoint")
    assert not [w for w in caught if "pickle protocol" in str(w.message)]


def test_settings_that_size_an_allocation_have_an_upper_bound_and_its_reason():
    from ata.core.mission import MissionSettings
    from ata.core.settings import describe
    rows = {key: (allowed, text) for key, _, _, allowed, text in describe(MissionSettings)}
    for key in ("humans", "robots", "tasks", "scenarios", "batch_size", "workers", "horizon_s"):
        allowed, text = rows[key]
        assert " to " in allowed, (key, allowed)                      # a maximum
        assert "(" in text or "at most" in text, (key, text)         # and why


def test_a_declared_component_a_bare_registry_does_not_load_is_named_not_suggested():
    from ata.core.errors import MissionError
    from ata.core.registry import Register

    with pytest.raises(MissionError) as caught:
        Register().get("policy", "attention", "[components] initial")
    text = str(caught.value)
    assert "policy 'attention' is declared by the plugin ata.plugins.ata_hrl" in text
    assert "collect_components(get_plugin_manager())" in text
    assert "did you mean 'attention'" not in text and "unknown policy" not in text
