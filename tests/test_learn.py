"""ATA-HRL's learned parts: shapes and masks, state reconstruction, training, checkpoints."""

import numpy as np
import pytest
import torch
from typer.testing import CliRunner

from _support import whole_and_killed
from ata.cli import app
from ata.core.kernel import Simulation
from ata.core.runner import load_session
from ata.learn import nets
from ata.learn import train as T
from ata.learn.features import inherent_features, masks_for, state_features, to_tensors
from ata.learn.runtime import CheckpointError, read_checkpoint
from ata.plugins.auxiliary import AuxReconstructor
from ata.plugins.ctr import CTRPolicy
from ata.plugins.policies.attention import AttentionITA

FULL = ["ita", "ctr", "aux"]
TINY = ["train.batch_size=6", "train.eval_scenarios=6", "train.aux_batches=1",
        "train.aux_steps=4", "train.imitation_steps=2", "train.rl_steps=2",
        "train.eval_every=1", "train.checkpoint_every=1", "train.d_model=16",
        "train.recon_hidden=8", "train.threads=1"]


def session(*extra, plugins=FULL):
    return load_session(str(T.TRAIN_MISSION), [*TINY, *extra], plugins)


@pytest.mark.parametrize("setting, sizes", [("a", (6, 8, 60)), ("b", (12, 16, 130))])
def test_one_network_serves_both_settings_with_masks(setting, sizes):
    H, R, P = sizes
    s = session(f"mission.setting='{setting}'")
    net = nets.ATAHRLNet(T.net_config(s.mission))
    ctr = CTRPolicy(CTRPolicy.Settings(), s.mission, net=net)
    sim = Simulation(s.mission, s.registry, [0, 1],
                     overrides={"initial": AttentionITA(AttentionITA.Settings(), s.mission,
                                                        net=net),
                                "condition": ctr, "reallocation": ctr,
                                "reconstructors": AuxReconstructor(None, s.mission, net=net)})
    I = sim.reset()
    masks = masks_for(I, None)
    logits = net.ita_logits(to_tensors(inherent_features(I)), masks)
    assert logits["robot"].shape == (2, P, R)
    assert logits["navigator"].shape == (2, P, 1 + H)
    assert logits["classifier"].shape == (2, P, 1 + H)
    # only highly skilled humans may navigate: the others are masked out
    high = torch.as_tensor(I["humans"].col("skill") == 2)
    nav = logits["navigator"][:, :, 1:]
    assert torch.all((nav <= nets.NEG / 2) == ~high[:, None, :])
    # a robot observed down is never chosen at reallocation
    sim.step_epoch()
    observed = sim.last_context.observed
    observed["robots"].features[:, 0, observed["robots"].index("working")] = 0.0
    m2 = masks_for(I, observed)
    assert not m2.robot[:, 0].any() and m2.robot[:, 1:].all()
    hidden = net.initial_hidden(2)
    feats = to_tensors(state_features(observed))
    cond, tr, hidden = net.ctr_step(to_tensors(inherent_features(I)), feats, feats,
                                    torch.as_tensor(sim.sim.allocation.stack()), hidden, m2)
    assert cond.shape == (2,) and hidden.shape == (2, net.cfg.d_model)
    assert tr["robot"].shape == (2, P, R)
    triples = nets.choose(tr, sample=True)
    assert (triples[..., 0] != 0).all()
    assert ((triples[..., 1] == -1) | high.gather(1, triples[..., 1].clamp(min=0))).all()


def test_reconstructors_beat_the_noisy_and_stale_observations(tmp_path):
    s = session("train.aux_batches=2", "train.aux_steps=150", "train.batch_size=8",
                "train.recon_hidden=16", "train.lr=0.003", "mission.uncertainty='high'")
    trainer = T.Trainer(s, tmp_path, resume=False)
    before = trainer.aux_report()
    trainer.train_aux()
    after = trainer.aux_report()            # held-out scenarios, not trained on
    # the cVAE's fatigue is closer to the truth than the noisy observation (variance 0.2)
    assert after["fatigue_mse"] < 0.5 * after["fatigue_mse_raw"]
    # the stacked GRUs' robot rows are closer to the truth than the stale observed rows
    assert after["robots_mse"] < after["robots_mse_raw"]
    assert after["fatigue_mse"] < before["fatigue_mse"]


