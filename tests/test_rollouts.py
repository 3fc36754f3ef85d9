"""A trainer's rollouts on several processes (ata.plugins.ata_hrl.phases.rollouts) are those
of one process to the bit: an ITA step's record, its recorded decisions, their
log-probabilities and the generator after it; a validation's record."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import torch

from ata.plugins.ata_hrl import logprob
from ata.plugins.ata_hrl.arch import KINDS
from ata.plugins.ata_hrl.network import encode_once
from ata.plugins.ata_hrl.phases.rollouts import Rollouts, StackedTrace, concat_traces, play
from ata.session import build_trainer, load_session, training_mission_for

IDS = np.repeat(np.arange(6) + 40, 3)


@pytest.fixture(scope="module")
def trainer():
    session = load_session(str(training_mission_for(["ctr", "aux"])), ["ata_hrl.batch_size=6"])
    tr = build_trainer(session)
    torch.manual_seed(5)
    with torch.no_grad():           # away from the prior, so the network's logits count
        for p in tr.net.ita.parameters():
            p.add_(0.3 * torch.randn_like(p))
    return tr


def rollout(trainer, workers: int | None):
    """One ITA step's rollout from the generator of seed 9: step by step (None) or on
    `workers` processes; (record, recorder, generator state)."""
    trainer.gen = torch.Generator().manual_seed(9)
    mission = trainer.mission_of("custom", 7)
    if workers is None:
        record, rec = play(trainer, mission, IDS, trainer.net,
                           logprob.torch_sampler(trainer.gen))
    else:
        pool = Rollouts(trainer, workers)
        try:
            record, rec = pool.ita(mission, IDS)
        finally:
            pool.close()
    return record, rec, trainer.gen.get_state()


def assert_same(trainer, a, b):
    for f in dataclasses.fields(a[0]):
        va, vb = getattr(a[0], f.name), getattr(b[0], f.name)
        if f.name == "metrics":
            assert va.keys() == vb.keys()
            for k in va:
                np.testing.assert_array_equal(va[k], vb[k])
        elif isinstance(va, np.ndarray):
            np.testing.assert_array_equal(va, vb, err_msg=f.name)
    assert torch.equal(a[2], b[2]), "the generator is not where the step-by-step loop left it"
    ta, tb = a[1].ita, b[1].ita
    assert ta.n_steps == tb.n_steps > 0
    for kind in KINDS:
        sa, sb = ta.stacked(kind), tb.stacked(kind)
        active = sa["active"]
        np.testing.assert_array_equal(active, sb["active"])
        for key in sa:
            np.testing.assert_array_equal(sa[key][active], sb[key][active], err_msg=key)
    with torch.no_grad():
        emb = encode_once(trainer.net.ita.encoder, a[1].inherent, torch.device("cpu"))
        la = logprob.trace_log_prob(trainer.net.ita, emb, ta)
        lb = logprob.trace_log_prob(trainer.net.ita, emb, tb)
    assert torch.equal(la[0], lb[0]) and torch.equal(la[1], lb[1])


def test_an_ita_rollout_on_any_processes_is_the_one_process_rollout(trainer):
    reference = rollout(trainer, None)
    # the samples of a scenario part: it sampled, not took the mode
    choices = reference[1].ita.stacked("poi")["choice"][0].reshape(-1, 3)
    assert (choices != choices[:, :1]).any()
    for workers in (1, 2, 4):
        assert_same(trainer, reference, rollout(trainer, workers))


def test_traces_of_parts_of_unequal_steps_join_with_idle_steps():
    def trace(S, E, fill):
        return StackedTrace({k: {"choice": np.full((S, E), fill), "active": np.ones((S, E), bool)}
                             for k in KINDS})
    joined = concat_traces([trace(2, 3, 1), trace(4, 2, 2)])
    assert joined.n_steps == 4
    poi = joined.stacked("poi")
    assert poi["choice"].shape == (4, 5)
    np.testing.assert_array_equal(poi["active"][:, :3], [[1] * 3] * 2 + [[0] * 3] * 2)
    np.testing.assert_array_equal(poi["choice"][:2], [[1, 1, 1, 2, 2]] * 2)
    np.testing.assert_array_equal(poi["choice"][2:], [[0, 0, 0, 2, 2]] * 2)
    assert poi["active"][:, 3:].all()


@pytest.mark.parametrize("phase", ["ita", "ctr"])
def test_a_validation_on_several_processes_is_the_one_process_validation(trainer, phase):
    mission = trainer.mission_of("custom", 11)
    records = []
    for workers in (1, 3):
        pool = Rollouts(trainer, workers)
        try:
            records.append(pool.mode(mission, np.arange(7), phase))
        finally:
            pool.close()
    assert records[1].reallocated.any() == (phase == "ctr")
    for f in dataclasses.fields(records[0]):
        va = getattr(records[0], f.name)
        if isinstance(va, np.ndarray):
            np.testing.assert_array_equal(va, getattr(records[1], f.name), err_msg=f.name)
    assert records[0].metrics.keys() == records[1].metrics.keys()


def test_a_worker_error_reaches_the_trainer_and_the_workers_end_with_it(trainer, monkeypatch):
    import threading

    from ata.plugins.ata_hrl.phases import rollouts

    real = rollouts.play_mode

    def fails_in_the_worker(host, mission, ids, phase):
        if ids[0] != 0:               # the second part's rows: played in the worker
            raise ValueError("a part failed")
        return real(host, mission, ids, phase)

    monkeypatch.setattr(rollouts, "play_mode", fails_in_the_worker)
    threads = threading.active_count()
    pool = Rollouts(trainer, 2)
    with pytest.raises(ValueError, match="a part failed"):
        pool.mode(trainer.mission_of("custom", 11), np.arange(4), "ita")
    assert threading.active_count() == threads, "the workers left a thread in the trainer"
    workers = [w.proc for w in pool.pool]
    assert workers and all(p.is_alive() for p in workers)
    pool.close()
    assert not any(p.is_alive() for p in workers)
