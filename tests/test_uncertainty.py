"""Statistical tests of the four uncertainty injectors against the paper's three levels
(docs/model.md: "Uncertainty"): low sigma^2 = 0.05, p = 0.1; medium 0.1, 0.2; high 0.2, 0.4.

Each level runs one batch of 2000 scenarios of setting (a) for a few epochs (random initial
allocation, no reallocation, to keep it fast). Tolerances are 5 standard errors of the
binomial proportion (or of the sample variance), and every test also checks that the
measured value is more than 5 standard errors away from the other levels' values, so a level
wired to the wrong numbers fails.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import stats

from ata.session import BASELINE_MISSION
from ata.core.kernel import Simulation
from ata.core.mission import UNCERTAINTY_LEVELS
from ata.session import load_session

LEVELS = {"low": (0.05, 0.1), "medium": (0.1, 0.2), "high": (0.2, 0.4)}
B = 2000
EPOCHS = 4
HORIZON = 1800.0
Z = 5.0


def build(level: str | None, extra: list[str] = (), batch: int = B, epochs: int = EPOCHS):
    """Run `epochs` epochs of a batch; return the simulation and per-epoch (truth, observed)."""
    overrides = [f"mission.scenarios={batch}", f"mission.batch_size={batch}",
                 "components.initial='random'", "components.condition='never'"]
    if level is not None:
        overrides.append(f"mission.uncertainty='{level}'")
    s = load_session(str(BASELINE_MISSION), overrides + list(extra))
    sim = Simulation(s.mission, s.registry, np.arange(batch))
    inherent = sim.reset()
    tasks = sim.sim.groups["tasks"]
    setup = {"est_kind": tasks.est_kind.copy(), "est_diff": tasks.est_diff.copy(),
             "true_kind": tasks.true_kind.copy(), "true_diff": tasks.true_diff.copy(),
             "reveal_time": tasks.reveal_time.copy(),
             "fail_time": sim.sim.groups["robots"].fail_time.copy(), "inherent": inherent}
    frames = []
    for _ in range(epochs):
        sim.step_epoch()
        ctx = sim.last_context
        frames.append((sim.last_truth.copy(), ctx.observed.copy(), sim.sim.now - 60.0,
                       sim.sim.groups["tasks"].capture_time.copy()))
    return sim, setup, frames


_CACHE: dict = {}


@pytest.fixture(scope="module", params=list(LEVELS))
def level_run(request):
    level = request.param
    if level not in _CACHE:
        _CACHE[level] = build(level)
    return level, _CACHE[level]


def check_rate(hits: int, n: int, p: float, others: list[float], what: str) -> None:
    """hits/n within Z binomial standard errors of p, and more than Z of them from others."""
    assert n > 0
    rate = hits / n
    se = math.sqrt(p * (1 - p) / n)
    assert abs(rate - p) < Z * se, f"{what}: rate {rate:.4f} vs p {p} (n={n}, se={se:.4f})"
    for q in others:
        se_q = math.sqrt(q * (1 - q) / n)
        assert abs(rate - q) > Z * max(se, se_q), f"{what}: rate {rate:.4f} cannot tell p={p} " \
            f"from p={q}"


def other_ps(level: str) -> list[float]:
    return [v[1] for k, v in LEVELS.items() if k != level]


def other_vars(level: str) -> list[float]:
    return [v[0] for k, v in LEVELS.items() if k != level]


# --- the level table ---------------------------------------------------------------------------

@pytest.mark.parametrize("level", ["none", "low", "medium", "high"])
def test_level_table_resolves_into_the_injectors(level):
    expected = {"none": (0.0, 0.0), **LEVELS}[level]
    assert UNCERTAINTY_LEVELS[level] == expected
    s = load_session(str(BASELINE_MISSION), [f"mission.uncertainty='{level}'", "mission.scenarios=2",
                            "mission.batch_size=2"])
    assert (s.mission.fatigue_variance, s.mission.event_probability) == expected
    sim = Simulation(s.mission, s.registry, np.arange(2))
    plug = sim.pm.get_plugin
    assert plug("injectors:fatigue_noise").variance == expected[0]
    for slot, name in (("perturbations", "attribute_change"), ("perturbations", "robot_failure"),
                       ("injectors", "latency")):
        assert plug(f"{slot}:{name}").p == expected[1]


# --- fatigue noise ------------------------------------------------------------------------------

def test_fatigue_noise_mean_and_variance(level_run):
    level, (sim, setup, frames) = level_run
    var = LEVELS[level][0]
    noise = []
    for truth, observed, _, _ in frames:
        th, oh = truth["humans"], observed["humans"]
        noise.append(oh.col("fatigue") - th.col("fatigue"))
        # the other human columns are exact: no noise, no latency for humans
        for name in ("working_time", "idleness", "sa"):
            np.testing.assert_array_equal(oh.col(name), th.col(name))
        # the truth column is the model's F_f (in [0.4, 1]); the observed one is not clipped
        assert th.col("fatigue").min() >= 0.4 - 1e-12 and th.col("fatigue").max() <= 1.0
    noise = np.stack(noise)                       # (epochs, B, H)
    x = noise.ravel()
    n = x.size
    assert abs(x.mean()) < Z * math.sqrt(var / n)
    measured = x.var(ddof=1)
    se = var * math.sqrt(2.0 / (n - 1))
    assert abs(measured - var) < Z * se, f"variance {measured:.5f} vs {var}"
    for other in other_vars(level):
        assert abs(measured - other) > Z * other * math.sqrt(2.0 / (n - 1))
    # Gaussian: share within one standard deviation 0.682689
    inside = (np.abs(x) < math.sqrt(var)).mean()
    assert abs(inside - 0.682689) < Z * math.sqrt(0.682689 * 0.317311 / n)
    # drawn afresh every epoch: consecutive epochs' noise is uncorrelated
    for k in range(len(frames) - 1):
        r = np.corrcoef(noise[k].ravel(), noise[k + 1].ravel())[0, 1]
        assert abs(r) < Z / math.sqrt(noise[k].size)
    # and independent across humans of a scenario
    r = np.corrcoef(noise[0][:, 0], noise[0][:, 1])[0, 1]
    assert abs(r) < Z / math.sqrt(B)


# --- task attribute change ----------------------------------------------------------------------

def test_attribute_change_rate_and_semantics(level_run):
    level, (sim, setup, frames) = level_run
    p = LEVELS[level][1]
    est_k, est_d = setup["est_kind"], setup["est_diff"]
    true_k, true_d = setup["true_kind"], setup["true_diff"]
    changed = (true_k != est_k) | (true_d != est_d)
    check_rate(int(changed.sum()), changed.size, p, other_ps(level), "attribute change")
    # the inherent information carries the estimate, not the truth
    inh = setup["inherent"]["tasks"]
    np.testing.assert_array_equal(inh.col("kind"), est_k)
    np.testing.assert_array_equal(inh.col("difficulty"), est_d)
    # every changed POI differs in difficulty (redrawn to another level) ...
    assert (true_d[changed] != est_d[changed]).all()
    # ... to either other level with probability 1/2 each
    n_ch = int(changed.sum())
    up_one = ((true_d - est_d) % 3 == 1)[changed].sum()
    assert abs(up_one / n_ch - 0.5) < Z * math.sqrt(0.25 / n_ch)
    # ... and its kind flips with probability 1/2
    flips = (true_k != est_k)[changed].sum()
    assert abs(flips / n_ch - 0.5) < Z * math.sqrt(0.25 / n_ch)
    assert not (true_k != est_k)[~changed].any()
    # the truth is revealed at a uniform time within the horizon; never for unchanged POIs
    reveal = setup["reveal_time"]
    assert np.isinf(reveal[~changed]).all()
    times = reveal[changed]
    assert times.min() >= 0.0 and times.max() < HORIZON
    counts, _ = np.histogram(times, bins=10, range=(0.0, HORIZON))
    chi2 = ((counts - n_ch / 10) ** 2 / (n_ch / 10)).sum()
    assert chi2 < stats.chi2.ppf(1 - 1e-6, df=9), f"reveal times not uniform: {counts}"


def test_attribute_change_shows_from_next_epoch(level_run):
    """S shows the estimate until the reveal time (or capture) has passed, the truth after."""
    level, (sim, setup, frames) = level_run
    est_k, est_d = setup["est_kind"], setup["est_diff"]
    true_k, true_d = setup["true_kind"], setup["true_diff"]
    reveal = setup["reveal_time"]
    shown_changed = 0
    for k, (truth, _, now, capture_time) in enumerate(frames):
        assert now == 60.0 * k
        tasks = truth["tasks"]
        # capture times seen after the epoch; a capture before `now` revealed the truth
        revealed = (reveal <= now) | (capture_time <= now)
        np.testing.assert_array_equal(tasks.col("kind"), np.where(revealed, true_k, est_k))
        np.testing.assert_array_equal(tasks.col("difficulty"), np.where(revealed, true_d, est_d))
        shown_changed += int((revealed & (true_d != est_d)).sum())
    # at epoch 0 nothing is revealed yet (a reveal exactly at t = 0 has probability ~0)
    np.testing.assert_array_equal(frames[0][0]["tasks"].col("difficulty"), est_d)
    assert shown_changed > 0


# --- robot failure -------------------------------------------------------------------------------

def test_robot_failure_rate_and_times(level_run):
    level, (sim, setup, frames) = level_run
    p = LEVELS[level][1]
    fail = setup["fail_time"]
    fails = np.isfinite(fail)
    check_rate(int(fails.sum()), fails.size, p, other_ps(level), "robot failure")
    times = fail[fails]
    assert times.min() >= 0.0 and times.max() < HORIZON
    n = times.size
    counts, _ = np.histogram(times, bins=10, range=(0.0, HORIZON))
    chi2 = ((counts - n / 10) ** 2 / (n / 10)).sum()
    assert chi2 < stats.chi2.ppf(1 - 1e-6, df=9), f"failure times not uniform: {counts}"
    # the UAV and UGV halves fail alike
    check_rate(int(fails[:, :4].sum()), fails[:, :4].size, p, [], "UAV failure")
    check_rate(int(fails[:, 4:].sum()), fails[:, 4:].size, p, [], "UGV failure")


def test_robot_failure_shows_from_next_epoch(level_run):
    level, (sim, setup, frames) = level_run
    fail = setup["fail_time"]
    for truth, _, now, _ in frames:
        working = truth["robots"].col("working")
        np.testing.assert_array_equal(working == 0.0, fail < now)
    # and the true state has them failed for good
    r = sim.sim.groups["robots"]
    np.testing.assert_array_equal(r.failed, fail < sim.sim.now)
    assert r.failed.any()


# --- latency -------------------------------------------------------------------------------------

def test_latency_rate_and_rows(level_run):
    level, (sim, setup, frames) = level_run
    p = LEVELS[level][1]
    hits = {"robots": 0, "tasks": 0}
    n = {"robots": 0, "tasks": 0}
    flags = {"robots": [], "tasks": []}
    # the first epoch has no earlier observation: it is the truth
    for group in ("robots", "tasks"):
        np.testing.assert_array_equal(frames[0][1][group].features, frames[0][0][group].features)
    for k in range(1, len(frames)):
        truth, observed, _, _ = frames[k]
        prev_obs = frames[k - 1][1]
        for group in ("robots", "tasks"):
            obs_rows = observed[group].features
            prev_rows = prev_obs[group].features
            true_rows = truth[group].features
            same_prev = (obs_rows == prev_rows).all(axis=-1)
            same_true = (obs_rows == true_rows).all(axis=-1)
            # every row is either the truth now or last epoch's observed row
            assert (same_prev | same_true).all()
            # where the truth moved on, a row equal to the previous one is a stale row
            informative = ~(true_rows == prev_rows).all(axis=-1)
            hits[group] += int((same_prev & informative).sum())
            n[group] += int(informative.sum())
            stale = observed.extras[f"stale_{group}"]
            assert (same_prev[stale]).all() and (same_true[~stale]).all()
            flags[group].append(stale)
    for group in ("robots", "tasks"):
        f = np.concatenate(flags[group])
        check_rate(int(f.sum()), f.size, p, other_ps(level), f"latency flags {group}")
    # independently of the flags: rows whose truth changed are stale at rate p
    check_rate(hits["robots"], n["robots"], p, other_ps(level), "latency robots")
    check_rate(hits["robots"] + hits["tasks"], n["robots"] + n["tasks"], p, other_ps(level),
               "latency rows")


# --- no uncertainty ------------------------------------------------------------------------------

def test_none_injects_nothing():
    sim, setup, frames = build("none", batch=300, epochs=3)
    np.testing.assert_array_equal(setup["true_kind"], setup["est_kind"])
    np.testing.assert_array_equal(setup["true_diff"], setup["est_diff"])
    assert np.isinf(setup["reveal_time"]).all()
    assert np.isinf(setup["fail_time"]).all()
    for truth, observed, _, _ in frames:
        for group in ("humans", "robots", "tasks"):
            np.testing.assert_array_equal(observed[group].features, truth[group].features)
        assert (truth["robots"].col("working") == 1.0).all()
    # something did change in the truth between epochs, so latency would have been visible
    assert not np.array_equal(frames[1][0]["robots"].features, frames[2][0]["robots"].features)


# --- per-injector settings override the level ----------------------------------------------------

def test_per_injector_settings_override_level():
    batch = 1000
    sim, setup, frames = build("low", extra=["latency.probability=0.5",
                                             "fatigue_noise.variance=0.3",
                                             "attribute_change.probability=0.6"],
                               batch=batch, epochs=3)
    plug = sim.pm.get_plugin
    assert plug("injectors:latency").p == 0.5
    assert plug("injectors:fatigue_noise").variance == 0.3
    assert plug("perturbations:attribute_change").p == 0.6
    assert plug("perturbations:robot_failure").p == 0.1         # still the level's p
    # latency at 0.5, not low's 0.1
    stale = np.concatenate([frames[k][1].extras["stale_robots"] for k in (1, 2)])
    check_rate(int(stale.sum()), stale.size, 0.5, [0.1], "latency override")
    # fatigue variance 0.3
    x = np.concatenate([(o["humans"].col("fatigue") - t["humans"].col("fatigue")).ravel()
                        for t, o, _, _ in frames])
    assert abs(x.var(ddof=1) - 0.3) < Z * 0.3 * math.sqrt(2.0 / (x.size - 1))
    # attribute change 0.6
    changed = (setup["true_kind"] != setup["est_kind"]) | (setup["true_diff"] != setup["est_diff"])
    check_rate(int(changed.sum()), changed.size, 0.6, [0.1], "attribute change override")
    # robot failure untouched: low's 0.1
    fails = np.isfinite(setup["fail_time"])
    check_rate(int(fails.sum()), fails.size, 0.1, [0.5, 0.6], "robot failure at level")


def test_robot_failure_setting_and_custom_level():
    s = load_session(str(BASELINE_MISSION), ["mission.uncertainty='custom'", "mission.fatigue_variance=0.02",
                            "mission.event_probability=0.3", "robot_failure.probability=0.7",
                            "mission.scenarios=1000", "mission.batch_size=1000"])
    sim = Simulation(s.mission, s.registry, np.arange(1000))
    sim.reset()
    plug = sim.pm.get_plugin
    assert plug("injectors:fatigue_noise").variance == 0.02
    assert plug("injectors:latency").p == 0.3
    assert plug("perturbations:robot_failure").p == 0.7
    fails = np.isfinite(sim.sim.groups["robots"].fail_time)
    check_rate(int(fails.sum()), fails.size, 0.7, [0.3], "robot failure override")
    t = sim.sim.groups["tasks"]
    changed = (t.true_kind != t.est_kind) | (t.true_diff != t.est_diff)
    check_rate(int(changed.sum()), changed.size, 0.3, [0.2, 0.4], "custom event probability")


def _held(obs, P):
    """(B, P) bool: the POIs some row of `obs` holds."""
    out = np.zeros((obs["tasks"].features.shape[0], P), bool)
    for group in ("tasks", "robots"):
        holds = obs[group].holds
        b, n = np.nonzero(holds >= 0)
        out[b, holds[b, n]] = True
    return out


def test_reallocatable_is_read_off_the_observed_rows_and_the_kernel_refuses_what_cannot_change():
    # under latency a policy sees which POIs are reallocatable as the observed rows show them:
    # a stale task row holds its POI if it was captured then, a stale robot row the POI it was
    # on its way to then. A POI truly captured (or with a leg under way) keeps its triple
    # whatever a policy proposes for it, and the change counts as refused.
    B = 64
    s = load_session(str(BASELINE_MISSION), [
        f"mission.scenarios={B}", f"mission.batch_size={B}", "mission.uncertainty='high'",
        "components.initial='random'", "components.condition='always'",
        "components.reallocation='random'"])
    sim = Simulation(s.mission, s.registry, np.arange(B))
    sim.reset()
    sim.step_epoch()
    prev = sim.last_context.observed
    P = sim.sim.sizes.tasks
    seen_open = robot_row_only = refused = 0
    for _ in range(12):
        ctx = sim.begin_epoch()
        truth, observed = sim.last_truth, ctx.observed
        for group in ("tasks", "robots"):
            stale = observed.extras[f"stale_{group}"]
            held, true_held, before = (observed[group].holds, truth[group].holds,
                                       prev[group].holds)
            assert np.array_equal(held[~stale], true_held[~stale])
            assert np.array_equal(held[stale], before[stale])
        assert np.array_equal(ctx.reallocatable, ~_held(observed, P))
        shown_open = ctx.reallocatable & ~truth.reallocatable
        seen_open += int(shown_open.sum())
        # shown open although the POI's own row is fresh: a stale robot row hides its leg
        robot_row_only += int((shown_open & ~observed.extras["stale_tasks"]).sum())
        # propose a change of every POI: a new robot for each
        proposal = ctx.previous.copy()
        proposal.robot[:] = (ctx.previous.robot + 1) % sim.sim.sizes.robots
        before_alloc = ctx.previous.copy()
        sim.end_epoch(proposal, np.ones(B, bool))
        after = sim.sim.allocation
        locked = ~truth.reallocatable
        assert np.array_equal(after.robot[locked], before_alloc.robot[locked])
        both = ctx.reallocatable & truth.reallocatable
        assert np.array_equal(after.robot[both], proposal.robot[both])
        refused += int(shown_open.sum())
        assert sim.sim.record.refused.sum() == refused
        prev = observed
    assert seen_open > 0 and robot_row_only > 0


def test_arrivals_guesses_captures_the_latency_hides_from_the_robot_rows():
    """The `arrivals` reconstructor names POIs whose stale row still shows them unvisited while
    their robot, seen fresh, has moved on: most of its guesses are true captures, it finds some
    of the hidden ones, it never names a POI whose row is fresh, and plan_start takes what it
    names as captured (not open; its image books the classifier)."""
    from ata.model.plan import plan_start
    s = load_session(str(BASELINE_MISSION), [
        "mission.uncertainty='high'", "mission.seed=4321",
        "components.reconstructors=['identity','arrivals']"])
    sim = Simulation(s.mission, s.registry, list(range(16)))
    sim.reset()
    right = wrong = hidden = 0
    prev = None
    while sim.sim.epoch < sim.sim.clock.n_epochs:
        ctx = sim.begin_epoch()
        guess = ctx.reconstructed["captured_guess"][..., 0] > 0.5
        obs, truth = ctx.observed["tasks"], sim.last_truth["tasks"]
        if ctx.epoch == 0:
            assert not guess.any()
        else:
            captured = truth.col("unvisited") < 0.5
            right += int((guess & captured).sum())
            wrong += int((guess & ~captured).sum())
            hidden += int(((obs.col("unvisited") > 0.5) & captured).sum())
            changed = (obs.features != prev).any(-1)
            assert not (guess & changed).any()          # a row that changed is fresh
            assert not (guess & (obs.col("unvisited") < 0.5)).any()
            if guess.any():
                start = plan_start(ctx)
                assert not start.open[guess].any()
        prev = obs.features.copy()
        sim.end_epoch(*sim.decide(ctx))
    assert hidden > 0 and right >= 0.2 * hidden, (right, hidden)
    assert wrong <= 0.25 * right, (right, wrong)
