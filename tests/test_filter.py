"""The filter reconstructor: its grid posterior over each human's fatigue curve, checked by
hand and against the simulator, and the age of the robot and task rows."""

import math

import numpy as np

from ata.core.kernel import Simulation
from ata.core.state import Observation
from ata.session import BASELINE_MISSION, load_session
from ata.model import tables
from ata.model.fatigue import belief_from, individual
from ata.model.team import HumanConstants
from ata.plugins.filter import FilterReconstructor, noise_variance, prior_grid
from ata.testing import check_component

HUMAN_STATE = ("working_time", "fatigue", "idleness", "sa")
FLOOR = 0.4


class View:
    """The part of a DecisionView the filter reads: the epoch and the published constants."""

    def __init__(self, epoch: int, spread: float = 1.0):
        self.epoch = epoch
        self.constants = HumanConstants(fatigue_floor=FLOOR, fatigue_spread=spread)

    def published(self, kind):
        assert kind is HumanConstants
        return self.constants


def make_filter(**settings) -> FilterReconstructor:
    variance = settings.pop("variance", 0.1)
    return FilterReconstructor(FilterReconstructor.Settings(variance=variance, **settings), None)


def humans_obs(hours: np.ndarray, fatigue: np.ndarray) -> Observation:
    obs = Observation()
    feats = np.stack([hours, fatigue, np.zeros_like(hours), np.ones_like(hours)], -1)
    obs.add("humans", HUMAN_STATE, feats.astype(float))
    return obs


def step(f: FilterReconstructor, epoch: int, hours, fatigue, spread: float = 1.0,
         **groups) -> dict:
    obs = humans_obs(np.asarray(hours, float), np.asarray(fatigue, float))
    for group, rows in groups.items():
        obs.add(group, tuple(f"c{i}" for i in range(rows.shape[-1])), rows.astype(float))
    out: dict = {}
    f.ata_reconstruct(sim=View(epoch, spread), obs=obs, inherent=Observation(), out=out)
    return out


def fatigue_now(out: dict) -> np.ndarray:
    return out["humans"][..., HUMAN_STATE.index("fatigue")]


def test_two_point_posterior_by_hand():
    # spread 1: onsets at the midpoints of two cells of [0.5, 1.5] (0.75 and 1.25), one slope
    # (0.3, the midpoint of [0.1, 0.5]); noise variance 0.1
    f = make_filter(onsets=2, slopes=1, variance=0.1)
    out = step(f, 0, [[1.5]], [[0.8]])
    assert np.allclose(out["fatigue_onset"], [[[0.75, 1.25]]])
    assert np.allclose(out["fatigue_slope"], [[[0.3, 0.3]]])
    # F(1.5) = 1 - 0.3 * 0.75 = 0.775 and 1 - 0.3 * 0.25 = 0.925: misses 0.025 and 0.125, so
    # log-likelihoods -0.003125 and -0.078125, which differ by 0.075
    w = 1.0 / (1.0 + math.exp(-0.075))
    assert np.allclose(out["fatigue_weight"], [[[w, 1 - w]]], rtol=0, atol=1e-12)
    assert np.allclose(fatigue_now(out), w * 0.775 + (1 - w) * 0.925, rtol=0, atol=1e-12)
    # an hour later: F(2.5) = 0.475 and 0.625, observed 0.5: the same misses again, so the
    # log-odds double
    out = step(f, 1, [[2.5]], [[0.5]])
    w = 1.0 / (1.0 + math.exp(-0.15))
    assert np.allclose(out["fatigue_weight"], [[[w, 1 - w]]], rtol=0, atol=1e-12)
    assert np.allclose(fatigue_now(out), w * 0.475 + (1 - w) * 0.625, rtol=0, atol=1e-12)
    # the belief projects ahead: at 3 h, 1 - 0.3 * 2.25 = 0.4 (the floor) and 0.475
    belief = belief_from(out, fatigue_now(out), np.array([[2.5]]), FLOOR)
    assert np.allclose(belief.at(np.array([[3.0]])), w * 0.4 + (1 - w) * 0.475, atol=1e-12)
    # the other columns pass through
    assert np.array_equal(out["humans"][..., 0], [[2.5]])
    assert np.array_equal(out["humans"][..., 3], [[1.0]])


