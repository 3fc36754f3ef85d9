"""Bytecode planted beside ata's sources (by a method once run in-process, say) is never run by
an isolated run: `ata.runtime.bytecode.guard` refuses a cache that is not its source's, and
compiles ata's modules from their sources from then on."""

import importlib.util
import subprocess
import sys
import textwrap

import ata

POISON = "import os\nos.environ['ATA_POISONED'] = 'ran'\n"


def run(script: str, prefix) -> subprocess.CompletedProcess:
    # the caches go to `prefix` (sys.pycache_prefix), not beside the checkout's sources
    return subprocess.run([sys.executable, "-c", f"import sys; sys.pycache_prefix = "
                           f"{str(prefix)!r}\n" + textwrap.dedent(script)],
                          capture_output=True, text=True, timeout=300)


def plant(prefix, module: str) -> None:
    """A valid-looking cache of `module` (its source's time and size) that also runs POISON."""
    script = f"""
        import importlib.util, importlib._bootstrap_external as ext, os
        spec = importlib.util.find_spec({module!r})
        source = spec.origin
        st = os.stat(source)
        text = open(source).read() + "\\n" + {POISON!r}
        code = compile(text, source, "exec")
        data = ext._code_to_timestamp_pyc(code, st.st_mtime, st.st_size)
        path = importlib.util.cache_from_source(source)
        os.makedirs(os.path.dirname(path), exist_ok=True)
        open(path, "wb").write(data)
    """
    done = run(script, prefix)
    assert done.returncode == 0, done.stderr


def test_a_planted_cache_runs_in_a_plain_process_and_is_refused_by_the_guard(tmp_path):
    plant(tmp_path, "ata.plugins.policies.keep")
    plain = run("""
        import os, ata.plugins.policies.keep
        print(os.environ.get("ATA_POISONED"))
    """, tmp_path)
    assert plain.stdout.strip() == "ran", plain.stderr          # the route is real
    guarded = run("""
        import os
        from ata.core.errors import MissionError
        from ata.runtime import bytecode
        try:
            bytecode.guard()
            print("NOT REFUSED")
        except MissionError as exc:
            print("refused:", exc)
        import ata.plugins.policies.keep
        print(os.environ.get("ATA_POISONED"))
    """, tmp_path)
    assert guarded.returncode == 0, guarded.stderr
    lines = guarded.stdout.strip().splitlines()
    assert lines[0].startswith("refused:") and "keep" in lines[0], lines
    assert lines[-1] == "None", lines          # compiled from its source, not from the cache


def test_the_guard_passes_caches_that_are_their_sources(tmp_path):
    done = run("""
        import ata.plugins.policies.keep, ata.core.kernel
        from ata.runtime import bytecode
        bytecode.guard()
        print("ok")
    """, tmp_path)
    assert done.returncode == 0 and done.stdout.strip() == "ok", done.stderr
    assert importlib.util.cache_from_source(ata.__file__)
