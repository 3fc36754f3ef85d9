"""The host bounds what it reads from a sandboxed decision process: an answer over its call's
limit is refused before it is read, a header nested too deep is a frame error, an answer is
held once, and a method from a file cannot take the name of a component ata already has."""

import hashlib
import os
import struct
import time
from pathlib import Path

import numpy as np
import pytest

from ata.core.errors import MissionError
from ata.core.mission import read_toml
from ata.isolation.remote import isolated_registry
from ata.runtime import frames, sandbox

EXAMPLE = Path(__file__).resolve().parent.parent / "examples" / "policies"


def test_an_answer_over_the_calls_limit_is_refused_before_it_is_read():
    r, w = os.pipe()
    pipe = frames.HostPipe(os.dup(w), r)
    os.write(w, struct.pack("<Q", frames.answer_limit(4) + 1))   # the length alone
    with pytest.raises(frames.FrameError, match="over the limit"):
        pipe.recv(time.monotonic() + 5, frames.answer_limit(4))
    os.close(w)
    pipe.close()


def test_a_header_nested_too_deep_is_a_frame_error():
    deep = b"[" * 200_000 + b"]" * 200_000
    with pytest.raises(frames.FrameError, match="nested too deep"):
        frames.decode_safe(struct.pack("<I", len(deep)) + deep)
    nested = b'{"a": ' + b"[" * 40 + b"]" * 40 + b"}"
    with pytest.raises(frames.FrameError, match="nested deeper"):
        frames.decode_safe(struct.pack("<I", len(nested)) + nested)


def test_an_answer_is_held_once():
    arrays = {"robot": np.arange(12, dtype=np.int64).reshape(3, 4),
              "active": np.ones(3, dtype=bool), "values": np.linspace(0, 1, 5)}
    payload = bytearray(frames.encode_safe({"x": 1}, arrays))
    header, got = frames.decode_safe(payload)
    assert header == {"x": 1}
    for name, value in arrays.items():
        np.testing.assert_array_equal(got[name], value)
        assert np.shares_memory(got[name], np.frombuffer(payload, dtype=np.uint8)), name


def test_a_method_from_a_file_cannot_take_a_builtin_name(tmp_path):
    # the decision process refuses this itself; the host checks it again, since a method may
    # change what its process answers: here, an answer that names the file's class "greedy"
    policy = tmp_path / "nearest_capable.py"
    policy.write_text((EXAMPLE / "nearest_capable.py").read_text())
    mission = tmp_path / "mine.toml"
    mission.write_text((EXAMPLE / "nearest_capable.toml").read_text())
    digest = hashlib.sha256(policy.read_bytes()).hexdigest()

    def lying(raw, source, wanted, files=(), folders=()):
        return {"components": [{"kind": kind, "name": name, "values": None,
                                "resolved": "greedy", "sha256": digest}
                               for kind, name in wanted]}

    raw = read_toml(str(mission))
    with pytest.raises(MissionError, match="'greedy', the name of a policy ata already has"):
        isolated_registry(raw, [], str(mission), lying, lambda entry_point: {"components": []})


@pytest.mark.skipif(sandbox.unavailable() is not None, reason=str(sandbox.unavailable()))
def test_isolate_on_a_public_seed_says_a_ranking_needs_a_secret_one(cli, tmp_path, monkeypatch):
    base = ["run", "builtin:greedy", "--set", "mission.scenarios=2", "--set",
            "mission.horizon_s=600", "--isolate"]
    public = cli(*base, "--out", str(tmp_path / "public"))
    assert public.exit_code == 0, public.output
    text = " ".join(public.output.split())
    assert "--isolate on the public seed 0" in text
    assert "isolated: the decisions run in a sandboxed process" in text
    assert "decisions isolated (--isolate)" in text
    monkeypatch.setenv("ATA_TEST_BOUNDS_SEED", str(2**40 + 12345))
    secret = cli(*base, "--set", "mission.seed='env:ATA_TEST_BOUNDS_SEED'",
                 "--out", str(tmp_path / "secret"))
    assert secret.exit_code == 0, secret.output
    assert "public seed" not in secret.output


@pytest.mark.skipif(sandbox.unavailable() is not None, reason=str(sandbox.unavailable()))
def test_ata_check_isolate_runs_nothing_of_the_component_outside_the_sandbox(cli, tmp_path):
    marker = tmp_path / "MARKER"
    policy = tmp_path / "nearest_capable.py"
    policy.write_text(f"from pathlib import Path\nPath({str(marker)!r}).write_text('ran')\n"
                      + (EXAMPLE / "nearest_capable.py").read_text())
    apart = cli("check", "--component", "policy", f"{policy}:NearestCapable", "--isolate")
    assert apart.exit_code == 0, apart.output
    assert "keeps the contract (checked in the sandbox)" in " ".join(apart.output.split())
    assert not marker.exists()
    inside = cli("check", "--component", "policy", f"{policy}:NearestCapable")
    assert inside.exit_code == 0, inside.output
    assert marker.read_text() == "ran"              # the check above can fail