def test_before_every_onset_an_observation_teaches_nothing():
    f = make_filter()
    out = step(f, 0, [[0.2, 0.5]], [[1.7, 0.1]])       # every grid onset is above 0.5 h
    assert np.allclose(out["fatigue_weight"], 1.0 / 225, rtol=0, atol=1e-15)
    assert np.array_equal(fatigue_now(out), [[1.0, 1.0]])


def on_grid_truth(seed: int, shape: tuple[int, int]):
    """Onsets and slopes drawn from the default grid's points."""
    on, sl = prior_grid(1.0, 15, 15)
    pick = np.random.default_rng(seed).integers(0, on.size, shape)
    return on[pick], sl[pick]


def test_zero_noise_returns_the_truth_after_one_observation_and_the_curve_after_two():
    B, H = 6, 5
    onset, slope = on_grid_truth(3, (B, H))
    f = make_filter(variance=0.0)
    # every human past every onset (the grid's largest is 1.467 h) and above the floor
    t1 = np.full((B, H), 1.5)
    out = step(f, 0, t1, individual(t1, onset, slope, FLOOR))
    assert np.abs(fatigue_now(out) - individual(t1, onset, slope, FLOOR)).max() < 1e-6
    t2 = np.full((B, H), 1.7)
    out = step(f, 1, t2, individual(t2, onset, slope, FLOOR))
    assert np.abs(fatigue_now(out) - individual(t2, onset, slope, FLOOR)).max() < 1e-6
    # two points past the onset fix the line: F an hour and two hours ahead is the truth's
    belief = belief_from(out, fatigue_now(out), t2, FLOOR)
    for ahead in (1.0, 2.0):
        truth = individual(t2 + ahead, onset, slope, FLOOR)
        assert np.abs(belief.at(t2 + ahead) - truth).max() < 1e-6


def test_with_no_spread_the_belief_is_the_population_curve():
    f = make_filter(variance=0.2)
    hours = np.array([[0.5, 1.2, 1.8, 3.5]])
    for epoch, noise in enumerate((0.3, -0.5, 0.05)):
        out = step(f, epoch, hours + epoch, tables.fatigue(hours + epoch, FLOOR) + noise,
                   spread=0.0)
        assert out["fatigue_onset"].shape == (1, 4, 1)
        assert np.array_equal(out["fatigue_onset"], np.ones((1, 4, 1)))
        assert np.array_equal(out["fatigue_slope"], np.full((1, 4, 1), 0.3))
        assert np.array_equal(out["fatigue_weight"], np.ones((1, 4, 1)))
        # the population line, whatever the noise, exactly
        assert np.array_equal(fatigue_now(out), tables.fatigue(hours + epoch, FLOOR))


