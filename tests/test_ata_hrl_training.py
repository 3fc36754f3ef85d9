"""ATA-HRL's trainer (ata/plugins/ata_hrl/trainer.py and phases/): it trains what the slots hold,
resumes a killed run to the same weights and log, refuses checkpoints of another method, cycles
through the uncertainty levels, and labels pi_C's decisions by runs turned over there alone."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from _support import HRL_TINY as TINY, hrl_session as session, train, whole_and_killed
from ata.core.errors import MissionError
from ata.core.kernel import Simulation
from ata.session import BASELINE_MISSION, build_trainer, load_session, training_mission_for
from ata.training import CheckpointError, read_checkpoint


# --- the trainer as a component ----------------------------------------------------------------------

def test_the_trainer_trains_what_the_slots_hold():
    full = build_trainer(session())
    assert (full.trains_ita, full.trains_cond, full.trains_tr, full.trains_aux) == \
        (True, True, True, True)
    wo_c = build_trainer(session("components.condition='always'"))
    assert (wo_c.trains_cond, wo_c.trains_tr) == (False, True)
    wo_aux = build_trainer(session(plugins=("ctr",)))
    assert wo_aux.mission.slots.reconstructors == ["identity"] and not wo_aux.trains_aux
    assert wo_aux.phases()["aux"] == 0
    ita = build_trainer(session(plugins=("ita",)))
    assert (ita.trains_ita, ita.trains_cond, ita.trains_tr) == (True, False, False)
    with pytest.raises(MissionError, match="nothing to train"):
        build_trainer(session("components.initial='greedy'",
                              "components.condition='never'",
                              "components.reallocation='greedy'", plugins=("ita",)))
    with pytest.raises(MissionError, match="names no trainer"):
        build_trainer(load_session(str(BASELINE_MISSION)))
    # a trainer's table without the trainer is refused like any unchosen component's
    with pytest.raises(MissionError, match=r"\[ata_hrl\]: names no chosen component"):
        session("components.trainer='none'")


def test_training_run_of_wo_c_writes_checkpoints_that_run_as_components(tmp_path):
    s = session("components.condition='always'")
    trainer = train(s, tmp_path)
    assert trainer.counters == {"aux": 3, "status": 3, "ita": 2, "cond": 0, "ctr": 2,
                                "episodes": 16}
    data = torch.load(tmp_path / "checkpoint.pt", weights_only=True)
    assert data["kind"] == "ata_hrl" and data["trained"] == ["ita", "tr", "aux"]
    assert set(data) >= {"model", "optimizer", "aux_optimizer", "rng", "counters", "config",
                         "mission", "scenario_ranges"}
    rows = (tmp_path / "log.csv").read_text().splitlines()
    # the CTR phase: its untrained parts validated at step 0, then two steps
    assert rows[0].startswith("phase,step") and sum(r.startswith("ctr,") for r in rows) == 3
    # the trained network runs from its file, and reports the scenarios it was trained on
    best = tmp_path / "best.pt"
    run = load_session(str(tmp_path / "mission.resolved.toml"),
                       ["mission.scenarios=2", *[f"{c}.checkpoint='{best}'"
                                                 for c in ("attention", "ctr", "aux")]])
    sim = Simulation(run.mission, run.registry, [2 ** 40, 2 ** 40 + 1])
    ranges = [r for rs in sim.pm.hook.ata_trained_on() for r in rs]
    assert (12345, 10_000_000, 20_000_000) in ranges
    assert sim.run().reallocated[:, 1:].all()


def test_ita_from_shares_an_ita_and_init_from_trains_on(tmp_path):
    first = train(session("ata_hrl.seed=7", plugins=("ita",)), tmp_path / "ita")
    src = tmp_path / "ita" / "best.pt"
    # ita_from: the same ITA weights, no ITA phase, and the source's scenarios reported
    shared = train(session("components.condition='always'", f"ata_hrl.ita_from='{src}'",
                           "ata_hrl.ctr_steps=1"), tmp_path / "wo_c")
    assert shared.counters["ita"] == 0 and shared.counters["ctr"] == 1
    best_ita = read_checkpoint(src, "ata_hrl")["model"]
    for k, v in shared.net.ita.state_dict().items():
        assert torch.equal(v, best_ita[f"ita.{k}"]), k
    assert set(first.scenario_ranges()) <= set(shared.scenario_ranges())
    # init_from: every network as the source's, then the ITA phase goes on from there
    more = build_trainer(session(f"ata_hrl.init_from='{src}'", "ata_hrl.ita_steps=1",
                                 plugins=("ita",)))
    more.take_ita(str(src), whole=True)
    assert all(torch.equal(v, best_ita[k]) for k, v in more.net.state_dict().items())
    # a checkpoint that trained no ITA cannot lend one
    no_ita = train(session("components.initial='greedy'", "components.condition='ctr'",
                           "ata_hrl.ctr_steps=1", plugins=("ctr", "aux")), tmp_path / "no_ita")
    with pytest.raises(CheckpointError, match="trained no ITA"):
        no_ita.take_ita(str(tmp_path / "no_ita" / "best.pt"))


# the rule's rounds need event epochs where pi_C re-plans, which the tiny team's short episodes
# and an untrained pi_C lack: setting (a), from the shipped weights
RULE_ROUNDS = ("ata_hrl.cond_scenarios=2", "ata_hrl.cond_rounds=2",
               "ata_hrl.init_from='builtin:ata_hrl_a'", "ata_hrl.aux_steps=0",
               "ata_hrl.ita_steps=0", "ata_hrl.ctr_steps=0")


def log_rows(run_dir) -> list[dict]:
    """log.csv's rows without the columns that time the run."""
    import csv
    with open(run_dir / "log.csv", newline="") as f:
        return [{k: v for k, v in r.items() if k not in ("wall_s", "episodes_per_s")}
                for r in csv.DictReader(f)]


