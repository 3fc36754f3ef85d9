"""ATA-HRL's decisions without torch: the numpy forward passes (ata.plugins.ata_hrl.infer)
against the torch modules they stand for, the architecture's shapes against the modules' own,
the torch-free reader of checkpoints (ata.training.tensorfile) against torch.load, and a run of
the default mission that never imports torch."""

from __future__ import annotations

import pickle
import subprocess
import sys
import zipfile

import numpy as np
import pytest
import torch

from ata.plugins.ata_hrl.arch import COND_FEATURES, I_DIMS, KINDS, S_DIMS, NetConfig, \
    expected_shapes
from ata.plugins.ata_hrl.checkpoint import infer_from_checkpoint, load_net
from ata.plugins.ata_hrl.infer import InferenceNet
from ata.plugins.ata_hrl.inputs import KEEP_FEATURES
from ata.plugins.ata_hrl.network import ATAHRLNet, encode_once, to_tensors
from ata.plugins.ata_hrl.status import STATUS_FEATURES
from ata.training import CheckpointError, read_checkpoint, tensorfile
from ata.training.checkpoints import _CACHE
from ata.runtime.inputs import WEIGHTS

SMALL = NetConfig(d_model=16, heads=2, layers=1, hidden=24, z_dim=3, recon_hidden=8,
                  status_hidden=12)


@pytest.mark.parametrize("cfg", [NetConfig(), SMALL], ids=["default", "small"])
def test_the_architectures_shapes_are_the_modules(cfg):
    want = {k: tuple(v.shape) for k, v in ATAHRLNet(cfg).state_dict().items()}
    assert expected_shapes(cfg) == want


def _drawn() -> ATAHRLNet:
    """A network of the small architecture with every weight drawn (the zero-initialised
    output layers included) and pi_C's fitted rule switched on."""
    torch.manual_seed(3)
    net = ATAHRLNet(SMALL)
    with torch.no_grad():
        for p in net.parameters():
            p.normal_(0.0, 0.4)
        net.cond.rule.on.fill_(1.0)
    return net


def _close(a: torch.Tensor, b: np.ndarray) -> None:
    assert b.dtype == np.float32 and b.shape == tuple(a.shape)
    np.testing.assert_allclose(b, a.numpy(), rtol=1e-5, atol=2e-5)


@pytest.mark.parametrize("which", ["ata_hrl_a", "ata_hrl_b_ft", "drawn"])
def test_every_forward_pass_is_the_torch_modules(which):
    net = _drawn() if which == "drawn" else load_net(f"builtin:{which}")
    twin = InferenceNet.of(net)
    rng = np.random.default_rng(len(which))
    E, sizes = 5, {"humans": 4, "robots": 6, "tasks": 13}
    d = net.cfg.d_model

    def draw(*shape):
        return rng.normal(0, 1, shape).astype(np.float32)

    feats = {g: draw(E, n, I_DIMS[g]) for g, n in sizes.items()}
    feats = {g: np.concatenate([v[:2], v[1:2], v[2:]]) for g, v in feats.items()}  # a repeat
    raw = {g: draw(E + 1, n, S_DIMS[g]) for g, n in sizes.items()}
    seen = {g: draw(E + 1, n, S_DIMS[g]) for g, n in sizes.items()}
    with torch.no_grad():
        for part in ("ita", "tr"):
            want = encode_once(getattr(net, part).encoder, feats)
            got = getattr(twin, part).encode(feats)
            for g in want:
                _close(want[g], got[g])
        emb_t = net.tr.embed(want, to_tensors(raw), to_tensors(seen))
        emb = twin.tr.embed({g: v.numpy() for g, v in want.items()}, raw, seen)
        for g in emb_t:
            _close(emb_t[g], emb[g])
        for kind in KINDS:
            _close(net.tr.candidates(kind, emb_t), twin.tr.candidates(kind, emb))
        P = sizes["tasks"]
        kf, prior = draw(E + 1, P, KEEP_FEATURES), draw(E + 1, P, 3)
        mask = rng.uniform(size=(E + 1, P, 3)) < 0.7
        for residual in (True, False):
            _close(net.tr.keep(torch.from_numpy(kf), emb_t["tasks"], torch.from_numpy(prior),
                               torch.from_numpy(mask), residual),
                   twin.tr.keep(kf, emb["tasks"], prior, mask, residual))
        pooled, cf = draw(E, d), draw(E, COND_FEATURES)
        cprior = np.where(rng.uniform(size=E) < 0.5, 1.0, -1.0).astype(np.float32)
        hidden_t, hidden = torch.zeros(E, d), np.zeros((E, d), np.float32)
        for _ in range(3):                         # the hidden state carried epoch to epoch
            lt, hidden_t = net.cond(torch.from_numpy(pooled), torch.from_numpy(cf),
                                    torch.from_numpy(cprior), hidden_t)
            lg, hidden = twin.cond(pooled, cf, cprior, hidden)
            _close(lt, lg)
            _close(hidden_t, hidden)
        fo, hours, cog = (rng.uniform(size=(E, 4)).astype(np.float32) for _ in range(3))
        _close(net.fatigue(*map(torch.from_numpy, (fo, hours, cog)))[0],
               twin.fatigue(fo, hours, cog))
        for g in ("robots", "tasks"):
            h_t, h = None, None
            for _ in range(3):
                x = rng.uniform(size=(40, S_DIMS[g])).astype(np.float32)
                est_t, h_t = net.latency[g](torch.from_numpy(x)[:, None], h_t)
                est, h = twin.latency(g, x, h)
                _close(est_t[:, 0], est)
                _close(h_t, h)
        assert twin.has_status == (net.cfg.status_hidden > 0)
        if twin.has_status:
            sf = draw(E, P, STATUS_FEATURES)
            _close(net.status(torch.from_numpy(sf)), twin.status(sf))
    if which == "drawn":       # the rule decides event epochs: the two paths differ there
        assert net.cond.rule_on() and (cprior > 0).any() and (cprior < 0).any()


