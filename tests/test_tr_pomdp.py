"""TR-POMDP and AtRL-TR: partial observations, joint actions, DQN training, checkpoints."""

import csv
import tomllib

import numpy as np
import pytest
import torch

from _support import train, whole_and_killed
from ata.core.kernel import Simulation
from ata.session import build_trainer, load_session, training_mission_for
from ata.experiment.runner import run_mission
from ata.core.state import Allocation
from ata.plugins.conditions import Always
from ata.model.agents import AgentConfig, AgentInputs, apply_actions, observe
from ata.plugins.tr_pomdp import agents as dqn
from ata.plugins.tr_pomdp.policy import TRPOMDPPolicy
from ata.plugins.tr_pomdp.trainer import Replay
from ata.training import CheckpointError, WEIGHTS, read_checkpoint

TINY = ["tr_pomdp.batch_size=4", "tr_pomdp.eval_scenarios=4", "tr_pomdp.steps=3", "tr_pomdp.updates=2",
        "tr_pomdp.minibatch=32", "tr_pomdp.eval_every=1", "tr_pomdp.checkpoint_every=1", "tr_pomdp.buffer=2000",
        "tr_pomdp.target_sync=2", "tr_pomdp.eps_decay_steps=2", "tr_pomdp.hidden=16", "tr_pomdp.threads=1"]
EXAMPLES = WEIGHTS.parents[1] / "examples" / "missions"


def session(*extra, plugins=("trp",)):
    return load_session(str(training_mission_for(list(plugins))), [*TINY, *extra])


def context(setting="a", epochs=3, ids=(0, 1, 2)):
    """A decision context a few epochs into an episode (random ITA, random agents)."""
    s = session(f"mission.setting='{setting}'")
    nets = dqn.AgentNets(AgentConfig(k=4, hidden=16))
    agents = TRPOMDPPolicy(TRPOMDPPolicy.Settings(), s.mission, nets=nets, epsilon=1.0)
    sim = Simulation(s.mission, s.registry, list(ids),
                     overrides={"reallocation": agents, "condition": Always(None, s.mission)})
    sim.reset()
    for _ in range(epochs):
        sim.step_epoch()
    return sim.last_context


def _set(table, row_of_entity, column, value):
    # the context's tables are read-only: a writable copy in their place
    table.features = np.array(table.features)
    table.features[:, row_of_entity, table.index(column)] = value


@pytest.mark.parametrize("setting", ["a", "b"])
def test_an_agent_sees_only_its_own_private_state(setting):
    ctx = context(setting)
    cfg = AgentConfig(k=4)
    base = observe(ctx, cfg)
    H, R = ctx.sizes.humans, ctx.sizes.robots
    assert base.robot_obs.shape == (3, R, cfg.robot_dim)
    assert base.human_obs.shape == (3, H, cfg.human_dim)
    # change human 0's and robot 0's private state: their observed rows, human 0's abilities
    hs, rs = ctx.observed["humans"], ctx.observed["robots"]
    for col, val in (("fatigue", 0.123), ("working_time", 2.5), ("idleness", 0.01), ("sa", 0.3)):
        _set(hs, 0, col, val)
    for col, val in (("cognitive", 0.9), ("expertise", 0.1), ("skill", 2.0)):
        _set(ctx.inherent["humans"], 0, col, val)
    for col, val in (("x", 0.97), ("y", 0.03), ("working", 0.0), ("idleness", 0.5),
                     ("target", 7)):
        _set(rs, 0, col, val)
    # (the roster, which kind of robot each one is, is public: every member knows it)
    after = observe(ctx, cfg)
    # every other agent's input is unchanged, bit for bit...
    assert np.array_equal(after.human_obs[:, 1:], base.human_obs[:, 1:])
    assert np.array_equal(after.human_legal[:, 1:], base.human_legal[:, 1:])
    assert np.array_equal(after.robot_obs[:, 1:], base.robot_obs[:, 1:])
    assert np.array_equal(after.robot_legal[:, 1:], base.robot_legal[:, 1:])
    # ...while the changed agents' own inputs did change (the test can fail)
    assert not np.array_equal(after.human_obs[:, 0], base.human_obs[:, 0])
    assert not np.array_equal(after.robot_obs[:, 0], base.robot_obs[:, 0])
    # a robot observed down may only keep
    assert not after.robot_legal[:, 0, 1:].any()


