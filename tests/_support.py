"""Helpers shared by the tests: kernel traces, small MILP instances."""

import numpy as np
import pytest

from ata.plugins import tables
from ata.plugins.policies import milp as M


def flat(text: str) -> str:
    """Whitespace collapsed, so that a message wrapped by rich still matches."""
    return " ".join(text.split())


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


def tiny_data(seed: int, P: int = 4, H: int = 2, R: int = 2) -> M.ScenarioData:
    gen = np.random.default_rng(seed)
    theta_s = gen.uniform(0, np.pi / 4, H)
    theta_s[0] = 0.7                       # one highly skilled human, so navigators are options
    return M.ScenarioData(kind=gen.integers(0, 2, P), diff=gen.integers(0, 3, P),
                          xy=gen.uniform(0, 2000, (P, 2)),
                          eta=np.sin(gen.uniform(0, np.pi / 4, H)), lam=np.sin(theta_s),
                          skill=tables.skill_band(theta_s), hours=gen.uniform(0, 1.5, H),
                          rtype=np.array([0, 1] * (R // 2)), speed=np.array([8.0, 3.0] * (R // 2)),
                          area_m=2000.0, horizon_s=600.0, event_p=0.2,
                          fatigue_sigma=np.sqrt(0.1))


class Killed(Exception):
    """Raised from a trainer's log hook to kill a run mid-phase."""


def whole_and_killed(session, tmp_path, phase: str, step: str):
    """Train `session` to the end in tmp_path/whole; train it again in tmp_path/broken, killed
    when the log reaches (phase, step); return the whole trainer and one resumed from the
    broken run's folder (not yet run on)."""
    from ata.core.runner import load_session
    from ata.learn import train as T

    whole = T.Trainer(session, tmp_path / "whole")
    whole.run()

    def kill(row):
        if row["phase"] == phase and str(row["step"]) == step:
            raise Killed

    broken = T.Trainer(session, tmp_path / "broken", on_row=kill)
    with pytest.raises(Killed):
        broken.run()
    resumed = T.Trainer(load_session(str(tmp_path / "broken" / "mission.resolved.toml")),
                        tmp_path / "broken", resume=True)
    return whole, resumed