@pytest.mark.parametrize("phase, step, extra", [
    ("aux", "2", ()), ("status", "2", ()), ("ita", "1", ()),
    pytest.param("cond", "0", RULE_ROUNDS, marks=pytest.mark.slow),  # before any checkpoint
    # killed in the rule's second round, the first saved (100 s: slow)
    pytest.param("cond", "2", RULE_ROUNDS, marks=pytest.mark.slow),
    ("ctr", "2", ()),
    ("ita", "2", ("ata_hrl.ita_steps=4", "ata_hrl.lr=3e-3", "ata_hrl.lr_end=0.1")),
    ("ita", "3", ("ata_hrl.ita_steps=4", "ata_hrl.ita_epochs=2"))])
def test_resume_after_kill_ends_with_the_same_weights_and_log(tmp_path, phase, step, extra):
    s = session(*extra) if extra is not RULE_ROUNDS else load_session(
        str(training_mission_for(["ctr", "aux"])),
        [*(k for k in TINY if not k.startswith(("mission.", "ata_hrl.d_model", "ata_hrl.hidden",
                                                "ata_hrl.recon_hidden", "ata_hrl.status_"))),
         *extra])
    whole, resumed = whole_and_killed(s, tmp_path, phase, step)
    assert resumed.counters == whole.counters
    assert whole.net.state_dict().keys() == resumed.net.state_dict().keys()
    for k, a in whole.net.state_dict().items():
        assert torch.equal(a, resumed.net.state_dict()[k]), k
    assert log_rows(tmp_path / "broken") == log_rows(tmp_path / "whole")


@pytest.mark.parametrize("name", ["ata_hrl_a", "ata_hrl_b_ft", "ata_hrl_wo_aux_a",
                                  "ata_hrl_wo_aux_b_ft", "ata_hrl_wo_c_a", "ata_hrl_wo_c_b_ft"])
