"""The compiled whole decode of the mode (ata.plugins.ata_hrl.fused) makes the step-by-step
decode's allocations to the bit: every decode of real runs (initial allocation and
reallocations, the per-POI reallocation and the full re-plan, re-briefs) computed both ways and
compared, with the learned part on and off, in settings (a) and (b) (more POIs than the
shortlist)."""

from __future__ import annotations

import copy
from pathlib import Path

import numpy as np
import pytest

import ata
from ata.core.kernel import Simulation
from ata.plugins.ata_hrl import decode as D
from ata.plugins.ata_hrl import fused
from ata.session import load_session


def _state(dec) -> dict:
    """What a decode leaves in its decoder beside the allocation (the step-by-step decode
    writes these back from the episodes it goes on with: `Decoder.put`)."""
    return {"left": dec.left, "robot_free": dec.robot_free}


@pytest.mark.parametrize("overrides, n", [
    (["mission.uncertainty='high'"], 4),
    (["mission.uncertainty='high'", "attention.learned=false", "ctr.learned=false"], 2),
    (["mission.setting='b'"], 1)])
def test_the_compiled_decode_gives_the_step_by_step_decode_bits(monkeypatch, overrides, n):
    real = D.decode
    seen = {"fused": 0, "reallocating": 0}

    def both(dec, net, emb, choose, *, residual=True, trace=None):
        if not (trace is None and choose is D.argmax_chooser and fused.fits(dec)):
            return real(dec, net, emb, choose, residual=residual, trace=trace)
        twin = copy.deepcopy(dec)
        with monkeypatch.context() as m:
            m.setattr(fused, "fits", lambda d: False)
            stepwise = real(twin, net, emb, choose, residual=residual)
        compiled = real(dec, net, emb, choose, residual=residual)
        assert np.array_equal(compiled.stack(), stepwise.stack())
        for name, a in _state(dec).items():
            assert np.array_equal(a, _state(twin)[name]), name
        seen["fused"] += 1
        seen["reallocating"] += dec.previous is not None
        return compiled

    import ata.plugins.ata_hrl.components as C
    monkeypatch.setattr(C.D, "decode", both)
    s = load_session(str(Path(ata.__file__).parent / "missions" / "default.toml"), overrides)
    rec = Simulation(s.mission, s.registry, list(range(n))).run()
    assert rec.allocations.size
    assert seen["fused"] > 10 and seen["reallocating"] > 5, seen


def _replay_numpy(dec, kept, alloc=None):
    """`Decoder.replay` in its array form: every episode's round at once, with the decoder's
    commit."""
    prev = alloc if alloc is not None else dec.previous
    left = kept & dec.left
    owner = prev.robot
    left &= np.isfinite(np.take_along_axis(dec.robot_free, owner, axis=1))
    for _ in range(dec.P):
        has = np.zeros((dec.E, dec.R), dtype=bool)
        lb, lp = np.nonzero(left)
        if lb.size == 0:
            break
        has[lb, owner[lb, lp]] = True
        rs = np.where(has, dec.robot_free, np.inf).argmin(axis=1)
        act = has.any(axis=1)
        gx = dec.tx - dec.robot_xy[dec.e, rs, 0][:, None]
        gy = dec.ty - dec.robot_xy[dec.e, rs, 1][:, None]
        dist = np.where(left & (owner == rs[:, None]), gx * gx + gy * gy, np.inf)
        p = dist.argmin(axis=1)
        dec.commit(act, p, rs, prev.navigator[dec.e, p], prev.classifier[dec.e, p])
        left[dec.e[act], p[act]] = False
    dec.left &= ~kept


def test_the_compiled_replay_gives_the_array_replays_bits(monkeypatch):
    from ata.plugins.ata_hrl.decoder import Decoder
    real, seen = Decoder.replay, []

    def both(dec, kept, alloc=None):
        twin = copy.deepcopy(dec)
        _replay_numpy(twin, kept, alloc)
        real(dec, kept, alloc)
        for name in ("left", "robot_free", "robot_xy", "n_assigned", "robot", "nav", "cls",
                     "touched"):
            assert np.array_equal(getattr(dec, name), getattr(twin, name)), name
        for name in ("cum", "booked", "free"):
            assert np.array_equal(getattr(dec.load, name), getattr(twin.load, name)), name
        np.testing.assert_array_equal(dec.load.fatigue_at(), twin.load.fatigue_at())
        seen.append(int((kept & ~dec.left).sum()))

    monkeypatch.setattr(Decoder, "replay", both)
    s = load_session(str(Path(ata.__file__).parent / "missions" / "default.toml"),
                     ["mission.uncertainty='high'"])
    Simulation(s.mission, s.registry, list(range(4))).run()
    assert len(seen) > 5 and sum(seen) > 20, seen