@pytest.mark.parametrize("name", ["ata_hrl_a.pt", "ata_hrl_s3_b_ft.pt", "atrl_tr_a.pt"])
def test_the_torch_free_reader_reads_what_torch_load_reads(name):
    want = torch.load(WEIGHTS / name, map_location="cpu", weights_only=True)
    got = tensorfile.load(WEIGHTS / name)

    def same(a, b, where="") -> None:
        if isinstance(b, torch.Tensor):
            assert isinstance(a, np.ndarray) and a.shape == tuple(b.shape), where
            assert a.dtype == b.numpy().dtype and np.array_equal(a, b.numpy()), where
        elif isinstance(b, dict):
            assert list(a) == list(b), where
            for k in b:
                same(a[k], b[k], f"{where}.{k}")
        elif isinstance(b, (list, tuple)):
            assert len(a) == len(b), where
            for i, (x, y) in enumerate(zip(a, b)):
                same(x, y, f"{where}[{i}]")
        else:
            assert a == b, where
    same(got, want)


def test_the_torch_free_reader_runs_nothing_of_a_foreign_pickle(tmp_path):
    # a zip laid out as torch's, whose pickle calls os.system: refused before any call
    class Evil:
        def __reduce__(self):
            import os
            return (os.system, (f"touch {tmp_path / 'ran'}",))
    path = tmp_path / "evil.pt"
    with zipfile.ZipFile(path, "w") as z:
        z.writestr("evil/data.pkl", pickle.dumps({"kind": "ata_hrl", "x": Evil()}, protocol=2))
        z.writestr("evil/byteorder", "little")
    with pytest.raises(CheckpointError, match="holds objects other than tensors and plain data"):
        read_checkpoint(path, arrays=True)
    assert not (tmp_path / "ran").exists()
    (tmp_path / "bad.pt").write_bytes(b"not a checkpoint")
    with pytest.raises(CheckpointError, match=r"cannot be read as a checkpoint \(BadZipFile"):
        read_checkpoint(tmp_path / "bad.pt", arrays=True)


def test_a_checkpoint_whose_weights_do_not_fit_is_refused_without_torch(tmp_path):
    data = torch.load(WEIGHTS / "ata_hrl_a.pt", map_location="cpu", weights_only=True)
    data["model"]["ita.auto"] = torch.zeros(7)
    torch.save(data, tmp_path / "wrong.pt")
    read = read_checkpoint(tmp_path / "wrong.pt", "ata_hrl", arrays=True)
    with pytest.raises(CheckpointError, match=r"size mismatch: ita.auto \(7,\) for \(32,\)"):
        infer_from_checkpoint(read, tmp_path / "wrong.pt")
    del data["model"]["ita.auto"]
    torch.save(data, tmp_path / "missing.pt")
    read = read_checkpoint(tmp_path / "missing.pt", "ata_hrl", arrays=True)
    with pytest.raises(CheckpointError, match="missing: ita.auto"):
        infer_from_checkpoint(read, tmp_path / "missing.pt")
    _CACHE.clear()


def test_a_run_of_ata_hrl_never_imports_torch():
    code = ("import sys\n"
            "from ata.experiment.runner import run_mission\n"
            "from ata.session import load_session\n"
            "record = run_mission(load_session('ata/missions/default.toml', "
            "['mission.scenarios=2', 'mission.uncertainty=high']), workers=1)\n"
            "assert record.reallocations.sum() > 0, record.reallocations\n"
            "print('torch' in sys.modules)\n")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=600)
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.strip().splitlines()[-1] == "False"