def test_a_shipped_checkpoint_resumes_under_the_mission_it_records(tmp_path, name):
    # each shipped file, with the training mission it records, is a run folder that `ata
    # train --resume` carries on: its trainer takes the networks, optimisers, generators and
    # counters; ata_hrl_a's run is done, and resuming it changes no weight
    from ata.training import WEIGHTS
    data = read_checkpoint(WEIGHTS / f"{name}.pt", "ata_hrl")
    (tmp_path / "mission.resolved.toml").write_text(data["mission"])
    (tmp_path / "checkpoint.pt").write_bytes((WEIGHTS / f"{name}.pt").read_bytes())
    # an ita_from or init_from that names a run folder of its time (not shipped) is read from
    # the shipped file itself, which holds those networks: so the ITA phase stays skipped
    unshipped = [f"ata_hrl.{key}='builtin:{name}'" for key in ("ita_from", "init_from")
                 if data[key].startswith("runs/")]
    trainer = build_trainer(load_session(str(tmp_path / "mission.resolved.toml"), unshipped))
    trainer.load(tmp_path / "checkpoint.pt")
    zero = {"aux": 0, "status": 0, "ita": 0, "cond": 0, "ctr": 0, "episodes": 0}
    assert trainer.counters == {**zero, **data["counters"]}
    assert all(torch.equal(v, data["model"][k]) for k, v in trainer.net.state_dict().items())
    if name == "ata_hrl_a":
        again = train(load_session(str(tmp_path / "mission.resolved.toml"), unshipped),
                      tmp_path, resume=True)
        assert again.counters == data["counters"]
        model = read_checkpoint(tmp_path / "checkpoint.pt", "ata_hrl")["model"]
        assert model.keys() == data["model"].keys()
        assert all(torch.equal(model[k], v) for k, v in data["model"].items())


# --- checkpoints -------------------------------------------------------------------------------------

def test_checkpoints_of_another_method_or_broken_are_refused(tmp_path, cli):
    trainer = train(session(*["ata_hrl.ita_steps=0", "ata_hrl.ctr_steps=0",
                              "ata_hrl.aux_steps=0"]), tmp_path / "run")
    good = tmp_path / "run" / "best.pt"
    data = read_checkpoint(good, "ata_hrl")
    assert data["counters"] == trainer.counters
    empty = tmp_path / "empty.pt"
    empty.write_bytes(b"")
    cut = tmp_path / "cut.pt"
    cut.write_bytes(good.read_bytes()[:200])
    foreign = tmp_path / "foreign.pt"
    torch.save({**data, "kind": "tr_pomdp"}, foreign)
    for path, message in ((empty, "cannot be read as a checkpoint"),
                          (cut, "cannot be read as a checkpoint"),
                          (foreign, "is a checkpoint of 'tr_pomdp', not of 'ata_hrl'"),
                          (tmp_path / "missing.pt", "no such checkpoint")):
        with pytest.raises(CheckpointError, match=message):
            read_checkpoint(path, "ata_hrl")
        # through the CLI: one clear line, exit 2
        res = cli("run", str(tmp_path / "run" / "mission.resolved.toml"), "--set",
                  "mission.scenarios=1", "--set", f"attention.checkpoint='{path}'",
                  "--set", f"ctr.checkpoint='{good}'", "--set", f"aux.checkpoint='{good}'",
                  "--quiet", "-o", tmp_path / "out")
        assert res.exit_code == 2, res.output
        assert message.split(",")[0] in " ".join(res.output.split())
        assert "Traceback" not in res.output
    # a checkpoint of the layout before pi_C's rule was part of every network is refused
    from ata.plugins.ata_hrl.checkpoint import net_from_checkpoint
    old = tmp_path / "old.pt"
    torch.save({**data, "format": 2}, old)
    with pytest.raises(CheckpointError, match="of format 2; this version reads format 3"):
        net_from_checkpoint(read_checkpoint(old, "ata_hrl"), old)
    with pytest.raises(CheckpointError, match="of format 2"):
        trainer.take_ita(str(old))


