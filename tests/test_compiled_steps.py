"""The compiled pieces give numpy's bits: the host's scalar formulas against their array twins,
and the decoder's four steps against their array form (tests/decoder_reference.py) at every
step of real decodes: the shipped weights in settings (a) and (b) (more POIs than the
shortlist), initial allocation and reallocations (an allocation in force, re-briefs)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import ata
import decoder_reference as ref
from ata.core.kernel import Simulation
from ata.experiment.runner import load_session
from ata.model import greedy_score, scalar, tables
from ata.plugins.ata_hrl.decoder import Decoder


def test_the_scalar_formulas_give_their_array_twins_bits():
    rng = np.random.default_rng(0)
    u = np.concatenate([rng.uniform(-0.1, 1.1, 2000), [0.45, 0.65, 0.0, 1.0]])
    assert np.array_equal(tables.workload(u), [scalar.workload(x) for x in u])
    pts, p = rng.uniform(5, 35, 500), rng.uniform(0, 1, 500)
    assert np.array_equal(tables.expected_points(pts, p),
                          [scalar.expected_points(a, b) for a, b in zip(pts, p)])
    ev, tb, delay = rng.normal(0, 20, 500), rng.uniform(20, 250, 500), rng.exponential(60, 500)
    assert np.array_equal(greedy_score.human_net(ev, tb, delay, 0.03),
                          [scalar.human_net(a, b, c, 0.03) for a, b, c in zip(ev, tb, delay)])
    fin = rng.uniform(0, 2000, 500)
    onboard = rng.normal(0, 20, 500)
    assert np.array_equal(greedy_score.option_value(ev, fin, 1000.0, onboard),
                          [scalar.option_value(a, b, 1000.0, c)
                           for a, b, c in zip(ev, fin, onboard)])
    secs = np.concatenate([rng.uniform(0, 500, 499), [np.inf]])
    assert np.array_equal(greedy_score.rate(ev, secs, 30.0),
                          [scalar.rate(a, b, 30.0) for a, b in zip(ev, secs)])


def _checked(monkeypatch, seen: dict) -> None:
    """Every step of every decode computed both ways, and the two compared."""
    for name in ("poi_inputs", "robot_inputs", "nav_inputs", "cls_inputs"):
        compiled, reference = getattr(Decoder, name), getattr(ref, name)

        def both(dec, *args, _c=compiled, _r=reference, _n=name):
            new = _c(dec, *args)
            r_ff = getattr(dec, "r_ff", None)
            old = _r(dec, *args)
            for field in ("features", "mask", "prior", "active"):
                a, b = getattr(new, field), getattr(old, field)
                assert a.dtype == b.dtype and np.array_equal(
                    a, b, equal_nan=a.dtype.kind == "f"), (_n, field)
            if _n == "poi_inputs":
                assert np.array_equal(r_ff, dec.r_ff)
            seen[_n] = seen.get(_n, 0) + 1
            if dec.previous is not None:
                seen["reallocating"] = seen.get("reallocating", 0) + 1
            return new

        monkeypatch.setattr(Decoder, name, both)


@pytest.mark.parametrize("overrides, n", [
    (["mission.uncertainty='high'"], 3),
    (["mission.setting='b'", "mission.uncertainty='high'"], 1)])
def test_the_compiled_steps_give_the_array_steps_bits(monkeypatch, overrides, n):
    s = load_session(str(Path(ata.__file__).parent / "missions" / "default.toml"), overrides)
    seen: dict = {}
    _checked(monkeypatch, seen)
    rec = Simulation(s.mission, s.registry, list(range(n))).run()
    assert rec.allocations.size
    assert len(seen) == 5 and min(seen.values()) > 50, seen    # every step, also reallocating


def test_the_compiled_projection_gives_the_array_projections_bits(monkeypatch):
    # every projection of real runs, computed both ways: ATA-HRL's (the population line) and
    # greedy's keep-or-repair reallocation with the filter's belief (a posterior over a grid
    # of fatigue curves), both settings
    import plan_reference
    from ata.model import plan as plan_module
    compiled = plan_module.project
    calls = {"curves": set(), "n": 0}

    def both(start, alloc, tasks=None, **kw):
        new, old = compiled(start, alloc, tasks, **kw), plan_reference.project(start, alloc,
                                                                               tasks, **kw)
        for field in ("value", "human_busy_s", "expected", "arrival", "finish", "robot_free",
                      "robot_xy", "human_free"):
            assert np.array_equal(getattr(new, field), getattr(old, field)), field
        calls["n"] += 1
        calls["curves"].add(start.belief.curves)
        return new

    for module in ("ata.model.plan", "ata.model.retask", "ata.model.greedy_planner",
                   "ata.plugins.ata_hrl.components", "ata.plugins.ata_hrl.status"):
        mod = __import__(module, fromlist=["project"])
        monkeypatch.setattr(mod, "project", both)
    root = Path(ata.__file__).parent / "missions"
    for mission, overrides, n in ((root / "default.toml", ["mission.uncertainty='high'"], 2),
                                  (root / "greedy.toml", ["mission.setting='b'",
                                                            "components.reconstructors=['filter']"],
                                   2)):
        s = load_session(str(mission), overrides)
        Simulation(s.mission, s.registry, list(range(n))).run()
    assert calls["n"] > 20 and 1 in calls["curves"] and max(calls["curves"]) > 1, calls
