"""`--isolate`: untrusted decision components in a sandbox, checked for results and peeking.

Decision components in a sandboxed process give the in-process results, find nothing of the
world by the routes an adversarial author would try, keep to a time limit, and are refused
with one line where no sandbox can run."""

from __future__ import annotations

import importlib
import json
import shutil
import struct
import sys
from pathlib import Path

import numpy as np
import pytest

from ata.core.errors import ContractError, MissionError
from ata.isolation import Isolated, require_sandbox
from ata.isolation import process as isolate
from ata.session import load_session
from ata.experiment.units import run_batch, one_thread
from ata.runtime import frames, sandbox

NO_SANDBOX = sandbox.unavailable()
needs_sandbox = pytest.mark.skipif(NO_SANDBOX is not None,
                                   reason=f"needs a sandbox, and {NO_SANDBOX}")
METHODS = Path(__file__).parent / "isolate_methods"
SHORT = ["mission.scenarios=4", "mission.batch_size=4", "mission.horizon_s=600"]
SECRET_SEED = 7_100_200_300_400_500_600


@pytest.fixture
def peekers(monkeypatch):
    """The peeking policies' plugin module (a module file of its own, so that the sandbox
    shows that file and nothing else of the tests)."""
    monkeypatch.syspath_prepend(str(METHODS))
    return importlib.import_module("ata_isolate_peekers")


def rows(out: dict) -> dict:
    """A batch's per-scenario results, without the columns only an isolated run has."""
    return {k: np.asarray(v) for k, v in out.items()
            if k not in ("warnings", "wall_s", f"m:{isolate.TIMEOUT_COLUMN}")}


def assert_same(a: dict, b: dict) -> None:
    a, b = rows(a), rows(b)
    assert sorted(a) == sorted(b)
    for k in a:
        np.testing.assert_array_equal(a[k], b[k], err_msg=k)


def differ(a: dict, b: dict) -> bool:
    a, b = rows(a), rows(b)
    return any(not np.array_equal(a[k], b[k]) for k in a)


def both(session, iso: Isolated, ids=np.arange(4)) -> tuple[dict, dict]:
    with one_thread():
        inside = run_batch(session.mission, session.registry, ids)
        apart = run_batch(session.mission, session.registry, ids, backend=iso)
    return inside, apart


# -- (a) the same results as in-process ----------------------------------------------------------
@needs_sandbox
def test_isolated_greedy_gives_the_in_process_results():
    inside, apart = both(load_session("builtin:greedy", SHORT), require_sandbox(60))
    assert_same(inside, apart)
    np.testing.assert_array_equal(apart[f"m:{isolate.TIMEOUT_COLUMN}"], 0.0)


@needs_sandbox
def test_isolated_ata_hrl_gives_the_in_process_results(tmp_path, monkeypatch):
    # the sandboxed process reads the loops the in-process run compiled (about 10 s; about 50
    # compiling them itself)
    # its weights named by a relative path through a link: the sandbox shows the file there
    (tmp_path / "weights").mkdir()
    shutil.copy(Path(sandbox.ata_dir()) / "weights" / "ata_hrl_a.pt", tmp_path / "weights")
    (tmp_path / "mine.pt").symlink_to(tmp_path / "weights" / "ata_hrl_a.pt")
    monkeypatch.chdir(tmp_path)
    session = load_session("builtin:default", ["mission.scenarios=3", "mission.batch_size=3",
                                               "mission.horizon_s=600",
                                               *[f"{c}.checkpoint='mine.pt'"
                                                 for c in ("attention", "ctr", "aux")]])
    assert session.mission.slots.reconstructors != ["identity"]   # the aux reconstructor too
    inside, apart = both(session, require_sandbox(120), np.arange(3))
    assert_same(inside, apart)


# -- (b) the routes to the world: found in-process, not in the sandbox ---------------------------
def peek_session(peekers, policy: str, *extra: str):
    return load_session("builtin:greedy", [*SHORT, f"components.initial='{policy}'", *extra],
                        extra=(peekers,))


@needs_sandbox
@pytest.mark.parametrize("policy", ["peek_gc", "peek_frames", "peek_thread", "peek_argv",
                                    "peek_env", "peek_files"])