def test_the_trainer_cycles_through_uncertainty_levels_and_validates_on_each(tmp_path,
                                                                               monkeypatch):
    from ata.core.mission import UNCERTAINTY_LEVELS
    from ata.plugins.ata_hrl.trainer import ATAHRLTrainer
    seen = []
    real = ATAHRLTrainer.rollout

    def spy(self, mission, ids, phase, train):
        seen.append((train, mission.settings.uncertainty, mission.event_probability,
                     mission.fatigue_variance))
        return real(self, mission, ids, phase, train)

    monkeypatch.setattr(ATAHRLTrainer, "rollout", spy)
    trainer = train(session("ata_hrl.ita_steps=3", "ata_hrl.eval_every=3",
                            "ata_hrl.eval_scenarios=2", "ata_hrl.batch_size=2",
                            "ata_hrl.samples=2", "ata_hrl.uncertainty_levels=['low', 'high']",
                            plugins=("ita",)), tmp_path / "levels")
    steps = [s[1:] for s in seen if s[0]]
    low = ("low", *UNCERTAINTY_LEVELS["low"][::-1])       # (level, p, fatigue variance)
    high = ("high", *UNCERTAINTY_LEVELS["high"][::-1])
    assert steps == [low, high, low]
    # each validation (at step 0 and step 3) plays both levels
    assert [s[1:] for s in seen if not s[0]] == [low, high, low, high]
    log = (tmp_path / "levels" / "log.csv").read_text().splitlines()
    assert [row.split(",")[2] for row in log[2:5]] == ["a/low", "a/high", "a/low"]
    assert trainer.counters["ita"] == 3


def test_a_run_with_no_ctr_step_ends_with_pi_tr_copied_from_its_ita(tmp_path):
    # ctr_steps = 0 (the shipped recipe: the CTR phase's step 0) must leave pi_TR as a run with
    # CTR steps starts it, copied from the ITA, not at its random initialisation
    train(session("ata_hrl.seed=5", plugins=("ita",)), tmp_path / "ita")
    src = tmp_path / "ita" / "best.pt"
    train(session(f"ata_hrl.ita_from='{src}'", "ata_hrl.ctr_steps=0"), tmp_path / "step0")
    for name in ("best.pt", "checkpoint.pt"):
        model = read_checkpoint(tmp_path / "step0" / name, "ata_hrl")["model"]
        pairs = [k for k in model if k.startswith(("tr.encoder.", "tr.scorers."))]
        assert pairs and all(torch.equal(model[k], model["ita." + k[3:]]) for k in pairs), name
        keep = [k for k in model if k.startswith("tr.keep.linear.")]
        assert keep and all(not model[k].any() for k in keep), name


def test_a_turned_over_condition_decision_changes_that_epoch_alone():
    # the cond phase's counterfactual runs: pi_C's decision at the given epoch is turned over,
    # and every epoch before it is as the policy decided (the same random streams)
    s = session("ata_hrl.cond_scenarios=2", "mission.uncertainty='high'",
                "mission.horizon_s=1800")
    tr = build_trainer(s)
    mission = tr.mission_of("a/high", 5)
    ids = np.arange(3)
    base = Simulation(mission, s.registry, ids, overrides=tr.overrides(mission, "ctr", None,
                                                                       None)).run()
    flip = np.array([1, 4, 9])
    overrides = tr.overrides(mission, "ctr", None, None)
    overrides["condition"].flip_at = flip
    turned = Simulation(mission, s.registry, ids, overrides=overrides).run()
    for i, f in enumerate(flip):
        assert turned.reallocated[i, f] != base.reallocated[i, f]
        assert np.array_equal(turned.reallocated[i, :f], base.reallocated[i, :f])
        assert np.array_equal(turned.r_expected[i, :f], base.r_expected[i, :f])


