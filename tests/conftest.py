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