def test_observation_layout_and_legal_actions():
    ctx = context()
    cfg = AgentConfig(k=4)
    inp = observe(ctx, cfg)
    prev, movable = ctx.previous, ctx.reallocatable
    B, R, K = inp.robot_cand.shape
    rx, ry = ctx.observed["robots"].col("x"), ctx.observed["robots"].col("y")
    tx, ty = ctx.inherent["tasks"].col("x"), ctx.inherent["tasks"].col("y")
    for b in range(B):
        for r in range(R):
            ok = movable[b] & (prev.robot[b] != r)
            d = np.where(ok, np.hypot(tx[b] - rx[b, r], ty[b] - ry[b, r]), np.inf)
            n = min(K, int(ok.sum()))
            assert sorted(inp.robot_cand[b, r, :n]) == sorted(np.argsort(d, kind="stable")[:n])
    # held roles are roles the human really holds on movable POIs
    H = ctx.sizes.humans
    valid = inp.human_legal[..., 1 + 2 * K:]
    b, h, k = np.nonzero(valid)
    p = inp.human_held[b, h, k]
    assert ((prev.classifier[b, p] == h) | (prev.navigator[b, p] == h)).all()
    assert movable[b, p].all()
    # navigation actions only for highly skilled humans
    high = ctx.inherent["humans"].col("skill") > 1.5
    assert not inp.human_legal[..., 1 + K:1 + 2 * K][~high].any()
    assert inp.human_obs.shape[1] == H


def test_joint_action_resolves_conflicts_by_q():
    P, K = 5, 2
    prev = Allocation(np.zeros((1, P), np.int64), np.full((1, P), -1), np.full((1, P), -1))
    prev.classifier[0, 3] = 1
    inp = AgentInputs(
        robot_obs=None, robot_legal=None, human_obs=None, human_legal=None,
        robot_cand=np.array([[[2, 4], [2, 1]]]),                # robots 0, 1 both eye POI 2
        human_new=np.array([[[0, 1], [0, 4]]]), human_held=np.array([[[0, 0], [3, 0]]]),
        human_load=None, robot_load=None)
    alloc = apply_actions(
        prev, inp, robot_a=np.array([[1, 1]]), robot_q=np.array([[0.5, 0.9]]),
        human_a=np.array([[1, 2 * K + 1]]), human_q=np.array([[0.1, 0.2]]), k=K)
    assert alloc.robot[0, 2] == 1                  # the higher Q wins
    assert alloc.classifier[0, 3] == -1            # human 1 released its classification
    assert alloc.classifier[0, 0] == 0             # human 0 took POI 0
    # both humans claim POI 0's classification: the higher Q wins
    alloc = apply_actions(prev, inp, np.zeros((1, 2), int), np.zeros((1, 2)),
                              np.array([[1, 1]]), np.array([[0.3, 0.7]]), K)
    assert alloc.classifier[0, 0] == 1 and (alloc.robot == prev.robot).all()


def test_replay_buffer_is_a_ring():
    buf = Replay(5, 2, 3)
    for i in range(3):
        buf.add(obs=np.full((2, 2), i), action=np.array([i, i]), reward=np.array([i, i]),
                next_obs=np.zeros((2, 2)), next_legal=np.ones((2, 3), bool),
                done=np.zeros(2))
    assert buf.size == 5 and buf.pos == 1
    assert buf.data["action"].tolist() == [2, 0, 1, 1, 2]
    state = buf.state()
    other = Replay(5, 2, 3)
    other.load(state)
    assert torch.equal(other.data["obs"], buf.data["obs"]) and other.pos == 1


