"""Fixtures shared by the test modules."""

import pytest
from typer.testing import CliRunner

from ata.cli import app


@pytest.fixture
def cli():
    """`cli("run", path, ...)`: the ata command in-process. A wide terminal, so that rich does
    not wrap or truncate the lines asserted on."""
    runner = CliRunner(env={"COLUMNS": "200"})
    return lambda *args: runner.invoke(app, [str(a) for a in args])


@pytest.fixture
def sigint_at_python_default():
    """SIGINT at Python's own handler for the test, as an interactive run finds it: a test run
    started in the background by a non-interactive shell inherits SIGINT ignored, where no
    Ctrl-C reaches the program at all. The handler found is put back after."""
    import signal
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    yield
    signal.signal(signal.SIGINT, previous)