def test_ages_count_epochs_since_the_row_changed_and_reset_at_epoch_0():
    f = make_filter()
    h = dict(hours=[[0.0]], fatigue=[[1.0]])
    rob = np.array([[[0.1, 0.2], [0.3, 0.4], [0.5, 0.6]]])      # (1, 3 robots, 2 columns)
    task = np.array([[[1, 0], [0, 1]]])                         # (1, 2 tasks, 2 columns)
    out = step(f, 0, **h, robots=rob, tasks=task)
    assert np.array_equal(out["robots_age"], [[0, 0, 0]])
    assert np.array_equal(out["tasks_age"], [[0, 0]])
    assert np.array_equal(out["robots"], rob) and np.array_equal(out["tasks"], task)
    rob1 = rob.copy()
    rob1[0, 0, 0] = 0.15                                        # robot 0 moved
    out = step(f, 1, **h, robots=rob1, tasks=task)
    assert np.array_equal(out["robots_age"], [[0, 1, 1]])
    assert np.array_equal(out["tasks_age"], [[1, 1]])
    rob2 = rob1.copy()
    rob2[0, 1, 1] = 0.45                                        # robot 1 moved
    task2 = task.copy()
    task2[0, 0] = [0, 1]                                        # task 0 captured
    out = step(f, 2, **h, robots=rob2, tasks=task2)
    assert np.array_equal(out["robots_age"], [[1, 0, 2]])
    assert np.array_equal(out["tasks_age"], [[0, 2]])
    out = step(f, 3, **h, robots=rob2, tasks=task2)
    assert np.array_equal(out["robots_age"], [[2, 1, 3]])
    assert np.array_equal(out["tasks_age"], [[1, 3]])
    assert np.array_equal(out["robots"], rob2) and np.array_equal(out["tasks"], task2)
    # a new episode starts afresh: ages and the posterior
    out = step(f, 0, [[1.5]], [[0.5]], robots=rob2, tasks=task2)
    assert np.array_equal(out["robots_age"], [[0, 0, 0]])
    assert np.array_equal(out["tasks_age"], [[0, 0]])
    fresh = step(make_filter(), 0, [[1.5]], [[0.5]])
    assert np.array_equal(out["fatigue_weight"], fresh["fatigue_weight"])


def small(*overrides: str):
    return load_session(str(BASELINE_MISSION), [
        "mission.setting='custom'", "mission.humans=3", "mission.robots=4", "mission.tasks=12",
        "mission.uncertainty='high'", *overrides])


def test_noise_variance_is_the_one_the_mission_injects():
    assert noise_variance(small().mission) == 0.2                  # the level's
    assert noise_variance(small("fatigue_noise.variance=0.05").mission) == 0.05
    assert noise_variance(small("mission.fatigue_variance=0.3").mission) == 0.3
    assert noise_variance(small("components.injectors=['latency']").mission) == 0.0
    s = FilterReconstructor.Settings()
    assert FilterReconstructor(s, small().mission.public()).variance == 0.2
    # no noise: the floor's square
    quiet = small("fatigue_noise.variance=0").mission.public()
    assert FilterReconstructor(s, quiet).variance == s.sigma_floor ** 2
    own = FilterReconstructor.Settings(variance=0.07)
    assert FilterReconstructor(own, small().mission).variance == 0.07


def test_filter_passes_the_checker():
    check_component("reconstructor", FilterReconstructor)


def run_truth(overrides: list[str], scenarios: int, seed: int = 5):
    """Run the baseline mission (setting (a)) with the filter; yield at every epoch its
    context, the true S and the humans' hidden onsets and slopes."""
    s = load_session(str(BASELINE_MISSION), [
        f"mission.seed={seed}", "components.reconstructors=['identity','filter']", *overrides])
    sim = Simulation(s.mission, s.registry, list(range(scenarios)))
    sim.reset()
    hidden = sim.sim.group("humans")
    onset, slope = np.asarray(hidden.fatigue_onset), np.asarray(hidden.fatigue_slope)
    while sim.sim.epoch < sim.sim.clock.n_epochs:
        ctx = sim.begin_epoch()
        yield ctx, sim.last_truth, onset, slope
        sim.end_epoch(*sim.decide(ctx))


def test_zero_noise_in_the_simulator_is_within_the_grid_resolution():
    """Exact observations of curves off the grid: F_f now is the best-fitting grid curve's,
    within a fraction of the grid's spacing (onsets 1/15 h apart, slopes 0.027 per hour), and
    within half as much on a grid twice as fine."""
    for grid, worst_bound, mean_bound in ((15, 0.02, 0.002), (31, 0.01, 0.001)):
        worst, errors = 0.0, []
        for ctx, truth, onset, slope in run_truth([
                "mission.uncertainty='high'", "fatigue_noise.variance=0",
                f"filter.onsets={grid}", f"filter.slopes={grid}"], 16):
            true_f = truth["humans"].col("fatigue")
            assert np.array_equal(ctx.observed["humans"].col("fatigue"), true_f)
            error = np.abs(fatigue_now(ctx.reconstructed) - true_f)
            worst = max(worst, error.max())
            errors.append(error.mean())
        assert worst < worst_bound and np.mean(errors) < mean_bound, (grid, worst, errors)


