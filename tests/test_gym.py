"""The Gymnasium and PettingZoo adapters (ata.gym): the libraries' own checkers, the same
episodes as `ata run` when the agent decides as the mission's components would, the action
masks, the errors, and the kernel's split epoch they rest on.

A small custom team (2 humans, 3 robots, 6 POIs, 10 epochs) keeps every test to seconds.
"""

from __future__ import annotations

import subprocess
import sys
import warnings

import numpy as np
import pytest

gym = pytest.importorskip("gymnasium")
pytest.importorskip("pettingzoo")

import ata.gym  # noqa: E402  (after the skips: it needs gymnasium)
from ata.core.kernel import Simulation  # noqa: E402
from ata.session import load_session
from ata.experiment.runner import run_mission  # noqa: E402
from ata.gym import sample_masked  # noqa: E402

H, R, P, T = 2, 3, 6, 10
SCENARIOS, SEED = 6, 11
MISSION = f"""\
[mission]
name = "gym-test"
setting = "custom"
humans = {H}
robots = {R}
tasks = {P}
horizon_s = {60 * T}
seed = {SEED}
scenarios = {SCENARIOS}
uncertainty = "high"

[components]
initial = "greedy"
condition = "on_event"
reallocation = "greedy"
"""
METHODS = {
    "greedy, on events": [],
    "greedy, every epoch": ["components.condition='always'"],
    "random, every epoch": ["components.initial='random'", "components.condition='always'",
                            "components.reallocation='random'"],
}


@pytest.fixture(scope="module")
def mission_file(tmp_path_factory):
    path = tmp_path_factory.mktemp("gym") / "team.toml"
    path.write_text(MISSION)
    return str(path)


@pytest.fixture(scope="module")
def session(mission_file):
    return load_session(mission_file)


def offsets(nvec):
    return np.concatenate([[0], np.cumsum(nvec)[:-1]])


def allowed(mask, nvec, action):
    """Whether every dimension's choice is one the flat mask allows."""
    return bool(np.take_along_axis(np.asarray(mask), offsets(nvec) + np.asarray(action),
                                   axis=-1).all())


def mask_of(mask, nvec, index):
    """The segment of the flat mask that belongs to one dimension."""
    start = offsets(nvec)[index]
    return np.asarray(mask)[start:start + nvec[index]]


# --- packaging -----------------------------------------------------------------------------------