def tiny_ita(tmp_path):
    """A checkpoint of ATA-HRL whose ITA (untrained: greedy's prior) AtRL-TR starts from."""
    s = load_session(str(training_mission_for(["ita"])),
                     ["ata_hrl.ita_steps=0", "ata_hrl.d_model=16", "ata_hrl.hidden=16",
                      "ata_hrl.eval_scenarios=2"])
    train(s, tmp_path / "ita")
    return tmp_path / "ita" / "best.pt"


@pytest.mark.parametrize("plugins", [("trp",), ("ita", "trp")])
def test_training_smoke_and_checkpoint_round_trip(tmp_path, plugins):
    extra = [f"attention.checkpoint='{tiny_ita(tmp_path)}'"] if "ita" in plugins else []
    s = session(*extra, plugins=plugins)
    assert s.mission.slots.reallocation == "tr_pomdp" and s.mission.slots.trainer == "tr_pomdp"
    assert s.mission.slots.initial == ("attention" if "ita" in plugins else "random")
    out = tmp_path / "run"
    trainer = train(s, out)
    assert trainer.report["counters"]["dqn"] == 3
    rows = [r.split(",") for r in (out / "log.csv").read_text().splitlines()]
    dqn_rows = [r for r in rows if r[0] == "dqn"]
    assert len(dqn_rows) == 3 and all(np.isfinite(float(r[4])) for r in dqn_rows)
    data = torch.load(out / "checkpoint.pt", weights_only=True)
    assert data["kind"] == "tr_pomdp"
    assert set(data) >= {"agents", "agents_target", "agents_optimizer", "agents_config",
                         "replay", "rng", "counters", "mission", "scenario_ranges"}
    assert data["replay"]["robot"]["size"] > 0
    best = read_checkpoint(out / "best.pt", "tr_pomdp")
    assert "replay" not in best and "agents" in best
    # the trained agents run as a mission component from their checkpoint file
    run = load_session(str(out / "mission.resolved.toml"),
                       ["mission.scenarios=3", f"tr_pomdp.checkpoint='{out / 'best.pt'}'"])
    assert_runs_the_agents_of(run, best["agents"])


def assert_runs_the_agents_of(session, agents: dict) -> None:
    """The mission's reallocation component holds exactly these weights, and its agents act:
    they change the allocation in force, and the same seed gives the same decisions."""
    sim = Simulation(session.mission, session.registry, [0, 1])
    policy = sim.slot_component["reallocation"]
    held = policy.nets.state_dict()
    assert held.keys() == agents.keys()
    for key, value in agents.items():
        assert torch.equal(held[key], value), key
    record = sim.run()
    changed = (record.allocations[:, 1:] != record.allocations[:, :-1]).any(axis=(2, 3))
    assert changed.any(), "the agents never changed the allocation"
    again = Simulation(session.mission, session.registry, [0, 1]).run()
    np.testing.assert_array_equal(record.allocations, again.allocations)


def test_the_agents_learn(tmp_path):
    # 3 steps of 2 gradient steps each: 6 Adam steps on every parameter, the target networks
    # synced every 2 (so, after the last, equal to the online ones), and every tensor moved
    # from the seed's initialisation
    trainer = train(session(), tmp_path)
    learner = trainer.agents
    assert learner.updates == 6
    assert [int(st["step"]) for st in learner.opt.state_dict()["state"].values()] == [6] * 12
    for k, v in learner.nets.state_dict().items():
        assert torch.equal(learner.target.state_dict()[k], v), k
    torch.manual_seed(12345)                # the trainer's seed: the agents before training
    fresh = dqn.AgentNets(learner.cfg)
    assert all(not torch.equal(a, b) for a, b in zip(fresh.parameters(),
                                                       learner.nets.parameters()))


@pytest.mark.parametrize("select, column", [("drawn", "eval_score"),
                                             ("expected", "eval_expected")])