def test_a_peeking_policy_finds_nothing_in_the_sandbox(peekers, policy, monkeypatch):
    monkeypatch.setenv(peekers.SECRET_ENV, "the host's secret")
    iso = require_sandbox(60)
    honest = peek_session(peekers, "peek_none")
    peeker = peek_session(peekers, policy)
    ids = np.arange(4)
    assert_same(run_batch(honest.mission, honest.registry, ids, backend=iso),
                run_batch(peeker.mission, peeker.registry, ids, backend=iso))


@pytest.mark.parametrize("policy", ["peek_gc", "peek_frames", "peek_env"])
def test_without_isolation_the_routes_find_the_world(peekers, policy, monkeypatch):
    """The test above can fail: in the host's process, the same policies find it."""
    monkeypatch.setenv(peekers.SECRET_ENV, "the host's secret")
    honest = peek_session(peekers, "peek_none")
    peeker = peek_session(peekers, policy)
    ids = np.arange(4)
    assert differ(run_batch(honest.mission, honest.registry, ids),
                  run_batch(peeker.mission, peeker.registry, ids))


# -- (c) a secret seed stays in the host ---------------------------------------------------------
@needs_sandbox
def test_the_sandbox_cannot_read_a_secret_seed(peekers, tmp_path, monkeypatch):
    monkeypatch.setenv(peekers.SEED_ENV, str(SECRET_SEED))
    mission = tmp_path / "secret.toml"
    mission.write_text(f'[mission]\nseed = "env:{peekers.SEED_ENV}"\nhorizon_s = 600.0\n'
                       "scenarios = 4\nbatch_size = 4\n")
    honest = load_session(str(mission), ["components.initial='peek_none'"], extra=(peekers,))
    peeker = load_session(str(mission), ["components.initial='peek_env'"], extra=(peekers,))
    assert honest.mission.secret_seed
    iso, ids = require_sandbox(60), np.arange(4)
    assert_same(run_batch(honest.mission, honest.registry, ids, backend=iso),
                run_batch(peeker.mission, peeker.registry, ids, backend=iso))
    # in the host's process, the same policy reads it
    assert differ(run_batch(honest.mission, honest.registry, ids),
                  run_batch(peeker.mission, peeker.registry, ids))


# -- (d) the time limit --------------------------------------------------------------------------
@needs_sandbox
def test_a_reallocation_past_the_time_limit_keeps_the_allocation_and_is_counted(peekers):
    session = load_session("builtin:greedy", [*SHORT, "components.condition='always'",
                                              "components.reallocation='sleepy'",
                                              "sleepy.seconds=5.0", "sleepy.at_epoch=2"],
                           extra=(peekers,))
    out = run_batch(session.mission, session.registry, np.arange(4),
                    backend=require_sandbox(0.5))
    np.testing.assert_array_equal(out[f"m:{isolate.TIMEOUT_COLUMN}"], 1.0)
    assert any("decision time limit of 0.5 s was exceeded" in w for w in out["warnings"])
    # epoch 1 reallocated (always), then the process was stopped at epoch 2: none after
    np.testing.assert_array_equal(out["reallocations"], 2)


@needs_sandbox
def test_an_initial_allocation_past_the_time_limit_fails_the_batch(peekers):
    session = load_session("builtin:greedy", [*SHORT, "components.initial='sleepy'",
                                              "sleepy.seconds=5.0", "sleepy.at_epoch=0"],
                           extra=(peekers,))
    with pytest.raises(isolate.DecisionTimeout, match=r"initial policy 'sleepy' took longer "
                       r"than the decision time limit of 0.5 s .*the batch fails"):
        run_batch(session.mission, session.registry, np.arange(4),
                  backend=require_sandbox(0.5))


@needs_sandbox
def test_an_error_in_the_decision_process_comes_back_as_text(peekers, monkeypatch):
    session = load_session("builtin:greedy", [*SHORT, "components.initial='sleepy'",
                                              "sleepy.seconds=-1.0", "sleepy.at_epoch=0"],
                           extra=(peekers,))
    with pytest.raises(isolate.ChildFailed, match="ValueError: sleep length must be "
                                                  "non-negative"):
        run_batch(session.mission, session.registry, np.arange(4),
                  backend=require_sandbox(10))