def test_imitation_loss_decreases(tmp_path):
    s = session("train.batch_size=8", "train.imitation_steps=12", "train.lr=0.003")
    trainer = T.Trainer(s, tmp_path)
    log = trainer.teacher_rollout(trainer._ids("imitation", 0), plan_targets=True)
    first = trainer.imitation_loss(log).item()
    for _ in range(20):
        trainer._optimise(trainer.imitation_loss(log))
    assert trainer.imitation_loss(log).item() < 0.9 * first


def test_rl_step_changes_the_policy_and_logs(tmp_path):
    s = session("train.rl_steps=2", "train.imitation_steps=0", "train.aux_steps=0")
    trainer = T.Trainer(s, tmp_path)
    before = [p.detach().clone() for p in trainer.net.ita_head.parameters()]
    trainer.train_rl()
    after = list(trainer.net.ita_head.parameters())
    assert any(not torch.equal(a, b) for a, b in zip(before, after))
    rows = (tmp_path / "log.csv").read_text().splitlines()
    assert rows[0].startswith("phase,step") and len(rows) == 3
    assert "rl,2" in rows[-1]


@pytest.mark.parametrize("phase, step", [("aux", "2"), ("rl", "1")])
def test_resume_after_kill_matches_an_uninterrupted_run(tmp_path, phase, step):
    whole, resumed = whole_and_killed(session(), tmp_path, phase, step)
    assert resumed.counters[phase] == int(step) - 1 or resumed.counters[phase] == int(step)
    assert resumed.counters != whole.counters
    resumed.run()
    assert resumed.counters == whole.counters
    for (k, a), (_, b) in zip(whole.net.state_dict().items(), resumed.net.state_dict().items()):
        assert torch.allclose(a, b, atol=1e-5), k


def test_checkpoint_round_trip_and_safe_load(tmp_path):
    s = session()
    trainer = T.Trainer(s, tmp_path)
    path = trainer.save()
    data = torch.load(path, weights_only=True)
    assert set(data) >= {"model", "optimizer", "rng", "counters", "config", "mission"}
    assert "[train]" in data["mission"] and data["config"]["d_model"] == 16
    assert read_checkpoint(path)["counters"] == trainer.counters


def test_corrupted_and_mismatched_checkpoints_fail_clearly(tmp_path):
    s = session()
    trainer = T.Trainer(s, tmp_path / "run")
    good = trainer.save()
    bad = tmp_path / "bad.pt"
    bad.write_bytes(good.read_bytes()[:200])
    with pytest.raises(CheckpointError, match="cannot be read as a checkpoint"):
        read_checkpoint(bad)
    other = session("train.d_model=8")
    with pytest.raises(CheckpointError, match="does not match"):
        T.Trainer(other, tmp_path / "run", resume=True)
    # through the CLI: one clear line, exit 2
    result = CliRunner(env={"COLUMNS": "200"}).invoke(
        app, ["run", str(T.TRAIN_MISSION), "--set", "mission.scenarios=1",
              *[x for c in ("attention", "ctr", "aux")
                for x in ("--set", f"{c}.checkpoint='{bad}'")]])
    assert result.exit_code == 2
    assert "cannot be read as a checkpoint" in result.output
    assert "Traceback" not in result.output


def test_sampled_decisions_do_not_depend_on_the_batch():
    s = session("components.condition='ctr'")
    torch.manual_seed(0)
    net = nets.ATAHRLNet(T.net_config(s.mission))

    def run(ids):
        ctr = CTRPolicy(CTRPolicy.Settings(sample=True), s.mission, net=net)
        sim = Simulation(s.mission, s.registry, ids, overrides={
            "initial": AttentionITA(AttentionITA.Settings(sample=True), s.mission, net=net),
            "condition": ctr, "reallocation": ctr,
            "reconstructors": AuxReconstructor(None, s.mission, net=net)})
        record = sim.run()
        return record.allocations, record.total

    alloc_batch, total_batch = run([3, 4, 5])
    alloc_alone, total_alone = run([5])
    np.testing.assert_array_equal(alloc_batch[2], alloc_alone[0])
    assert total_batch[2] == total_alone[0]