def test_best_pt_follows_the_validation_score_select_names(tmp_path, select, column):
    # every step validated: both scores logged, best.pt the step of the best one `select` names
    train(session(f"tr_pomdp.select='{select}'", "tr_pomdp.steps=4"), tmp_path)
    rows = [r for r in csv.DictReader((tmp_path / "log.csv").open()) if r["eval_score"]]
    assert [r["step"] for r in rows] == ["1", "2", "3", "4"]
    scores = {k: [float(r[k]) for r in rows] for k in ("eval_score", "eval_expected")}
    assert scores["eval_score"] != scores["eval_expected"]
    best = read_checkpoint(tmp_path / "best.pt", "tr_pomdp")
    assert best["best_eval"] == pytest.approx(max(scores[column]), abs=0.006)
    assert best["counters"]["dqn"] == 1 + int(np.argmax(scores[column]))


def test_resume_after_kill_matches_an_uninterrupted_run(tmp_path):
    whole, resumed = whole_and_killed(session(), tmp_path, "dqn", "2")
    assert resumed.counters == whole.counters
    for (k, a), (_, b) in zip(whole.agents.nets.state_dict().items(),
                              resumed.agents.nets.state_dict().items()):
        assert torch.equal(a, b), k


def test_weight_averaging_leaves_the_training_alone_and_tracks_the_online_agents(tmp_path):
    plain = train(session(), tmp_path / "plain").agents
    averaged = train(session("tr_pomdp.average=0.5"), tmp_path / "avg").agents
    assert plain.avg is None
    for (k, a), (_, b) in zip(plain.nets.state_dict().items(),
                              averaged.nets.state_dict().items()):
        assert torch.equal(a, b), k                      # the online agents: the same bits
    assert any(not torch.equal(a, b) for a, b in zip(averaged.avg.parameters(),
                                                       averaged.nets.parameters()))
    close = train(session("tr_pomdp.average=1e-6"), tmp_path / "close").agents
    for a, b in zip(close.avg.parameters(), close.nets.parameters()):
        torch.testing.assert_close(a, b, atol=1e-4, rtol=0)   # a weight near 0 follows them


def test_best_pt_keeps_the_higher_of_the_online_and_averaged_agents(tmp_path):
    trainer = train(session("tr_pomdp.average=0.5", "tr_pomdp.select='expected'",
                            "tr_pomdp.steps=4"), tmp_path)
    rows = [r for r in csv.DictReader((tmp_path / "log.csv").open()) if r["eval_score"]]
    online = [float(r["eval_expected"]) for r in rows]
    avg = [float(r["eval_avg_expected"]) for r in rows]
    assert len(online) == len(avg) == 4 and online != avg
    best = read_checkpoint(tmp_path / "best.pt", "tr_pomdp")
    assert best["best_eval"] == pytest.approx(max(online + avg), abs=0.006)
    assert best["agents_source"] == ("average" if max(avg) > max(online) else "online")
    assert "agents_avg" not in best and "agents_avg" in read_checkpoint(
        tmp_path / "checkpoint.pt", "tr_pomdp")
    # the agents best.pt holds play the validation score it records
    probe = build_trainer(session("tr_pomdp.select='expected'"))
    probe.agents.nets.load_state_dict(best["agents"])
    score, _ = probe.validate()
    assert score == pytest.approx(best["best_eval"], abs=0.006)
    assert trainer.report["best_eval"] == pytest.approx(best["best_eval"])


def test_resume_with_weight_averaging_matches_an_uninterrupted_run(tmp_path):
    whole, resumed = whole_and_killed(session("tr_pomdp.average=0.5"), tmp_path, "dqn", "2")
    for a, b in zip(whole.agents.avg.parameters(), resumed.agents.avg.parameters()):
        assert torch.equal(a, b)


