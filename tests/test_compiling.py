"""The host's compiled loops are compiled again when a function they call changes in another
file (numba's own cache checks the function's file alone): `ata.model.compiling.jit`."""

from __future__ import annotations

import subprocess
import sys
import textwrap


def test_a_cached_loop_is_compiled_again_when_what_it_calls_changes(tmp_path):
    pkg = tmp_path / "loops"
    pkg.mkdir()
    (pkg / "__init__.py").write_text("")
    formula = textwrap.dedent("""\
        from ata.model.compiling import jit

        @jit
        def points(x):
            return x * {factor}
        """)
    (pkg / "formula.py").write_text(formula.format(factor=2.0))
    (pkg / "loop.py").write_text(textwrap.dedent("""\
        from ata.model.compiling import jit
        from loops.formula import points

        @jit
        def total(n):
            s = 0.0
            for i in range(n):
                s += points(float(i))
            return s
        """))

    def run() -> str:
        done = subprocess.run([sys.executable, "-c", "from loops.loop import total; "
                               "print(total(4))"], cwd=tmp_path, capture_output=True,
                              text=True, timeout=300)
        assert done.returncode == 0, done.stderr
        return done.stdout.strip()

    assert run() == "12.0"
    assert list((pkg / "__pycache__").glob("loop.total-*.nbi"))      # cached
    assert run() == "12.0"                                              # from the cache
    (pkg / "formula.py").write_text(formula.format(factor=3.0))
    assert run() == "18.0"                  # numba's own cache would still give 12.0
