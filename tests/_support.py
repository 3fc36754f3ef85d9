"""Helpers shared by the kernel and dynamics tests."""

import pytest


def assert_trace(actual, expected):
    """Events equal one by one; floats to 1e-9 s."""
    assert len(actual) == len(expected), f"trace {actual}\n  expected {expected}"
    for a, e in zip(actual, expected):
        assert len(a) == len(e), f"{a} != {e}"
        for x, y in zip(a, e):
            if isinstance(y, float):
                assert x == pytest.approx(y, rel=1e-12, abs=1e-9), f"{a} != {e}"
            else:
                assert x == y and type(x) is type(y), f"{a} != {e}"
