"""The sandbox holds whoever runs the host, root included (as CI runs): the method has no
capability, cannot remount what it is shown or write into ata's package or site-packages, runs
as an unprivileged user, and is held to its memory and output limits."""

import os
import subprocess
import sys
import tempfile
import textwrap
import uuid

import pytest

from ata.runtime import sandbox

pytestmark = pytest.mark.skipif(sandbox.unavailable() is not None,
                                reason=str(sandbox.unavailable()))


def inside(script: str, memory: int | None = None) -> subprocess.CompletedProcess:
    argv = sandbox.command([sys.executable, "-S", "-c", textwrap.dedent(script)])
    return subprocess.run(argv, env=sandbox.host_env(), capture_output=True, text=True,
                          timeout=120, preexec_fn=sandbox.limits(memory))


def test_the_method_has_no_capability_and_is_no_root_whoever_runs_the_host():
    done = inside("""
        import os
        caps = dict(line.split(":\\t") for line in open("/proc/self/status").read().splitlines()
                    if line.startswith("Cap"))
        print(os.getuid(), os.getgid(), caps["CapEff"].strip(), caps["CapPrm"].strip(),
              caps["CapBnd"].strip())
    """)
    assert done.returncode == 0, done.stderr
    uid, gid, eff, prm, bnd = done.stdout.split()
    assert (int(uid), int(gid)) == (sandbox.SANDBOX_UID, sandbox.SANDBOX_UID)
    assert int(eff, 16) == int(prm, 16) == int(bnd, 16) == 0
    if os.geteuid() == 0:      # what the confinement is for: root's capabilities stay outside
        host = open("/proc/self/status").read()
        assert "CapEff:\t0000000000000000" not in host


def test_what_the_method_is_shown_cannot_be_remounted_or_written():
    targets = [sandbox.ata_dir(), *sandbox.python_dirs()]
    done = inside(f"""
        import ctypes, errno, os
        libc = ctypes.CDLL(None, use_errno=True)
        MS_REMOUNT, MS_BIND = 32, 4096
        for path in {targets!r}:
            try:
                fd = os.open(os.path.join(path, "planted.pth"), os.O_CREAT | os.O_WRONLY)
                os.close(fd)
                print("WROTE", path)
            except OSError as exc:
                print("write refused", errno.errorcode[exc.errno])
            rc = libc.mount(None, path.encode(), None, MS_REMOUNT | MS_BIND, None)
            print("REMOUNTED" if rc == 0 else "remount refused",
                  errno.errorcode[ctypes.get_errno()] if rc else path)
        rc = libc.unshare(0x10000000)          # CLONE_NEWUSER: a namespace of its own
        print("UNSHARED" if rc == 0 else "unshare refused")
    """)
    assert done.returncode == 0, done.stderr
    assert "WROTE" not in done.stdout and "REMOUNTED" not in done.stdout, done.stdout
    assert "UNSHARED" not in done.stdout, done.stdout
    assert done.stdout.count("write refused") == len(targets)
    assert done.stdout.count("remount refused") == len(targets)
    for path in targets:
        assert not os.path.exists(os.path.join(path, "planted.pth"))


def test_the_sandbox_writes_only_its_own_tmp():
    name = f"/tmp/ata-sandbox-{uuid.uuid4().hex}"
    done = inside(f"""
        open({name!r}, "w").write("x")
        print(open({name!r}).read())
    """)
    assert done.returncode == 0 and done.stdout.strip() == "x", done.stderr
    assert not os.path.exists(name)          # its /tmp was its own, and ended with it


def test_the_memory_and_output_limits_hold_inside():
    done = inside("""
        try:
            block = bytearray(3 << 30)
            print("ALLOCATED")
        except MemoryError:
            print("memory refused")
    """, memory=sandbox.MIN_MEMORY)
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "memory refused"
    # the host keeps a process's stderr in a file, as the decision process's is kept
    script = f"import sys; sys.stderr.write('x' * {sandbox.OUTPUT_LIMIT + (1 << 20)})"
    with tempfile.TemporaryFile() as err:
        code = subprocess.run(sandbox.command([sys.executable, "-S", "-c", script]),
                              env=sandbox.host_env(), stdout=subprocess.DEVNULL, stderr=err,
                              timeout=120, preexec_fn=sandbox.limits(None)).returncode
        size = err.seek(0, os.SEEK_END)
    assert code != 0
    assert size <= sandbox.OUTPUT_LIMIT