def test_with_noise_the_error_falls_as_observations_accumulate():
    """(a) high, 40 scenarios: for the humans past 1.2 h of work at epoch 1 (all are past some
    onsets), the mean absolute error of F_f now and of F_f an hour ahead falls from epoch 1 to
    the last, while that of the prior's mean (the same grid, equal weights) rises: the humans
    tire and their curves part, so the filter gains from what it observed, not from an easier
    problem."""
    errors = {}
    chosen = None
    for ctx, truth, onset, slope in run_truth(["mission.uncertainty='high'"], 40):
        if ctx.epoch == 0:
            continue
        rec, hours = ctx.reconstructed, ctx.observed["humans"].col("working_time")
        if chosen is None:
            chosen = hours > 1.2
        now = fatigue_now(rec)
        belief = belief_from(rec, now, hours, FLOOR)
        prior = belief_from({**rec, "fatigue_weight": np.full(rec["fatigue_weight"].shape,
                                                               1.0 / 225)}, now, hours, FLOOR)
        true_now = truth["humans"].col("fatigue")
        true_ahead = individual(hours + 1.0, onset, slope, FLOOR)
        errors[ctx.epoch] = [np.abs(x - t)[chosen].mean() for x, t in (
            (now, true_now), (prior.at(hours), true_now),
            (belief.at(hours + 1.0), true_ahead), (prior.at(hours + 1.0), true_ahead))]
    assert chosen.sum() >= 30
    first, last = errors[1], errors[max(errors)]
    now, prior_now, ahead, prior_ahead = zip(first, last)
    assert now[1] < 0.8 * now[0] and prior_now[1] > prior_now[0], (now, prior_now)
    assert ahead[1] < 0.9 * ahead[0] and prior_ahead[1] > 0.9 * prior_ahead[0], \
        (ahead, prior_ahead)
    assert now[1] < 0.75 * prior_now[1] and ahead[1] < 0.9 * prior_ahead[1]


def test_with_no_spread_in_the_simulator_the_filter_returns_the_truth():
    for ctx, truth, onset, slope in run_truth(["mission.uncertainty='high'",
                                               "human.fatigue_spread=0"], 4):
        assert ctx.reconstructed["fatigue_weight"].shape[-1] == 1
        assert np.array_equal(fatigue_now(ctx.reconstructed), truth["humans"].col("fatigue"))


def test_without_observations_the_belief_is_the_prior():
    """observe = false: the weights stay uniform over the grid whatever the observations."""
    def make(observe):
        return FilterReconstructor(FilterReconstructor.Settings(
            onsets=3, slopes=3, variance=0.1, observe=observe), mission=None)

    class View:
        epoch = 0

        def published(self, kind):
            return kind()

    obs = Observation()
    obs.add("humans", ("working_time", "fatigue", "idleness", "sa"),
            np.array([[[1.4, 0.2, 0.5, 1.0], [0.2, 1.0, 0.5, 1.0]]]))
    prior: dict = {}
    make(False).ata_reconstruct(sim=View(), obs=obs, inherent=Observation(), out=prior)
    assert np.allclose(prior["fatigue_weight"], 1 / 9, rtol=0, atol=1e-15)
    seen: dict = {}
    make(True).ata_reconstruct(sim=View(), obs=obs, inherent=Observation(), out=seen)
    # the first human, past some onsets and observed tired, moves the weights; the second,
    # before every onset, teaches nothing
    assert np.ptp(seen["fatigue_weight"][0, 0]) > 0.1
    assert np.allclose(seen["fatigue_weight"][0, 1], 1 / 9, rtol=0, atol=1e-15)
