"""`ata check --component KIND TARGET --isolate`: a component's contract checks
(`ata.testing.check_reference`) run in the sandbox, so that the code of an untrusted method runs
nowhere else: not in the host, not with the user's rights over the checkout.

The sandboxed process is shown what an isolated run shows (the Python installation and ata,
read-only) and the component's own file or package; it answers one line of JSON on stdout.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

from ata.core import references
from ata.core.errors import MissionError
from ata.isolation.remote import _locate
from ata.runtime import memory, sandbox

CHILD = """
import json, sys
from ata.core.errors import MissionError
from ata.testing import check_reference
args = json.loads(sys.argv[1])
sys.path[:0] = args.pop("paths")
try:
    name = check_reference(**args)
    out = {"ok": name}
except AssertionError as exc:
    out = {"failed": str(exc)}
except MissionError as exc:
    out = {"error": str(exc)}
sys.stdout.write("\\n" + json.dumps(out) + "\\n")
"""
TIMEOUT_S = 900.0
"""The longest a check may take in the sandbox (it runs a small mission a few times)."""


def check_isolated(kind: str, target: str, overrides: list[str] = (),
                   plugins: list[str] = (), seed: int | None = None,
                   timeout_s: float = TIMEOUT_S) -> str:
    """`check_reference` in a sandboxed process: the component's name; AssertionError on a
    breach of the contract, MissionError on bad input or where no sandbox can run."""
    reason = sandbox.unavailable()
    if reason is not None:
        raise MissionError("--isolate", None, reason)
    binds: list[str] = []
    paths: list[str] = []
    if references.is_reference(target):
        target = references.absolute(target, Path.cwd())
        ref = _locate(target, "--component")
        binds, paths = list(ref.binds), list(ref.paths)
    args = {"kind": kind, "target": target, "overrides": list(overrides),
            "plugins": list(plugins), "seed": seed, "paths": paths}
    argv = [sys.executable, "-s", "-P", "-c", CHILD, json.dumps(args)]
    with tempfile.TemporaryFile() as err:
        try:
            done = subprocess.run(sandbox.command(argv, binds=binds, cwd=os.getcwd()),
                                  env=sandbox.host_env(), stdin=subprocess.DEVNULL,
                                  stdout=subprocess.PIPE, stderr=err, timeout=timeout_s,
                                  preexec_fn=sandbox.limits(memory.memory_limit()))
        except subprocess.TimeoutExpired:
            raise AssertionError(f"the check did not end within {timeout_s:g} s in the "
                                 "sandbox") from None
        err.seek(0)
        tail = err.read()[-4000:].decode("utf-8", "replace").strip()
    lines = done.stdout[-(1 << 20):].decode("utf-8", "replace").strip().splitlines()
    try:
        answer = json.loads(lines[-1]) if lines else None
    except ValueError:
        answer = None
    if not isinstance(answer, dict):
        raise AssertionError(f"the check ended in the sandbox without an answer (exit "
                             f"{done.returncode}): {tail[-2000:] or 'no message'}")
    if "error" in answer:
        raise MissionError("--component", None, str(answer["error"])[:4000])
    if "failed" in answer:
        raise AssertionError(str(answer["failed"])[:20000])
    return str(answer.get("ok"))[:200]
