"""ATA-HRL (ata/plugins/ata_hrl): the capacity-aware decoder checked by hand on a tiny team,
the shared baseline, the networks against their priors, the full re-plan's choice, and the
state reconstruction (the aux module and its status head). The trainer's tests are in
test_ata_hrl_training.py."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch

from _support import HRL_TINY as TINY, hrl_session as session, train
from ata.core.errors import MissionError
from ata.core.kernel import Simulation, build_component
from ata.session import BASELINE_MISSION, build_trainer, load_session, training_mission_for
from ata.core.state import Allocation
from ata.model import tables
from ata.plugins.ata_hrl.components import AttentionITA, AuxReconstructor, CTRPolicy
from ata.plugins.ata_hrl.decoder import DecodeSettings, Decoder
from ata.plugins.ata_hrl.network import ATAHRLNet, NetConfig
from ata.plugins.ata_hrl.phases.policy import shared_baseline_advantage
from ata.model.plan import PlanStart
from ata.training import read_checkpoint
# --- the decoder, by hand --------------------------------------------------------------------------

def tiny_start(horizon=50.0):
    """Two POIs, two humans (0 highly skilled, 1 low), a UAV and a UGV at the base (1000, 1000).
    POI 0: 80 m east, ground, low (15 points); POI 1: 240 m north, air, high (35 points)."""
    return PlanStart(
        now=0.0, horizon=horizon,
        task_xy=np.array([[[1080.0, 1000.0], [1000.0, 1240.0]]]),
        kind=np.array([[tables.GROUND, tables.AIR]]), diff=np.array([[0, 2]]),
        points=np.array([[15.0, 35.0]]), open=np.ones((1, 2), bool),
        eta=np.array([[0.6, 0.4]]), lam=np.array([[0.6, 0.3]]), skill=np.array([[2, 0]]),
        hours=np.zeros((1, 2)), human_free=np.zeros((1, 2)),
        robot_type=np.array([[tables.UAV, tables.UGV]]), speed=np.array([[8.0, 3.0]]),
        robot_free=np.zeros((1, 2)), robot_xy=np.full((1, 2, 2), 1000.0),
        robot_at=np.full((1, 2), -1))


def test_decoder_masks_and_updates_the_members_after_each_choice():
    dec = Decoder(tiny_start(), np.ones((1, 2), bool), np.ones((1, 2)), np.zeros((1, 2)),
                  DecodeSettings())
    poi = dec.poi_inputs()
    assert poi.mask.tolist() == [[True, True]] and dec.r_ff.tolist() == [0]
    robots = dec.robot_inputs(np.array([0]))
    assert robots.mask.tolist() == [[True, True]]
    assert robots.prior.tolist() == [[1.0, 0.0]]            # greedy's robot: the one free first
    nav = dec.nav_inputs(np.array([0]), np.array([0]))
    # autonomous, human 0 (highly skilled); human 1 (low skill) may not navigate
    assert nav.mask.tolist() == [[True, True, False]]
    # POI 0 to the UAV, navigated by human 0, classified by human 1:
    #   leg 80 m at 8 * 1.5 m/s + 3 s capture = 9.6667 s, human 0 busy 0 .. 9.6667;
    #   image quality UAV / ground / high-skill navigator = Upper-Medium (2): t_bar 25 s;
    #   human 1 classifies 9.6667 .. 34.6667
    dec.commit(np.array([True]), np.array([0]), np.array([0]), np.array([0]), np.array([1]))
    leg = 80.0 / 12.0 + 3.0
    assert dec.robot_free[0].tolist() == pytest.approx([leg, 0.0])
    assert dec.robot_xy[0, 0].tolist() == [1080.0, 1000.0]
    assert dec.human_free[0].tolist() == pytest.approx([leg, leg + 25.0])
    assert dec.load.booked[0].tolist() == pytest.approx([leg, 25.0])
    # human 1's projected utilisation at t = 100: 25 busy s of the 100 elapsed
    u = dec.load.utilisation_at(np.full((1, 1, 2), 100.0))
    assert u[0, 0].tolist() == pytest.approx([leg / 100.0, 0.25])
    # POI 1 next: the UGV is free first now, but from the base it needs 240/3 + 3 = 83 s > 50:
    # only the UAV reaches it in time (from POI 0: sqrt(80^2 + 240^2) / 8 + 3 after 9.67 s)
    poi = dec.poi_inputs()
    assert poi.mask.tolist() == [[False, True]] and dec.r_ff.tolist() == [1]
    robots = dec.robot_inputs(np.array([1]))
    assert robots.mask.tolist() == [[True, False]]
    cls = dec.cls_inputs(np.array([1]), np.array([0]), np.array([-1]))
    # onboard: UAV / air / autonomous = Upper-Medium, P_rc[UM, high] = 0.3
    assert cls.features[0, 0, 1] == pytest.approx(0.3)
    dec.commit(np.array([True]), np.array([1]), np.array([0]), np.array([-1]), np.array([-1]))
    arrive = leg + math.hypot(80.0, 240.0) / 8.0 + 3.0
    assert dec.robot_free[0, 0] == pytest.approx(arrive)
    assert not dec.poi_inputs().active.any()
    alloc = dec.finish()
    assert alloc.stack()[0].tolist() == [[0, 0, 1], [0, -1, -1]]


def test_replay_books_the_kept_pois_in_route_order_and_rebriefs_on_a_change():
    start = tiny_start(horizon=1800.0)
    prev = Allocation(np.array([[0, 0]]), np.array([[-1, -1]]), np.array([[1, 1]]))
    dec = Decoder(start, np.ones((1, 2), bool), np.ones((1, 2)), np.zeros((1, 2)),
                  DecodeSettings(rebrief_s=20.0), previous=prev)
    dec.replay(np.array([[True, False]]))
    # POI 0 kept: the UAV flies 80/8 + 3 = 13 s; human 1 classifies it 13 .. 13 + t_bar[Medium,
    # low] 35 = 48 (quality Medium: UAV / ground / autonomous)
    assert dec.robot_free[0, 0] == pytest.approx(13.0)
    assert dec.human_free[0].tolist() == pytest.approx([0.0, 48.0])
    assert dec.left.tolist() == [[False, True]]
    # POI 1 planned again onboard: human 1 loses it, a re-brief of 20 s after its work (48)
    dec.commit(np.array([True]), np.array([1]), np.array([0]), np.array([-1]), np.array([-1]))
    assert dec.human_free[0, 1] == pytest.approx(68.0) and dec.touched[0].tolist() == [False,
                                                                                       True]


def test_first_reallocation_step_follows_greedy_and_masks_down_robots():
    # pi_TR's first step, per POI: decode again (0), keep (1), greedy's triple (2)
    start = tiny_start(horizon=1800.0)
    start.robot_free[0, 1] = np.inf                     # the UGV is seen down
    prev = Allocation(np.array([[0, 1]]), np.array([[-1, -1]]), np.array([[-1, 1]]))
    dec = Decoder(start, np.ones((1, 2), bool), np.ones((1, 2)), np.zeros((1, 2)),
                  DecodeSettings(), previous=prev)
    # greedy keeps POI 0 and moves POI 1 (held by the robot that is down) to the UAV
    greedy = Allocation(np.array([[0, 0]]), np.array([[-1, -1]]), np.array([[-1, 1]]))
    first = dec.keep_inputs(np.zeros((1, 2)), np.full((1, 2), np.inf), np.zeros((1, 2), bool),
                            greedy)
    assert dec.prev_valid.tolist() == [[True, False]]
    # POI 0: greedy keeps it, so keeping is the prior (greedy's triple is the same: masked);
    # POI 1: its robot is down, so no keeping; greedy changes it, so the prior decodes it again,
    # greedy's triple the other choice
    assert first.mask[0].tolist() == [[True, True, False], [True, False, True]]
    assert first.prior[0].tolist() == [[-1.0, 1.0, 0.0], [1.0, -1.0, 0.0]]
    assert first.features[0, :, 0].tolist() == [1.0, 0.0]      # robot up
    assert first.features[0, :, 3].tolist() == [0.0, 1.0]      # classified by a human
    assert first.features[0, :, 12].tolist() == [1.0, 0.0]     # greedy keeps it


# --- the shared baseline and the networks ----------------------------------------------------------

def test_shared_baseline_advantages_sum_to_zero_per_scenario():
    rewards = np.array([10.0, 12.0, 11.0, 3.0, -1.0, 0.0, 4.0, 9.0])   # 2 scenarios x 4 samples
    adv = shared_baseline_advantage(rewards, 4).reshape(2, 4)
    np.testing.assert_allclose(adv.sum(axis=1), 0.0, atol=1e-12)
    # scenario 0: mean 9; scenario 1: mean 3
    np.testing.assert_allclose(adv[0], [1.0, 3.0, 2.0, -6.0])
    np.testing.assert_allclose(adv[1], [-4.0, -3.0, 1.0, 6.0])


def components(s, net, learned=True, sample=False):
    st = AttentionITA.Settings(learned=learned, sample=sample)
    ita = AttentionITA(st, s.mission, net=net)
    ctr = CTRPolicy(CTRPolicy.Settings(learned=learned, sample=sample), s.mission, net=net)
    return {"initial": ita, "condition": ctr, "reallocation": ctr,
            "reconstructors": AuxReconstructor(None, s.mission, net=net)}


def test_the_ctr_phase_starts_pi_tr_as_the_trained_ita(tmp_path):
    # one CTR step at learning rate 0: what the phase started from, unchanged by the step
    trainer = train(session("ata_hrl.ctr_steps=1", "ata_hrl.ctr_lr=0"), tmp_path)
    tr, ita = trainer.net.tr, trainer.net.ita
    for name, value in ita.scorers.state_dict().items():
        assert torch.equal(tr.scorers.state_dict()[name], value), name
    assert all(not layer.weight.any() for layer in tr.state.values())
    # so pi_TR's embeddings of any state are the ITA's of I
    feats = {g: torch.rand(2, n, d) for g, n, d in (("humans", 3, 5), ("robots", 4, 3),
                                                     ("tasks", 12, 7))}
    state = {g: torch.rand(2, n, d) for g, n, d in (("humans", 3, 4), ("robots", 4, 5),
                                                     ("tasks", 12, 7))}
    with torch.no_grad():
        a = tr.embed(tr.encoder(feats), state, state)
        b = ita.encoder(feats)
    assert all(torch.allclose(a[g], b[g]) for g in a)


def test_an_untrained_network_decides_as_its_prior_alone():
    # the scorers' learned parts start at zero: with the learned part on or off, the same
    # decisions (pi_C: the on_event rule; pi_TR: repair; the ITA: greedy's choices)
    s = session()
    net = ATAHRLNet(NetConfig(d_model=16, hidden=16, recon_hidden=8))
    runs = [Simulation(s.mission, s.registry, [0, 1, 2], overrides=components(s, net, learned))
            .run() for learned in (True, False)]
    np.testing.assert_array_equal(runs[0].allocations, runs[1].allocations)
    np.testing.assert_array_equal(runs[0].reallocated, runs[1].reallocated)
    # and pi_C decides exactly as the on_event condition does in its place, on the same state
    # (the observed one: an untrained aux module's rows are not)
    def run(condition):
        over = components(s, net)
        over["reconstructors"] = build_component(s.registry, s.mission, "reconstructor",
                                                 "identity")
        if condition:
            over["condition"] = build_component(s.registry, s.mission, "condition", condition)
        return Simulation(s.mission, s.registry, [0, 1, 2], overrides=over).run()

    pi_c, on_event = run(None), run("on_event")
    np.testing.assert_array_equal(pi_c.reallocated, on_event.reallocated)
    np.testing.assert_array_equal(pi_c.allocations, on_event.allocations)
    assert pi_c.reallocated[:, 1:].sum(1).tolist() == [3, 4, 2]     # the epochs with events


def test_sampled_decisions_do_not_depend_on_the_batch():
    s = session()
    torch.manual_seed(0)
    net = ATAHRLNet(NetConfig(d_model=16, hidden=16, recon_hidden=8))

    def run(ids):
        record = Simulation(s.mission, s.registry, ids,
                            overrides=components(s, net, sample=True)).run()
        return record.allocations, record.total

    alloc_batch, total_batch = run([3, 4, 5])
    alloc_alone, total_alone = run([5])
    np.testing.assert_array_equal(alloc_batch[2], alloc_alone[0])
    assert total_batch[2] == total_alone[0]


def test_the_shipped_ita_is_trained_and_decides_otherwise_than_its_prior():
    # ata/weights/ata_hrl_a.pt records its training (docs/training.md, "The shipped weights"):
    # the aux phase on the ITA of a run of its own, which the three (a) files share
    from ata.training import WEIGHTS
    data = read_checkpoint(WEIGHTS / "ata_hrl_a.pt", "ata_hrl")
    assert data["trained"] == ["ita", "cond", "tr", "aux"]
    assert (data["init_from"], data["ita_from"]) == ("", "runs/r3/ita_a_1e-3/best.pt")
    assert data["counters"] == {"aux": 400, "status": 0, "ita": 0, "cond": 0, "ctr": 0,
                                "episodes": 0}
    for other in ("ata_hrl_wo_aux_a", "ata_hrl_wo_c_a"):
        model = read_checkpoint(WEIGHTS / f"{other}.pt", "ata_hrl")["model"]
        assert all(torch.equal(model[k], v) for k, v in data["model"].items()
                   if k.startswith("ita.")), other
    # with its learned part off it decides as an untrained network (the prior alone); on, it
    # changes the initial triples of 53, 56 and 53 of the 60 POIs of three held-out scenarios
    mission = str(WEIGHTS.parents[1] / "examples" / "missions" / "ata_hrl_a.toml")
    ids = np.arange(3) + 2 ** 40
    runs = []
    for flag in ("true", "false"):
        s = load_session(mission, ["components.condition='never'", f"attention.learned={flag}"])
        runs.append(Simulation(s.mission, s.registry, ids).run())
    untrained = AttentionITA(AttentionITA.Settings(), s.mission, net=ATAHRLNet(NetConfig()))
    prior = Simulation(s.mission, s.registry, ids, overrides={"initial": untrained}).run()
    np.testing.assert_array_equal(runs[1].allocations, prior.allocations)
    changed = (runs[0].allocations[:, 0] != runs[1].allocations[:, 0]).any(-1).sum(1)
    assert changed.tolist() == [53, 56, 53]


def test_no_shipped_file_carries_a_rule_and_wo_aux_differs_in_the_aux_module_alone():
    # the revision-3 fit of pi_C's rule lost at validation and was not kept (docs/training.md,
    # "Provenance", step 4): every file's rule is zero and off, and pi_C decides with its
    # network; w/o.AUX's networks are the full method's but for the aux module's tensors (which
    # w/o.AUX does not run)
    from ata.training import WEIGHTS
    for name in ("ata_hrl_a", "ata_hrl_b_ft", "ata_hrl_wo_aux_a", "ata_hrl_wo_aux_b_ft",
                 "ata_hrl_wo_c_a", "ata_hrl_wo_c_b_ft"):
        data = read_checkpoint(WEIGHTS / f"{name}.pt", "ata_hrl")
        assert data["format"] == 3 and data["counters"]["cond"] == 0, name
        model = data["model"]
        assert model["cond.rule.on"] == 0 and not model["cond.rule.weight"].any(), name
    for full, wo_aux in (("ata_hrl_a", "ata_hrl_wo_aux_a"), ("ata_hrl_b_ft", "ata_hrl_wo_aux_b_ft")):
        a = read_checkpoint(WEIGHTS / f"{full}.pt", "ata_hrl")["model"]
        b = read_checkpoint(WEIGHTS / f"{wo_aux}.pt", "ata_hrl")["model"]
        differ = {k for k in a if k not in b or not torch.equal(a[k], b[k])}
        assert {k.split(".")[0] for k in differ} == ({"fatigue", "latency", "status"}
                                                     if full == "ata_hrl_b_ft" else
                                                     {"fatigue", "latency"}), differ


@pytest.mark.slow
def test_shipped_ata_hrl_beats_greedy_on_held_out_scenarios_of_a_at_medium():
    # the suite's (a) medium cell (docs/RESULTS.md: +18.3 [+6.8, +30.0]): paired, 500 scenarios
    from ata.experiment.runner import run_mission
    from ata.training import WEIGHTS
    common = ["mission.scenarios=500", "mission.first_scenario=1099511627776",
              "mission.seed=0", "mission.setting='a'", "mission.uncertainty='medium'"]
    mission = str(WEIGHTS.parents[1] / "examples" / "missions" / "ata_hrl_a.toml")
    learned = run_mission(load_session(mission, common))
    greedy = run_mission(load_session(str(BASELINE_MISSION), common))
    diff = learned.total - greedy.total
    assert diff.mean() - 1.96 * diff.std(ddof=1) / np.sqrt(diff.size) > 0


# --- the auxiliary reconstruction -------------------------------------------------------------------

def test_reconstructors_beat_the_noisy_and_stale_observations(tmp_path):
    s = session("ata_hrl.aux_batches=2", "ata_hrl.aux_steps=150", "ata_hrl.batch_size=8",
                "ata_hrl.recon_hidden=16", "mission.uncertainty='high'",
                "ata_hrl.ita_steps=0", "ata_hrl.ctr_steps=0")
    trainer = build_trainer(s)
    from ata.training import TrainRun
    trainer.loop.run = TrainRun(tmp_path, s.mission.to_toml(), trainer.log_fields)
    before = trainer.aux.report()
    after = trainer.loop.run_phase(trainer.aux.phase())    # held-out scenarios, not trained on
    # the cVAE's fatigue is closer to the truth than the noisy observation (variance 0.2)
    assert after["fatigue_mse"] < 0.5 * after["fatigue_mse_observed"]
    # the stacked GRUs' robot rows are closer to the truth than the stale observed rows
    assert after["robots_mse"] < after["robots_mse_observed"]
    assert after["fatigue_mse"] < before["fatigue_mse"]


def test_the_aux_losses_are_the_cvae_loss_and_the_grus_squared_errors():
    from ata.plugins.ata_hrl.network import S_DIMS
    gen = torch.Generator().manual_seed(0)
    data = {"fatigue_in": torch.rand(20, 3, generator=gen),
            "fatigue_target": torch.rand(20, generator=gen)}
    for g in ("robots", "tasks"):
        data[f"{g}_in"] = torch.rand(6, 4, S_DIMS[g], generator=gen)
        data[f"{g}_target"] = torch.rand(6, 4, S_DIMS[g], generator=gen)
    trainer = build_trainer(session("ata_hrl.seed=3"))
    net = trainer.net
    with torch.no_grad():
        cvae, f_mse, lat_mse = trainer.aux.losses(data, sample=False)
        recon, mu, logvar = net.fatigue(*data["fatigue_in"].T, sample=False)
        err = {g: net.latency[g](data[f"{g}_in"])[0] - data[f"{g}_target"]
               for g in ("robots", "tasks")}
    # ||f - f_hat||^2 + 0.1 KL, averaged; the KL of N(mu, exp(logvar)) against N(0, 1)
    kl = 0.5 * (mu ** 2 + logvar.exp() - 1 - logvar).sum(-1)
    want = ((recon - data["fatigue_target"]) ** 2 + 0.1 * kl).mean()
    assert torch.allclose(cvae, want, rtol=1e-6)
    assert torch.allclose(f_mse, ((recon - data["fatigue_target"]) ** 2).mean())
    assert torch.allclose(lat_mse, sum((e * e).mean() for e in err.values()))


def test_the_full_replan_is_taken_only_where_the_model_expects_it_to_be_worth_more():
    # replan_in_full: pi_TR's per-POI reallocation or a full re-plan decoded afresh, per
    # scenario, whichever greedy's model of worth prefers (net of the re-tasking cost)
    from ata.model.plan import plan_start
    from ata.model.retask import retask_cost, worth
    s = session()
    torch.manual_seed(0)
    net = ATAHRLNet(NetConfig(d_model=16, hidden=16, recon_hidden=8))
    seen = []

    class Spy(CTRPolicy):
        def _or_full_replan(self, sub, replan, alloc):
            out, take = super()._or_full_replan(sub, replan, alloc)
            at, price = plan_start(sub), self.greedy.s.human_time_cost
            value = [worth(sub, at, a, sub.reallocatable, retask_cost(sub), price)
                     for a in (alloc, out)]
            seen.append((value, take, alloc, out, sub.reallocatable))
            return out, take

    def run(full):
        over = components(s, net)
        ctr = Spy(CTRPolicy.Settings(replan_in_full=True), s.mission, net=net) if full else \
            CTRPolicy(CTRPolicy.Settings(replan_in_full=False), s.mission, net=net)
        over["condition"] = over["reallocation"] = ctr
        return Simulation(s.mission, s.registry, list(range(8)), overrides=over).run()

    plain, full = run(False), run(True)
    assert seen and any(take.any() for _, take, *_ in seen)
    for (w_alloc, w_out), take, alloc, out, open_ in seen:
        np.testing.assert_array_less(w_alloc[take], w_out[take])      # taken: worth more
        same = (alloc.robot == out.robot) & (alloc.navigator == out.navigator) & \
            (alloc.classifier == out.classifier)
        assert same[~take].all()                                       # not taken: unchanged
        assert same[~open_].all()                                      # closed POIs: unchanged
    assert not np.array_equal(plain.allocations, full.allocations)


def test_one_pass_and_the_deciding_episodes_alone_decode_as_every_episode_apart(monkeypatch):
    # taking the mode, pi_TR's reallocation and the full re-plan decoded in one pass, on the
    # episodes still deciding alone: as decoded apart, every episode to the end
    from ata.plugins.ata_hrl import decode as D
    s = session()
    torch.manual_seed(0)
    net = ATAHRLNet(NetConfig(d_model=16, hidden=16, recon_hidden=8))
    with torch.no_grad():              # a learned part that is not zero
        [p.add_(0.05 * torch.randn_like(p)) for p in net.parameters()]

    def run(apart):
        over = components(s, net)
        if apart:                      # not the argmax chooser itself: two passes
            over["reallocation"].sampler = lambda kind, logits: D.argmax_chooser(kind, logits)
        return Simulation(s.mission, s.registry, list(range(8)), overrides=over).run()

    taken, take = [], Decoder.take
    monkeypatch.setattr(Decoder, "take", lambda dec, rows: taken.append(rows) or take(dec, rows))
    with monkeypatch.context() as m:                 # decoded step by step
        m.setattr(D.fused, "fits", lambda dec: False)
        fast = run(False)
    assert taken                                      # episodes were dropped on the way
    compiled = run(False)                             # the compiled whole decode
    monkeypatch.setattr(D, "SHRINK", 0.0)            # never drop a finished episode
    slow = run(True)
    for got in (fast, compiled):
        assert got.allocations.size and np.array_equal(got.allocations, slow.allocations)
        np.testing.assert_array_equal(got.r_perf, slow.r_perf)


def test_aux_reconstructs_only_the_parts_it_is_given():
    from ata.plugins.ata_hrl.features import seen_state, state_features
    s = load_session(str(BASELINE_MISSION), ["mission.uncertainty='high'"])
    net = ATAHRLNet(NetConfig(d_model=16, hidden=16, recon_hidden=8))
    seen = {}
    for parts in (["fatigue", "robots", "tasks"], ["fatigue"], ["robots"]):
        aux = AuxReconstructor(AuxReconstructor.Settings(parts=parts), s.mission, net=net)
        sim = Simulation(s.mission, s.registry, [0, 1], overrides={"reconstructors": aux})
        sim.reset()
        for _ in range(3):
            ctx = sim.begin_epoch()
            sim.end_epoch(*sim.decide(ctx))
        assert sorted(ctx.reconstructed) == sorted(f"aux_{p}" for p in parts)
        seen[parts[0] if len(parts) == 1 else "all"] = (seen_state(ctx),
                                                       state_features(ctx.observed))
    got, raw = seen["fatigue"]
    np.testing.assert_array_equal(got["robots"], raw["robots"])      # as observed
    np.testing.assert_array_equal(got["tasks"], raw["tasks"])
    assert not np.array_equal(got["humans"], raw["humans"])          # fatigue reconstructed
    got, raw = seen["robots"]
    np.testing.assert_array_equal(got["humans"], raw["humans"])
    assert not np.array_equal(got["robots"], raw["robots"])
    # the same scenarios and policy: what the full reconstruction gives the robots
    np.testing.assert_allclose(got["robots"], seen["all"][0]["robots"])
    with pytest.raises(MissionError, match="parts"):
        load_session(str(training_mission_for(["ctr", "aux"])), [*TINY, "aux.parts=['speed']"])


# --- the aux module's status head --------------------------------------------------------------------

def test_status_head_trains_to_find_hidden_captures(tmp_path):
    """Fitted on teacher rollouts at high uncertainty, the head finds, on held-out rollouts,
    some of the captures the latency hides, and takes fewer open POIs wrongly as captured than
    it finds; before training it finds less."""
    s = session("ata_hrl.batch_size=8", "ata_hrl.status_batches=3",
                "ata_hrl.status_steps=400", "ata_hrl.status_hidden=32",
                "ata_hrl.ita_steps=0", "ata_hrl.ctr_steps=0", "ata_hrl.aux_steps=0")
    trainer = build_trainer(s)
    from ata.training import TrainRun
    trainer.loop.run = TrainRun(tmp_path, s.mission.to_toml(), trainer.log_fields)
    before = trainer.status.report()
    after = trainer.loop.run_phase(trainer.status.phase())
    assert after["status_captured_hidden"] > 0
    assert after["status_captured_found"] > after["status_captured_wrong"]
    assert after["status_captured_found"] - after["status_captured_wrong"] \
        > before["status_captured_found"] - before["status_captured_wrong"]
    assert trainer.counters["status"] == 400


def test_status_guesses_reach_the_plan_start_and_the_policy_view():
    """A POI guessed committed is not reallocatable to the policies (`as_seen`) and not open in
    the plan start; one guessed captured is not open either; without guesses nothing changes."""
    from ata.model.plan import as_seen, plan_start
    s = load_session(str(BASELINE_MISSION), TINY[:5] + ["mission.uncertainty='high'"])
    sim = Simulation(s.mission, s.registry, [0, 1])
    sim.reset()
    sim.end_epoch(*sim.decide(sim.begin_epoch()))
    ctx = sim.begin_epoch()
    assert as_seen(ctx) is ctx
    base = plan_start(ctx)
    B, P = ctx.reallocatable.shape
    committed = np.zeros((B, P, 1))
    captured = np.zeros((B, P, 1))
    open_now = np.argwhere(base.open)
    (b1, p1), (b2, p2) = open_now[0], open_now[-1]
    committed[b1, p1] = 1.0
    captured[b2, p2] = 1.0
    ctx.reconstructed.update(committed_guess=committed, captured_guess=captured)
    seen = as_seen(ctx)
    assert not seen.reallocatable[b1, p1]
    assert (seen.reallocatable | (committed[..., 0] > 0.5) == ctx.reallocatable).all()
    start = plan_start(ctx)
    assert not start.open[b1, p1] and not start.open[b2, p2]
    changed = base.open & ~start.open
    assert changed.sum() == 2


def test_status_head_is_optional_and_checkpoints_without_it_serve(tmp_path):
    """A checkpoint without a head (status_hidden = 0, as the (a) weights) loads, and its aux
    component writes no guesses; its ITA serves a training with a head (ita_from)."""
    no_head = train(session("ata_hrl.status_hidden=0", "ata_hrl.ctr_steps=0"),
                    tmp_path / "no_head")
    assert not hasattr(no_head.net, "status")
    best = tmp_path / "no_head" / "best.pt"
    s = load_session(str(tmp_path / "no_head" / "mission.resolved.toml"),
                     ["mission.uncertainty='high'", f"aux.checkpoint='{best}'",
                      f"attention.checkpoint='{best}'", f"ctr.checkpoint='{best}'"])
    sim = Simulation(s.mission, s.registry, [0, 1])
    sim.reset()
    for _ in range(3):
        ctx = sim.begin_epoch()
        assert "captured_guess" not in ctx.reconstructed and "aux_fatigue" in ctx.reconstructed
        sim.end_epoch(*sim.decide(ctx))
    with_head = train(session(f"ata_hrl.ita_from='{best}'", "ata_hrl.ctr_steps=0"),
                      tmp_path / "with_head")
    assert hasattr(with_head.net, "status")
    taken = read_checkpoint(best, "ata_hrl")["model"]
    for k, v in with_head.net.ita.state_dict().items():
        assert torch.equal(v, taken[f"ita.{k}"]), k
    s = load_session(str(tmp_path / "with_head" / "mission.resolved.toml"),
                     ["mission.uncertainty='high'"]
                     + [f"{c}.checkpoint='{tmp_path / 'with_head' / 'best.pt'}'"
                        for c in ("aux", "attention", "ctr")])
    sim = Simulation(s.mission, s.registry, [0, 1])
    sim.reset()
    sim.end_epoch(*sim.decide(sim.begin_epoch()))
    ctx = sim.begin_epoch()
    assert ctx.reconstructed["captured_guess"].shape == ctx.reallocatable.shape + (1,)