def test_ata_and_ata_run_do_not_import_gymnasium(mission_file, tmp_path):
    code = ("import sys\n"
            "from typer.testing import CliRunner\n"
            "from ata.cli import app\n"
            f"r = CliRunner().invoke(app, ['run', {mission_file!r}, '-q', '--out', "
            f"{str(tmp_path / 'out')!r}])\n"
            "assert r.exit_code == 0, r.output\n"
            "print(sorted(m for m in sys.modules if m.split('.')[0] in "
            "('gymnasium', 'pettingzoo', 'ata')))\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout
    assert "'ata.core.kernel'" in out            # it did run
    assert "gymnasium" not in out and "pettingzoo" not in out and "ata.gym" not in out


# --- the single environment ----------------------------------------------------------------------

def test_gymnasium_env_checker_passes(mission_file):
    from gymnasium.utils.env_checker import check_env

    env = ata.gym.make(mission_file)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        check_env(env, skip_render_check=True)
    # the only advice: the tables' values are unbounded (injected noise is)
    assert all("infinity" in str(w.message) for w in caught), [str(w.message) for w in caught]


def test_registered_id_makes_the_single_and_the_vector_environment(mission_file):
    env = gym.make(ata.gym.ENV_ID, mission=mission_file)
    assert isinstance(env.unwrapped, ata.gym.CentralisedEnv)
    obs, info = env.reset(seed=1)
    assert obs in env.observation_space
    np.testing.assert_array_equal(env.get_wrapper_attr("action_masks")(), info["action_mask"])
    vec = gym.make_vec(ata.gym.ENV_ID, num_envs=3, mission=mission_file)
    assert isinstance(vec, ata.gym.CentralisedVectorEnv) and vec.num_envs == 3
    obs, info = vec.reset(seed=1)
    assert obs in vec.observation_space
    assert info["action_mask"].shape == (3, sum(vec.single_action_space.nvec))


def test_spaces_follow_the_team_and_the_tables(session):
    env = ata.gym.make(session)
    nvec = env.action_space.nvec
    assert nvec.tolist() == [2] + [R, 1 + H, 1 + H] * P
    obs, info = env.reset()
    assert info["action_mask"].shape == (nvec.sum(),) and info["action_mask"].dtype == bool
    assert env.columns["observed_humans"] == ("working_time", "fatigue", "idleness", "sa")
    assert env.columns["inherent_tasks"] == ("x", "y", "kind", "difficulty", "points")
    for key, space in env.observation_space.spaces.items():
        assert obs[key].shape == space.shape and obs[key].dtype == np.float32, key
    assert obs["observed_robots"].shape == (R, 5) and obs["allocation"].shape == (P, 3)
    assert (obs["allocation"] == -1).all() and obs["epoch"][0] == 0


@pytest.mark.parametrize("uncertainty", ["high", "none"])
def test_observations_show_the_observed_state_never_the_truth(mission_file, uncertainty):
    """The fatigue the agent sees is that of the observed S: at high uncertainty it is noisy,
    off the true F_f of the working time (at spread 0 every human is on the population line, a
    function of the working time, which is seen without noise); with no uncertainty it is the
    true one. The exposed context holds no true state."""
    from ata.model import tables

    env = ata.gym.make(mission_file, overrides=[f"mission.uncertainty='{uncertainty}'",
                                                "human.fatigue_spread=0"])
    obs, _ = env.reset(seed=3)
    hours, fatigue = (env.columns["observed_humans"].index(c) for c in ("working_time", "fatigue"))
    for _ in range(T):
        ctx = env.context
        assert not hasattr(ctx, "truth")
        for group in ("humans", "robots", "tasks"):
            np.testing.assert_array_equal(obs[f"observed_{group}"],
                                          ctx.observed[group].features[0].astype(np.float32))
            np.testing.assert_array_equal(obs[f"inherent_{group}"],
                                          ctx.inherent[group].features[0].astype(np.float32))
        true_fatigue = tables.fatigue(obs["observed_humans"][:, hours].astype(float), 0.4)
        off = np.abs(obs["observed_humans"][:, fatigue] - true_fatigue).max()
        assert off > 1e-3 if uncertainty == "high" else off < 1e-6
        obs, *_ = env.step(env.mission_action())


# --- the same episodes as `ata run` --------------------------------------------------------------

@pytest.mark.parametrize("method", list(METHODS))
def test_mission_actions_give_the_episodes_of_ata_run(mission_file, method):
    """Driving the environments with the actions of the mission's own components gives, per
    scenario, exactly the totals `ata run` gives: one scenario at a time, all at once in one
    vector environment, and two episodes of a smaller one (autoreset moves to the next ids)."""
    overrides = METHODS[method]
    expected = run_mission(load_session(mission_file, overrides))
    assert expected.scenario.tolist() == list(range(SCENARIOS))

    env = ata.gym.make(mission_file, overrides=overrides)
    env.reset(seed=SEED)
    for i in range(SCENARIOS):
        if i:
            env.reset()
        total, steps, terminated = 0.0, 0, False
        while not terminated:
            action = env.mission_action()
            assert allowed(env.action_masks(), env.action_space.nvec, action)
            _, reward, terminated, truncated, info = env.step(action)
            total, steps = total + reward, steps + 1
            assert not truncated
        assert steps == T and info["scenario"] == i
        assert total == info["total"] == expected.total[i], i
        assert info["upper_bound"] == expected.upper_bound[i]

    for num_envs in (SCENARIOS, SCENARIOS // 2):
        vec = ata.gym.make_vec(mission_file, num_envs=num_envs, overrides=overrides)
        _, info = vec.reset(seed=SEED)
        totals = []
        for _ in range(SCENARIOS // num_envs):
            total = np.zeros(num_envs)
            for k in range(T):
                actions = vec.mission_action()
                assert allowed(info["action_mask"], vec.single_action_space.nvec, actions)
                _, reward, terminated, truncated, info = vec.step(actions)
                total += reward
                assert terminated.all() == (k == T - 1) and not truncated.any()
            np.testing.assert_array_equal(total, info["total"])
            totals.append(total)
            # next-step autoreset: the actions are ignored, the next scenarios begin
            obs, reward, terminated, truncated, info = vec.step(vec.action_space.sample())
            assert (reward == 0).all() and not terminated.any() and (obs["epoch"] == 0).all()
        np.testing.assert_array_equal(np.concatenate(totals), expected.total)


def test_reset_seeds_and_scenario_ids(session):
    env = ata.gym.make(session)
    first, info = env.reset(seed=5)
    assert info["scenario"] == 0
    second, info = env.reset()
    assert info["scenario"] == 1
    again, info = env.reset(options={"scenario": 1})
    assert info["scenario"] == 1
    np.testing.assert_array_equal(again["inherent_tasks"], second["inherent_tasks"])
    restarted, info = env.reset(seed=5)
    assert info["scenario"] == 0
    np.testing.assert_array_equal(restarted["inherent_tasks"], first["inherent_tasks"])
    other, _ = env.reset(seed=6)
    assert not np.array_equal(other["inherent_tasks"], first["inherent_tasks"])


# --- masks ---------------------------------------------------------------------------------------

def test_masks_allow_exactly_what_the_kernel_allows(session):
    """Epoch 0: the flag must be 1, every choice is open. Later: a POI that may not change
    (captured, or its leg under way) keeps exactly its triple; the others are open. Random
    masked actions never change such a POI, and after the end only "keep" is allowed."""
    env = ata.gym.make(session)
    nvec = env.action_space.nvec
    rng = np.random.default_rng(0)
    obs, info = env.reset(seed=2)
    mask = info["action_mask"]
    assert mask_of(mask, nvec, 0).tolist() == [False, True]
    assert mask[2:].all()
    assert [mask_of(mask, nvec, 1 + 3 * p).size for p in range(P)] == [R] * P
    closed_seen = 0
    for k in range(T):
        action = sample_masked(mask, nvec, rng)
        assert allowed(mask, nvec, action)
        before = obs["allocation"].copy()
        closed = obs["reallocatable"] == 0 if k else np.zeros(P, bool)
        for p in range(P):
            segments = [mask_of(mask, nvec, 1 + 3 * p + i) for i in range(3)]
            if closed[p]:
                current = before[p].astype(int) + [0, 1, 1]
                assert [np.flatnonzero(s).tolist() for s in segments] == \
                    [[c] for c in current.tolist()]
            else:
                assert all(s.all() for s in segments)
        closed_seen += int(closed.sum())
        if k:
            assert mask_of(mask, nvec, 0).all()
        obs, _, terminated, _, info = env.step(action)
        np.testing.assert_array_equal(obs["allocation"][closed], before[closed])
        mask = info["action_mask"]
    assert terminated and closed_seen > 0
    assert mask_of(mask, nvec, 0).tolist() == [True, False]
    current = obs["allocation"].astype(int) + [0, 1, 1]
    assert allowed(mask, nvec, np.concatenate([[0], current.ravel()]))
    assert mask[2:].sum() == 3 * P


def test_every_robot_and_every_human_is_allowed_where_a_poi_is_open(session):
    """The model forbids no member a role (a low-skill navigator is slow, not illegal): the
    robot segment has R choices, navigator and classifier 1 + H, all open at epoch 0."""
    env = ata.gym.make(session)
    _, info = env.reset(seed=0)
    nvec = env.action_space.nvec
    skill = env.context.inherent["humans"].col("skill")[0]
    assert (skill < 2).any()                       # a human who is not highly skilled
    for p in range(P):
        assert mask_of(info["action_mask"], nvec, 1 + 3 * p).tolist() == [True] * R
        assert mask_of(info["action_mask"], nvec, 2 + 3 * p).tolist() == [True] * (1 + H)
        assert mask_of(info["action_mask"], nvec, 3 + 3 * p).tolist() == [True] * (1 + H)


def test_the_action_encoding(session):
    """Flag, then per POI robot, navigator + 1 (0 autonomous), classifier + 1 (0 onboard)."""
    env = ata.gym.make(session)
    env.reset(seed=0)
    action = np.zeros(1 + 3 * P, np.int64)
    action[1 + 3 * 2] = R - 1          # POI 2: the last robot,
    action[2 + 3 * 2] = 1 + 1          # navigated by human 1,
    action[3 + 3 * 4] = 1 + 0          # POI 4 classified by human 0
    obs, *_ = env.step(action)
    expected = np.tile([0, -1, -1], (P, 1))
    expected[2] = [R - 1, 1, -1]
    expected[4] = [0, -1, 0]
    np.testing.assert_array_equal(obs["allocation"], expected)


def test_sample_masked_draws_only_and_all_allowed_choices():
    mask = np.array([False, True, True, False, True])
    draws = sample_masked(np.tile(mask, (400, 1)), [2, 3], np.random.default_rng(1))
    assert set(draws[:, 0]) == {1} and set(draws[:, 1]) == {0, 2}
    with pytest.raises(ValueError, match="allows no choice"):
        sample_masked(np.array([True, True, False, False, False]), [2, 3],
                      np.random.default_rng(1))


# --- errors --------------------------------------------------------------------------------------

def test_bad_actions_and_calls_raise_clear_errors(session):
    env = ata.gym.make(session)
    with pytest.raises(RuntimeError, match="call reset first"):
        env.step(np.zeros(1 + 3 * P, np.int64))
    env.reset()
    good = env.mission_action()
    with pytest.raises(ValueError, match=r"actions must have shape \(19,\), got \(18,\)"):
        env.step(good[:-1])
    with pytest.raises(TypeError, match="actions must be integers"):
        env.step(good.astype(float))
    bad = good.copy()
    bad[1 + 3 * 4] = R                  # a robot index >= R
    with pytest.raises(ValueError, match=r"index 13, POI 4's robot\) is 3; allowed: 0 \.\. 2"):
        env.step(bad)
    with pytest.raises(ValueError, match="unknown reset option"):
        env.reset(options={"scenaro": 3})
    with pytest.raises(ValueError, match="seed must lie in"):
        env.reset(seed=2 ** 63)
    env.reset()
    for _ in range(T):
        env.step(env.mission_action())
    with pytest.raises(RuntimeError, match="episode is over: call reset"):
        env.step(good)
    vec = ata.gym.make_vec(session, num_envs=2)
    vec.reset()
    bad = np.stack([vec.mission_action()[0]] * 2)
    bad[1, 3] = H + 1
    with pytest.raises(ValueError, match=r"environment 1, index 3, POI 0's classifier\) is 3"):
        vec.step(bad)
    with pytest.raises(ValueError, match="scenario ids must be a sequence of 2 integers"):
        vec.reset(options={"scenarios": [1]})


def test_the_kernel_refuses_halves_out_of_order(session):
    sim = Simulation(session.mission, session.registry, [0])
    sim.reset()
    with pytest.raises(RuntimeError, match="no epoch has begun"):
        sim.end_epoch(None)
    ctx = sim.begin_epoch()
    with pytest.raises(RuntimeError, match="has begun already"):
        sim.begin_epoch()
    sim.end_epoch(*sim.decide(ctx))
    for _ in range(T - 1):
        sim.step_epoch()
    with pytest.raises(RuntimeError, match="the episode is over"):
        sim.begin_epoch()


# --- the decentralised view (PettingZoo) ---------------------------------------------------------

def test_pettingzoo_api_and_seed_tests_pass(mission_file, session):
    from pettingzoo.test import parallel_api_test, parallel_seed_test

    parallel_api_test(ata.gym.parallel_env(mission_file), num_cycles=2 * T)
    parallel_seed_test(lambda: ata.gym.parallel_env(session))


def test_agents_and_their_spaces(session):
    env = ata.gym.parallel_env(session, k=3)
    assert env.possible_agents == ["human_0", "human_1", "robot_0", "robot_1", "robot_2"]
    assert env.action_space("robot_0").n == 1 + 3 and env.action_space("human_1").n == 1 + 9
    obs, infos = env.reset(seed=0)
    assert set(obs) == set(infos) == set(env.possible_agents)
    for agent in env.agents:
        assert obs[agent] in env.observation_space(agent)
        assert obs[agent]["action_mask"][0] == 1          # keep is always allowed
    assert obs["robot_0"]["observation"].shape == (10 + 12 * 3,)
    assert obs["human_0"]["observation"].shape == (12 + 22 * 3,)


def test_agents_that_keep_give_the_episodes_of_ata_run_without_reallocation(mission_file,
                                                                           session):
    """Every agent keeping at every epoch leaves the mission's initial allocation in force:
    the totals are those of `ata run` with condition "never", epoch 0's points included."""
    never = load_session(mission_file, ["components.condition='never'"])
    expected = Simulation(never.mission, never.registry, list(range(SCENARIOS))).run()
    env = ata.gym.parallel_env(session)
    env.reset(seed=SEED)
    for i in range(SCENARIOS):
        obs, _ = env.reset() if i else env.reset(options={"scenario": 0})
        summed, steps = 0.0, 0
        while env.agents:
            obs, rewards, terms, truncs, infos = env.step({a: 0 for a in env.agents})
            assert len(set(rewards.values())) == 1           # one team reward
            summed, steps = summed + rewards["robot_0"], steps + 1
        assert steps == T - 1 and all(terms.values()) and not any(truncs.values())
        assert infos["human_0"]["total"] == expected.total[i]
        assert summed == expected.total[i] - expected.r_perf[i, 0]


def test_a_forbidden_agent_action_is_taken_as_keep(session):
    env = ata.gym.parallel_env(session)
    obs, _ = env.reset(seed=1)
    # a navigation take (action K+1 = 5) by a human who may classify its first candidate but may
    # not navigate (not highly skilled): without the mask the kernel would accept it
    forbidden = [(agent, 5) for agent, o in obs.items()
                 if agent.startswith("human") and o["action_mask"][1] and not o["action_mask"][5]]
    assert forbidden, "every agent may do everything: no forbidden action to try"
    before = env.context.previous.stack().copy()
    env.step(dict(forbidden))
    np.testing.assert_array_equal(env.context.previous.stack(), before)
    with pytest.raises(ValueError, match="unknown agent 'robot_9'"):
        env.step({"robot_9": 0})
    with pytest.raises(ValueError, match=r"action of robot_0 is 99; allowed: 0 \.\. 4"):
        env.step({"robot_0": 99})


def test_without_the_extra_ata_gym_says_how_to_get_it():
    # gymnasium hidden from a fresh interpreter: the import names the extra
    code = ("import sys; sys.modules['gymnasium'] = None\n"
            "try:\n    import ata.gym\nexcept ModuleNotFoundError as e:\n    print(e)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert "ata.gym needs the gym extra" in out.stdout and "pip install 'ata[gym]'" in out.stdout