def test_cli_train_trp_and_bad_checkpoint(cli, tmp_path):
    out = tmp_path / "run"
    res = cli("train", "--plugins", "trp", "--out", out, "--quiet",
              *[x for kv in TINY for x in ("--set", kv)])
    assert res.exit_code == 0, res.output
    assert (out / "best.pt").exists() and "dqn" in (out / "log.csv").read_text()
    # a mission file given without --plugins trains with the plugins it names, no others
    mission_file = training_mission_for(["trp"])
    res = cli("train", str(mission_file), "--out", tmp_path / "file", "--quiet",
              *[x for kv in TINY for x in ("--set", kv)])
    assert res.exit_code == 0, res.output
    resolved = tomllib.loads((tmp_path / "file" / "mission.resolved.toml").read_text())
    assert resolved["mission"]["plugins"] == ["trp"]
    res = cli("train", "--plugins", "trp,ctr")
    assert res.exit_code == 2 and "no built-in training mission" in res.output
    # a file that is no checkpoint, and an ATA-HRL checkpoint, are refused with clear messages
    (tmp_path / "bad.pt").write_bytes(b"not a checkpoint")
    with pytest.raises(CheckpointError, match="cannot be read"):
        TRPOMDPPolicy(TRPOMDPPolicy.Settings(checkpoint=str(tmp_path / "bad.pt")), None)
    with pytest.raises(CheckpointError, match="not of 'tr_pomdp'"):
        TRPOMDPPolicy(TRPOMDPPolicy.Settings(checkpoint=str(tiny_ita(tmp_path))), None)


@pytest.mark.parametrize("name, steps", [("tr_pomdp_a", 1750), ("atrl_tr_a", 2000)])
def test_shipped_weights_are_the_best_step_of_a_run_that_resumes(tmp_path, name, steps):
    # the best validation of the run each default is (step 1750 of TR-POMDP's recipe seed 1,
    # 2000 of AtRL-TR's, its averaged agents), without the replay buffers; with the training
    # mission it records, the file is a run folder whose trainer takes its agents, optimiser,
    # generators and counters
    data = read_checkpoint(WEIGHTS / f"{name}.pt", "tr_pomdp")
    assert data["counters"] == {"dqn": steps, "episodes": 16 * steps} and "replay" not in data
    assert data["trainer"] == "tr_pomdp"
    (tmp_path / "mission.resolved.toml").write_text(data["mission"])
    # AtRL-TR's ITA was read from a run folder of its time (not shipped), whose ITA is the one
    # builtin:ata_hrl_s1_a carries
    ita = tomllib.loads(data["mission"]).get("attention", {}).get("checkpoint", "")
    unshipped = ["attention.checkpoint='builtin:ata_hrl_s1_a'"] if ita.startswith("runs/") else []
    session = load_session(str(tmp_path / "mission.resolved.toml"), unshipped)
    assert session.mission.settings.setting == "a" and session.mission.slots.trainer == "tr_pomdp"
    trainer = build_trainer(session)
    trainer.load(WEIGHTS / f"{name}.pt")
    assert trainer.counters == data["counters"] and trainer.agents.updates == 32 * steps
    for k, v in data["agents"].items():
        assert torch.equal(trainer.agents.nets.state_dict()[k], v), k


@pytest.mark.parametrize("name", ["tr_pomdp_a", "tr_pomdp_b", "atrl_tr_a", "atrl_tr_b"])
def test_example_missions_run_the_shipped_agents(name):
    # setting (b) runs the agents trained on (a): they act per member, whatever the team size
    path = EXAMPLES / f"{name}.toml"
    assert tomllib.loads(path.read_text())["tr_pomdp"]["checkpoint"] == f"builtin:{name[:-1]}a"
    shipped = read_checkpoint(WEIGHTS / f"{name[:-1]}a.pt", "tr_pomdp")["agents"]
    assert_runs_the_agents_of(load_session(str(path), ["mission.scenarios=2"]), shipped)


@pytest.mark.slow
@pytest.mark.parametrize("name", ["tr_pomdp_a", "atrl_tr_a"])
def test_shipped_agents_beat_random_on_held_out_scenarios(name):
    common = ["mission.scenarios=200", "mission.first_scenario=1099511627776"]
    learned = run_mission(load_session(str(EXAMPLES / f"{name}.toml"), common))
    random = run_mission(load_session(str(EXAMPLES / "random_baseline.toml"), common))
    diff = learned.total - random.total
    assert diff.mean() - 2 * diff.std(ddof=1) / np.sqrt(diff.size) > 0
