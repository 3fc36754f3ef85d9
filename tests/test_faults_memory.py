"""The memory estimate per component (the ``ata_peak_bytes`` hook, with the planner's arrays
and the kernel's record as the default) and the fixed cost of each worker process: a mission
too large is cut into smaller batches, or refused before any work starts, naming the figure
and the limit, in `ata run`, `ata eval` and the Gymnasium adapters."""

from __future__ import annotations

import pytest

from _support import assert_user_error
from ata.experiment import runner
from ata.session import load_session
from ata.runtime import memory

TEAM = """\
[mission]
name = "big"
setting = "custom"
humans = {humans}
robots = {robots}
tasks = {tasks}
scenarios = {scenarios}

[components]
initial = "{initial}"
condition = "never"
"""


def mission(tmp_path, initial="greedy", humans=2, robots=3, tasks=10, scenarios=4):
    path = tmp_path / f"{initial}-{tasks}.toml"
    path.write_text(TEAM.format(initial=initial, humans=humans, robots=robots, tasks=tasks,
                                scenarios=scenarios), encoding="utf-8")
    return path


def test_the_components_are_asked_once_built(tmp_path):
    pytest.importorskip("torch")
    session = load_session(str(mission(tmp_path, "attention", 6, 8, 10_000, 10)))
    m = session.mission
    default = memory.batch_peak(m, 10)
    runner.build_once(session)
    tokens = 10_000 + 6 + 8
    # the encoder's (batch, heads, tokens, tokens) scores: 16 GB was what killed the run
    assert memory.batch_peak(m, 10) - default >= 10 * 4 * 4 * tokens * tokens
    assert memory.component_bytes(m, 10) == memory.batch_peak(m, 10) - default


def test_ata_hrl_too_large_for_memory_is_refused_before_any_work(cli, tmp_path, monkeypatch):
    pytest.importorskip("torch")
    path = mission(tmp_path, "attention", 6, 8, 300, 2)
    session = load_session(str(path))
    runner.build_once(session)
    limit = memory.batch_peak(session.mission, 1) - 1
    assert limit > 2 * memory.batch_peak(load_session(str(path)).mission, 2)  # default
    monkeypatch.setattr(memory, "memory_limit", lambda: limit)
    out = tmp_path / "out"
    result = cli("run", path, "-q", "-o", out)
    assert_user_error(result, f"error: {path}: [mission] key 'tasks': one scenario of 300 POIs, "
                              "8 robots and 6 humans needs about", "more than the")
    assert not out.exists()


def test_itamilp_at_a_huge_team_is_refused_not_a_memory_error(cli, tmp_path):
    path = mission(tmp_path, "milp", 300, 400, 2000, 1)
    result = cli("run", path, "-q", "-o", tmp_path / "out")
    assert_user_error(result, "one scenario of 2000 POIs, 400 robots and 300 humans needs "
                              "about", "run fewer POIs")


def test_each_worker_is_counted(cli, tmp_path, monkeypatch):
    path = mission(tmp_path)
    session = load_session(str(path))
    m = session.mission
    assert memory.run_peak(m, 1, 16) >= 16 * memory.WORKER_BYTES
    assert memory.run_peak(m, 1, 1) == memory.batch_peak(m, 1)          # serial: none
    monkeypatch.setattr(memory, "memory_limit", lambda: memory.WORKER_BYTES)
    result = cli("run", path, "-q", "-w", 2, "-o", tmp_path / "out")
    assert_user_error(result, "in each of 2 workers (with 0.3 GiB each worker holds anyway)",
                      "or fewer workers")
    result = cli("run", path, "-q", "-o", tmp_path / "serial")
    assert result.exit_code == 0, result.output


def test_eval_counts_the_components(cli, tmp_path, monkeypatch):
    pytest.importorskip("torch")
    path = mission(tmp_path, "attention", 6, 8, 300, 2)
    session = load_session(str(path))
    runner.build_once(session)
    limit = memory.batch_peak(session.mission, 2) - 1
    monkeypatch.setattr(memory, "memory_limit", lambda: limit)
    result = cli("eval", path, "-e", "serial", "-n", 2, "--chunk-size", 2, "--no-cache", "-q",
                 "-o", tmp_path / "out")
    assert_user_error(result, "error: --chunk-size: batches of 2 scenarios of 'big' need about",
                      "give a --chunk-size of at most 1")


def test_the_gym_adapter_refuses_num_envs_too_large_for_memory(tmp_path, monkeypatch):
    pytest.importorskip("gymnasium")
    import ata.gym
    from ata.core.errors import MissionError
    path = mission(tmp_path)
    session = load_session(str(path))
    monkeypatch.setattr(memory, "memory_limit",
                        lambda: memory.batch_peak(session.mission, 4))
    with pytest.raises(MissionError, match="num_envs: 64 scenarios of 'big' stepped together "
                                           "need about .* give num_envs of at most [1-4]$"):
        ata.gym.make_vec(path, num_envs=64)
    assert ata.gym.make_vec(path, num_envs=2).num_envs == 2
