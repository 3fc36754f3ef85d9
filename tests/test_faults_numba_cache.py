"""Faults of numba's compile cache: a cache that cannot be used never stops a command. An
emptied or truncated cache file is compiled anew with one warning line (it ended every run in
`Aborted.` or an `UnpicklingError`); where no cache folder is writable (a read-only install,
no writable HOME) the cache moves to the user's temporary folder with one warning line (it
failed at import: "cannot cache function ...: no locator available")."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from ata.runtime.sandbox import bwrap_path

MODULE = """\
from ata.model.compiling import jit


@jit
def twice(x):
    return 2 * x


print(twice(21))
"""


def _run(folder: Path, *prefix: str, env: dict[str, str] | None = None):
    return subprocess.run([*prefix, sys.executable, "-c", "import twice_mod"],
                          cwd=folder, capture_output=True, text=True, timeout=300,
                          env={**os.environ, "PYTHONPATH": str(folder), **(env or {})})


def _cache_files(folder: Path) -> list[Path]:
    return sorted(p for p in (folder / "__pycache__").glob("twice_mod.*")
                  if p.suffix in (".nbi", ".nbc"))


@pytest.mark.parametrize("damage", ["emptied", "truncated"])
def test_a_damaged_cache_entry_is_compiled_anew_with_one_warning(tmp_path, damage):
    (tmp_path / "twice_mod.py").write_text(MODULE)
    first = _run(tmp_path)
    assert first.returncode == 0, first.stderr
    files = _cache_files(tmp_path)
    assert {p.suffix for p in files} == {".nbi", ".nbc"}
    for p in files:
        p.write_bytes(b"" if damage == "emptied" else p.read_bytes()[:40])
    second = _run(tmp_path)
    assert second.returncode == 0, second.stderr
    assert second.stdout.strip() == "42"
    lines = [line for line in second.stderr.splitlines() if line.strip()]
    assert len(lines) == 1 and lines[0].startswith("warning: numba's cache of twice"), lines
    assert "compiled anew" in lines[0]
    third = _run(tmp_path)                       # the entry was written again, whole
    assert third.returncode == 0 and third.stdout.strip() == "42"
    assert third.stderr.strip() == ""


def _bwrap_works(bwrap: str) -> bool:
    probe = subprocess.run([bwrap, "--ro-bind", "/", "/", "--dev", "/dev", "true"],
                           capture_output=True)
    return probe.returncode == 0


@pytest.mark.skipif(bwrap_path() is None or not _bwrap_works(bwrap_path()),
                    reason="needs bubblewrap (the sandbox extra) able to make mounts here")
def test_no_writable_cache_folder_moves_the_cache_to_the_temporary_folder(tmp_path):
    """Everything read-only (root included: a read-only mount), HOME unwritable, /tmp empty
    and writable: the module still runs, one warning names the folder the cache went to."""
    (tmp_path / "twice_mod.py").write_text(MODULE)
    box = [bwrap_path(), "--ro-bind", "/", "/", "--dev", "/dev", "--proc", "/proc",
           "--tmpfs", "/tmp", "--ro-bind", str(tmp_path), "/tmp/mod", "--chdir", "/tmp/mod",
           "--setenv", "HOME", "/nonexistent", "--setenv", "PYTHONPATH", "/tmp/mod",
           "--unsetenv", "NUMBA_CACHE_DIR"]
    done = subprocess.run([*box, sys.executable, "-c",
                           "import twice_mod, os; print(sorted(os.listdir('/tmp')))"],
                          capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    out = done.stdout.split()
    assert out[0] == "42"
    assert f"'ata-numba-{os.getuid()}'" in done.stdout
    lines = [line for line in done.stderr.splitlines() if line.strip()]
    assert len(lines) == 1 and "no writable cache folder" in lines[0], lines
    assert "NUMBA_CACHE_DIR" in lines[0]
