"""The compiled pieces give numpy's bits: the host's scalar formulas against their array twins,
and the decoder's four steps and its commit against their array form
(tests/decoder_reference.py) at every step of real decodes: the shipped weights in settings (a) and (b) (more POIs than the
shortlist), initial allocation and reallocations (an allocation in force, re-briefs)."""

from __future__ import annotations

import copy
from pathlib import Path

import numpy as np
import pytest

import ata
import decoder_reference as ref
from ata.core.kernel import Simulation
from ata.session import load_session
from ata.model import fatigue, greedy_score, scalar, tables
from ata.plugins.ata_hrl import fused
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
    cost = np.where(rng.uniform(0, 1, 500) < 0.5, 0.0, rng.uniform(0, 10, 500))
    assert np.array_equal(greedy_score.option_rate(ev, fin, 1000.0, onboard, cost, secs, 30.0),
                          [scalar.option_rate(a, b, 1000.0, c, d, e, 30.0)
                           for a, b, c, d, e in zip(ev, fin, onboard, cost, secs)])
    eta, lam, f_f, f_w, f_d = (rng.uniform(0, 1, 500) for _ in range(5))
    assert np.array_equal(tables.human_success(eta, lam, f_f, f_w, f_d),
                          [scalar.human_success(*x) for x in zip(eta, lam, f_f, f_w, f_d)])
    assert np.array_equal(greedy_score.human_gain(eta, lam, f_f, f_d, pts),
                          [scalar.human_gain(*x) for x in zip(eta, lam, f_f, f_d, pts)])
    hours = np.concatenate([rng.uniform(0, 4, 497), [1.0, 0.0, 10.0]])
    onset, slope = rng.uniform(0.5, 1.5, 500), rng.uniform(0.1, 0.5, 500)
    assert np.array_equal(fatigue.individual(hours, onset, slope, 0.4),
                          [scalar.individual(*x, 0.4) for x in zip(hours, onset, slope)])


def test_the_load_formulas_give_humanload_bits():
    # the grid's read (cum_at, utilisation: ata.model.grid's functions, compiled) and a booking
    # (book) against HumanLoad's arrays, which run the same functions with numpy
    from ata.model import grid
    from ata.model.load import BIN_S, HumanLoad
    rng = np.random.default_rng(1)
    E, H, window = 3, 4, 300.0
    load = HumanLoad.__new__(HumanLoad)
    load.edges = np.arange(0.0, 1500.0 + window + BIN_S, BIN_S)
    load.window_s = window
    load.cum = np.cumsum(rng.uniform(0, BIN_S, (E, H, load.edges.size)), -1)
    load.booked, load.free = rng.uniform(0, 900, (E, H)), rng.uniform(0, 900, (E, H))
    load._fatigue = load._fatigue_greedy = None
    t = np.concatenate([rng.uniform(-50, 2000, (E, 30, H)),
                        np.full((E, 1, H), load.edges[-1]), np.zeros((E, 1, H))], 1)
    K, flat = load.edges.size, load.cum.reshape(-1)
    base = load._base(None)
    scalar_cum = [[[scalar.cum_at(flat, (e * H + h) * K, load.edges[-1], K, BIN_S, t[e, i, h])
                    for h in range(H)] for i in range(t.shape[1])] for e in range(E)]
    assert np.array_equal(grid.cum_at(flat, base, load.edges[-1], K, BIN_S, t), scalar_cum)
    scalar_u = [[[scalar.utilisation(flat, (e * H + h) * K, load.edges[-1], K, BIN_S, window,
                                     t[e, i, h]) for h in range(H)]
                 for i in range(t.shape[1])] for e in range(E)]
    assert np.array_equal(load.utilisation_at(t), scalar_u)
    twin = {k: getattr(load, k).copy() for k in ("cum", "booked", "free")}
    before = load.cum.copy()
    e, h = np.array([0, 2, 1]), np.array([3, 0, 3])
    a = rng.uniform(0, 1000, 3)
    b = a + rng.uniform(0, 300, 3)
    load.book(e, h, a, b)
    for i in range(3):
        scalar.book(twin["cum"], twin["booked"], twin["free"], load.edges, e[i], h[i], a[i],
                    b[i])
    for k, v in twin.items():
        assert np.array_equal(getattr(load, k), v), k
    assert (twin["cum"] > before).any() and (twin["cum"] >= before).all()    # it booked


def _checked(monkeypatch, seen: dict) -> None:
    """Every step of every decode computed both ways, and the two compared (decoded step by
    step: the compiled whole decode of the mode is held to this one in test_ata_hrl_fused)."""
    monkeypatch.setattr(fused, "fits", lambda dec: False)
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

    compiled_commit = Decoder.commit

    def commit_both(dec, *args):
        twin = _clone(dec)
        ref.commit(twin, *args)
        compiled_commit(dec, *args)
        for name in _STATE:
            assert np.array_equal(getattr(dec, name), getattr(twin, name)), ("commit", name)
        for name in _LOAD:
            assert np.array_equal(getattr(dec.load, name), getattr(twin.load, name)), \
                ("commit", name)
        assert dec.human_free is dec.load.free
        seen["commit"] = seen.get("commit", 0) + 1
        if dec.previous is not None and dec.touched.any():
            seen["rebriefs"] = seen.get("rebriefs", 0) + 1

    monkeypatch.setattr(Decoder, "commit", commit_both)


_STATE = ("robot_free", "robot_xy", "n_assigned", "robot", "nav", "cls", "left", "touched")
_LOAD = ("cum", "booked", "free")


def _clone(dec: Decoder) -> Decoder:
    """A copy of `dec` whose commit changes nothing of `dec`'s."""
    twin = copy.copy(dec)
    for name in _STATE:
        setattr(twin, name, getattr(dec, name).copy())
    twin.load = copy.copy(dec.load)
    for name in _LOAD:
        setattr(twin.load, name, getattr(dec.load, name).copy())
    twin.human_free = twin.load.free
    return twin


@pytest.mark.parametrize("overrides, n", [
    (["mission.uncertainty='high'"], 3),
    (["mission.setting='b'", "mission.uncertainty='high'"], 1)])
def test_the_compiled_steps_give_the_array_steps_bits(monkeypatch, overrides, n):
    s = load_session(str(Path(ata.__file__).parent / "missions" / "default.toml"), overrides)
    seen: dict = {}
    _checked(monkeypatch, seen)
    rec = Simulation(s.mission, s.registry, list(range(n))).run()
    assert rec.allocations.size
    # every step and commit, also reallocating (with re-briefs)
    assert len(seen) == 7 and min(seen.values()) > 50, seen


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