def shipped_cond_trainer(*extra):
    """A trainer of the full method with a cond phase, its networks the shipped (a) ones but
    for pi_C's rule (left off, as init_from leaves it)."""
    tr = build_trainer(load_session(str(training_mission_for(["ctr", "aux"])),
                                    ["ata_hrl.cond_scenarios=2", *extra]))
    tr.take_ita("builtin:ata_hrl_a", whole=True)
    return tr


def test_the_cond_phase_labels_each_replan_by_a_run_turned_over_there_alone():
    # on two (a) scenarios at high uncertainty, with the rule off: the labelled epochs are
    # those where the policy re-planned, and a label's gain, the weight with the sign of "the
    # other choice did better", is what a run of that scenario turned over at that epoch alone
    # gives from that epoch on (scenario 0's first, middle and last labels, one run each)
    tr = shipped_cond_trainer("ata_hrl.batch_size=2")
    assert not tr.net.cond.rule_on()
    mission = tr.mission_of("a/high", 77)
    ids = np.array([3, 4])
    b = tr.cond.batch(mission, ids)
    np.testing.assert_array_equal(b["labelled"], b["taken"])
    assert b["episodes"] == 2 + b["labelled"].sum()
    assert not b["weight"][~b["labelled"]].any()

    def run(flip):
        overrides = tr.overrides(mission, "ctr", None, None)
        overrides["condition"].flip_at = flip
        return Simulation(mission, tr.registry, ids[:1], overrides=overrides).run()

    base = run(None)
    (epochs,) = np.nonzero(b["labelled"][0])
    assert epochs.size >= 3
    for e in epochs[[0, epochs.size // 2, -1]] + 1:       # labels are of epochs 1 .. T-1
        sign = 1 if b["target"][0, e - 1] != b["taken"][0, e - 1] else -1
        gain = run(np.array([e])).r_expected[0, e:].sum() - base.r_expected[0, e:].sum()
        assert gain == pytest.approx(sign * b["weight"][0, e - 1], abs=1e-6), e


def test_the_rule_is_the_weighted_logistic_regression_and_decides_event_epochs_alone(tmp_path):
    # the fit is the optimum of the weighted, L2-penalised logistic regression on the
    # standardised features; then event epochs follow the rule alone and quiet epochs the
    # network; only cond.rule.* changes, and a checkpoint holds the rule switched on
    from ata.plugins.ata_hrl.checkpoint import net_from_checkpoint
    from ata.plugins.ata_hrl.phases.cond import fit_rule
    tr = shipped_cond_trainer("ata_hrl.batch_size=3")
    assert tr.phases()["cond"] == 1 and tr.net.cond.rule.on == 0
    b = tr.cond.batch(tr.mission_of("a/high", 77), np.array([3, 4, 5]))
    feats, prior = b["feats"][:, 0], torch.tensor([1.0, -1.0, 1.0])
    hidden = torch.zeros(3, tr.cfg.d_model)
    with torch.no_grad():
        net, _ = tr.net.cond(b["pooled"][:, 0], feats, prior, hidden)
    before = {k: v.clone() for k, v in tr.net.state_dict().items()}
    fit_rule(tr.net.cond.rule, [b], 1e-2)
    changed = {k for k, v in tr.net.state_dict().items() if not torch.equal(v, before[k])}
    assert changed == {"cond.rule.weight", "cond.rule.bias", "cond.rule.on"}
    # the optimum: the penalised objective's gradient, in the standardised features, is zero
    m = b["labelled"] & (b["prior"].numpy() > 0)
    F = b["feats"].numpy()[m].astype(np.float64)
    t, w = b["target"][m].astype(np.float64), b["weight"][m] / b["weight"][m].sum()
    mu, sd = F.mean(0), F.std(0) + 1e-9
    rule = tr.net.cond.rule
    beta_w = rule.weight.detach().double().numpy()[0] * sd
    beta = np.r_[beta_w, rule.bias.item() + np.sum(beta_w * mu / sd)]
    X = np.c_[(F - mu) / sd, np.ones(len(F))]
    p = 1 / (1 + np.exp(-X @ beta))
    assert np.abs(X.T @ ((p - t) * w) + 1e-2 * beta).max() < 1e-4
    with torch.no_grad():
        logit, _ = tr.net.cond(b["pooled"][:, 0], feats, prior, hidden)
        alone = rule(feats)[:, 0]
    assert logit[0] == alone[0] and logit[2] == alone[2] and logit[1] == net[1]
    torch.save(tr.checkpoint(), tmp_path / "rule.pt")
    again = net_from_checkpoint(read_checkpoint(tmp_path / "rule.pt", "ata_hrl"), "rule.pt")
    assert again.cond.rule.on == 1 and torch.equal(again.cond.rule.weight, rule.weight)


def test_later_rounds_of_the_rule_label_every_event_epoch_as_the_rule_decides():
    # cond_rounds: from the second round on, the labels are collected with the fitted rule
    # deciding the event epochs, and every event epoch is labelled (re-planned or skipped),
    # so that the rule is fitted again on the states it leads to
    from ata.plugins.ata_hrl.phases.cond import fit_rule
    tr = shipped_cond_trainer("ata_hrl.batch_size=4", "ata_hrl.cond_rounds=2")
    assert tr.phases()["cond"] == 2 and not tr.net.cond.rule_on()
    mission = tr.mission_of("a/high", 77)
    ids = np.array([3, 4, 5, 6])
    first = tr.cond.batch(mission, ids)
    assert np.array_equal(first["labelled"], first["taken"])     # where it re-planned
    fit_rule(tr.net.cond.rule, [first], 1e-2)
    with torch.no_grad():        # make the rule skip some events: their labels must be kept
        tr.net.cond.rule.bias -= 1.0
    assert tr.net.cond.rule_on()
    second = tr.cond.batch(mission, ids)
    prior = second["prior"].numpy() > 0
    assert np.array_equal(second["labelled"], prior)
    # the rule decided the event epochs: its logit's sign, from the recorded features
    with torch.no_grad():
        logit = tr.net.cond.rule(second["feats"])[..., 0].numpy()
    assert np.array_equal(second["taken"][prior], logit[prior] > 0)
    assert (prior & ~second["taken"]).any()                      # skipped events, labelled
    assert (second["weight"][~prior] == 0).all()                 # only they were turned over


# --- the device of the updates ------------------------------------------------------------------


@pytest.mark.parametrize("phase", ["ita", "ctr"])
def test_an_update_computes_on_the_device_its_network_is_on(phase, monkeypatch):
    # the "meta" device holds shapes alone and refuses any CPU tensor beside its own: a loss
    # that left one of its inputs on the CPU fails here, as it would on a GPU
    import copy

    from ata.plugins.ata_hrl.network import ConditionNet
    from ata.plugins.ata_hrl.phases.policy import rewards
    tr = build_trainer(session())
    assert tr.trains_cond and tr.trains_tr
    part = getattr(tr, phase)
    part.start()
    record, rec = tr.rollout(tr.mission_of("custom", 7), np.repeat(np.arange(2), 2), phase,
                             train=True)
    assert rec.ita if phase == "ita" else rec.tr, "the rollout recorded no decision to score"
    R = rewards(record)
    cpu_loss = part.loss(rec, R)
    monkeypatch.setattr(ConditionNet, "rule_on", lambda self: False)   # reads a value: no meta
    tr.net, tr.device = copy.deepcopy(tr.net).to("meta"), torch.device("meta")
    loss = part.loss(rec, R)
    loss.backward()
    assert loss.device.type == "meta" and cpu_loss.device.type == "cpu"
    assert loss.shape == cpu_loss.shape == ()


def test_an_update_device_torch_cannot_use_is_refused_before_any_work():
    with pytest.raises(MissionError, match="not a device"):
        build_trainer(session("ata_hrl.device='tpu'"))
    if not torch.cuda.is_available():
        with pytest.raises(MissionError, match="sees no CUDA device"):
            build_trainer(session("ata_hrl.device='cuda'"))


def test_an_ita_update_on_several_threads_is_bit_for_bit_the_one_thread_update():
    # `threads` takes the update's parts' gradients side by side: the weights and the Adam
    # state after the step are those of one thread, and of backward() on each part in turn
    previous = torch.get_num_threads()
    torch.set_num_threads(1)             # as the trainer's run sets it
    try:
        states, losses = _one_ita_step_each((1, 3, 0))
    finally:
        torch.set_num_threads(previous)
    assert losses[0] == losses[1] == losses[2]
    for other in states[1:]:
        assert other.keys() == states[0].keys()
        for key, value in states[0].items():
            assert torch.equal(other[key], value), key
    # the step moved the weights (an update that did nothing would pass the above)
    fresh = build_trainer(session("ata_hrl.batch_size=4")).net.state_dict()
    assert any(not torch.equal(fresh[k], states[0][k]) for k in fresh)


def _one_ita_step_each(counts):
    """For each thread count (0: backward() on each part in turn), one ITA step of a fresh
    trainer on the same rollout: its network and Adam state, and its loss."""
    from ata.plugins.ata_hrl.phases.policy import rewards
    states, losses = [], []
    for threads in counts:
        tr = build_trainer(session("ata_hrl.batch_size=4", f"ata_hrl.threads={max(threads, 1)}",
                                   "ata_hrl.ita_epochs=1"))      # one update: the reference's
        tr.ita.start()
        record, rec = tr.rollout(tr.mission_of("custom", 7), np.repeat(np.arange(4), 2), "ita",
                                 train=True)
        R = rewards(record)
        assert len(list(tr.ita.parts(rec, R))) == 4, "the update should have four parts"
        if threads:
            losses.append(tr.ita.learn(rec, R))
        else:                          # the reference: backward() on each part in turn
            tr.opt.zero_grad()
            loss = 0.0
            for part in tr.ita.parts(rec, R):
                value = part()
                value.backward()
                loss += value.item()
            tr.ita.update()
            losses.append(loss)
        states.append({**tr.net.state_dict(),
                       **{f"opt{i}": v["exp_avg_sq"] for i, v in tr.opt.state_dict()["state"]
                          .items()}})
    return states, losses


def test_the_ita_learning_rate_falls_along_a_half_cosine_to_lr_end(tmp_path):
    tr = build_trainer(session("ata_hrl.ita_steps=5", "ata_hrl.lr=2e-3", "ata_hrl.lr_end=0.1"))
    lrs = [tr.ita.lr_at(k) for k in range(5)]
    assert lrs[0] == pytest.approx(2e-3) and lrs[-1] == pytest.approx(2e-4)
    assert lrs[2] == pytest.approx(1.1e-3)                  # half way: the mean of the two
    assert all(a > b for a, b in zip(lrs, lrs[1:]))
    assert tr.ctr.lr_at(3) == tr.s.ctr_lr                   # the CTR phase keeps its own
    flat = build_trainer(session("ata_hrl.ita_steps=5", "ata_hrl.lr=2e-3", "ata_hrl.lr_end=1"))
    assert [flat.ita.lr_at(k) for k in range(5)] == [2e-3] * 5
    # each step updates with its rate: the optimiser holds the last step's
    done = train(session("ata_hrl.ita_steps=3", "ata_hrl.lr=2e-3", "ata_hrl.lr_end=0.25",
                         "ata_hrl.ctr_steps=0"), tmp_path)
    assert [g["lr"] for g in done.opt.param_groups] == [pytest.approx(5e-4)]