# -- (e) no sandbox: one line, exit 2 ------------------------------------------------------------
def test_isolate_refuses_where_no_sandbox_can_run(cli, monkeypatch):
    monkeypatch.setattr(sandbox, "probe", lambda: "user namespaces are off here")
    for args in (["run", "builtin:greedy", "--isolate"], ["eval", "suite.toml", "--isolate"]):
        result = cli(*args)
        assert result.exit_code == 2
        text = " ".join(result.output.split())
        assert "--isolate: no sandbox can run here: user namespaces are off here" in text
        assert "pip install 'ata[sandbox]'" in text


# -- the run path and the channel ----------------------------------------------------------------
@needs_sandbox
def test_ata_run_isolate_on_the_process_executor(cli, tmp_path):
    base = ["run", "builtin:greedy", "--set", "mission.scenarios=4", "--set",
            "mission.horizon_s=600", "--chunk-size", "2", "-q"]
    plain = cli(*base, "--out", str(tmp_path / "plain"))
    apart = cli(*base, "--isolate", "--executor", "process", "--workers", "2",
                "--out", str(tmp_path / "apart"))
    assert plain.exit_code == 0, plain.output
    assert apart.exit_code == 0, apart.output
    a = (tmp_path / "plain" / "results.csv").read_text().splitlines()
    b = (tmp_path / "apart" / "results.csv").read_text().splitlines()
    assert b[0] == a[0] + ",decision_timeouts"
    assert b[1:] == [line + ",0.0" for line in a[1:]]


@needs_sandbox
def test_ata_eval_isolate_gives_the_rows_of_ata_eval(cli, tmp_path, monkeypatch):
    monkeypatch.setenv("ATA_ISOLATE_TEST_EVAL_SEED", str(SECRET_SEED))
    suite = tmp_path / "suite.toml"
    suite.write_text('[suite]\nname = "tiny"\nscenarios = 2\nseed = '
                     '"env:ATA_ISOLATE_TEST_EVAL_SEED"\n'
                     '[[method]]\nname = "greedy"\nmission = "builtin:greedy"\n'
                     'set = ["mission.horizon_s=600"]\n'
                     '[[method]]\nname = "random"\nmission = "builtin:greedy"\n'
                     'set = ["mission.horizon_s=600", "components.initial=\'random\'"]\n')
    base = ["eval", suite, "--executor", "serial", "--no-cache", "-q"]
    plain = cli(*base, "--out", tmp_path / "plain")
    apart = cli(*base, "--isolate", "--decision-timeout", "30", "--out", tmp_path / "apart")
    assert plain.exit_code == 0, plain.output
    assert apart.exit_code == 0, apart.output

    def rows(folder):
        lines = (folder / "results.csv").read_text().splitlines()
        head = lines[0].split(",")
        keep = [i for i, c in enumerate(head) if c not in ("wall_s", isolate.TIMEOUT_COLUMN)]
        return [[line.split(",")[i] for i in keep] for line in lines]

    assert rows(tmp_path / "apart") == rows(tmp_path / "plain")
    assert str(SECRET_SEED) not in (tmp_path / "apart" / "results.csv").read_text()
    eval_json = json.loads((tmp_path / "apart" / "eval.json").read_text())
    assert eval_json["arguments"]["isolate"]["decision_timeout_s"] == 30


def test_a_safe_frame_carries_numbers_only():
    header, arrays = frames.decode_safe(frames.encode_safe(
        {"x": 1}, {"a": np.arange(6, dtype=np.int16).reshape(2, 3), "b": np.ones(2, bool)}))
    assert header == {"x": 1} and arrays["a"].shape == (2, 3) and arrays["b"].dtype == bool
    for dtype in ("|O", "<V8", "|S4"):           # objects, raw records, bytes: refused unread
        head = json.dumps({"arrays": [["a", dtype, [1], 8]]}).encode()
        with pytest.raises(frames.FrameError, match="out of format"):
            frames.decode_safe(struct.pack("<I", len(head)) + head + b"\0" * 8)
    with pytest.raises(frames.FrameError):
        frames.decode_safe(b"\x80\x05pickled")


def test_a_reference_reconstructor_is_refused():
    session = load_session("builtin:greedy", [*SHORT, "components.reconstructors=['oracle']"])
    with pytest.raises(MissionError, match="reference"):
        isolate.method_code(session.mission, session.registry)


def test_the_sandbox_shows_the_package_not_the_checkout():
    argv = sandbox.command(["true"]) if sandbox.bwrap_path() else []
    if not argv:
        pytest.skip(f"needs bwrap, and {NO_SANDBOX}")
    shown = [argv[i + 2] for i, a in enumerate(argv) if a == "--ro-bind"]
    checkout = str(Path(sandbox.ata_dir()).parent)
    assert sandbox.ata_dir() in shown and checkout not in shown
    assert "--unshare-all" in argv and "--clearenv" in argv and "--die-with-parent" in argv
    assert sys.prefix in shown or any(sys.prefix.startswith(s) for s in shown)


def test_contract_errors_from_the_process_are_contract_errors():
    assert issubclass(isolate.DecisionTimeout, ContractError)


def test_the_decision_process_finds_the_hosts_compiled_loops(tmp_path):
    # the package is read-only in the sandbox, where numba caches nothing beside it: the
    # process copies the host's cached loops into its own numba cache, where numba loads them
    # without compiling (NUMBA_DEBUG_CACHE says where each comes from)
    import os
    import subprocess

    from ata.model import scalar
    assert scalar.workload(0.5) == 1.0                  # compiled and cached by the host
    cache = tmp_path / "numba"
    env = {**os.environ, "NUMBA_CACHE_DIR": str(cache)}
    code = ("from ata.runtime.decider import seed_compiled_cache; seed_compiled_cache(); "
            "from ata.model import scalar; print(scalar.workload(0.5))")
    done = subprocess.run([sys.executable, "-c", code], env={**env, "NUMBA_DEBUG_CACHE": "1"},
                          capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    out = done.stdout + done.stderr
    assert "1.0" in done.stdout
    assert f"data loaded from '{cache}" in out and "data saved to" not in out, out


def test_the_decision_process_finds_a_methods_own_compiled_loops(tmp_path):
    # a method's loops (compiled with the host's jit) are cached beside its code by the host:
    # the process copies them too, walking a plugin package whole, and only the folder of a
    # plugin file
    import os
    import subprocess
    loop = "from ata.model.scalar import jit\n\n\n@jit\ndef twice(x):\n    return 2.0 * x\n"
    (tmp_path / "mypkg" / "inner").mkdir(parents=True)
    (tmp_path / "mypkg" / "__init__.py").write_text("")
    (tmp_path / "mypkg" / "inner" / "__init__.py").write_text("")
    (tmp_path / "mypkg" / "inner" / "loops.py").write_text(loop)
    (tmp_path / "solo.py").write_text(loop)
    calls = ("import sys; sys.path.insert(0, {root!r}); import mypkg.inner.loops as a, solo; "
             "{seed}print(a.twice(2.0), solo.twice(3.0))")
    root = str(tmp_path)
    host = subprocess.run([sys.executable, "-c", calls.format(root=root, seed="")],
                          capture_output=True, text=True, timeout=300)
    assert host.returncode == 0 and "4.0 6.0" in host.stdout, host.stderr
    assert list(tmp_path.glob("__pycache__/solo.twice-*.nbi"))
    assert list(tmp_path.glob("mypkg/inner/__pycache__/loops.twice-*.nbi"))
    cache = tmp_path / "numba"
    seed = ("from ata.runtime.decider import seed_compiled_cache; "
            "seed_compiled_cache(['mypkg.inner.loops', 'solo']); ")
    done = subprocess.run([sys.executable, "-c", calls.format(root=root, seed=seed)],
                          env={**os.environ, "NUMBA_CACHE_DIR": str(cache),
                               "NUMBA_DEBUG_CACHE": "1"},
                          capture_output=True, text=True, timeout=300)
    out = done.stdout + done.stderr
    assert done.returncode == 0 and "4.0 6.0" in done.stdout, done.stderr
    assert "data saved to" not in out, out
    for name in ("loops.twice", "solo.twice"):
        assert any(name in line and f"data loaded from '{cache}" in line
                   for line in out.splitlines()), out
