"""The tables and formulas of the model (docs/model.md) against hand-computed values.

Every expected value here is a literal worked out by hand from docs/model.md (with exp() values
written out to 16 digits), never recomputed with the code under test.
"""

from __future__ import annotations

import numpy as np
import pytest

from ata.session import BASELINE_MISSION
from ata.core.kernel import Simulation
from ata.core.mission import TEAM_SETTINGS
from ata.session import load_session
from ata.core.state import Clock
from ata.model import tables
from ata.plugins.robots import RobotModel
from ata.plugins.tasks import upper_bound

PI_12 = 0.2617993877991494   # pi / 12
PI_6 = 0.5235987755982988    # pi / 6

# codes (tables.py docstring): kind 0 air, 1 ground; quality 0 Low .. 3 High; UAV 0, UGV 1;
# navigator class 0 low skill, 1 auto or medium, 2 high
LOW_Q, MED_Q, UM_Q, HIGH_Q = 0, 1, 2, 3


def test_codes():
    assert (tables.AIR, tables.GROUND) == (0, 1)
    assert (tables.UAV, tables.UGV) == (0, 1)
    assert tables.QUALITIES == ("Low", "Medium", "Upper-Medium", "High")
    assert tables.DIFFICULTIES == ("low", "medium", "high")


# --- Table I: image quality ---------------------------------------------------------------------

# (robot, POI kind, navigator class) -> quality, cell by cell from docs/model.md, "Robots"
TABLE_I = [
    # UAV, ground POI: Low / Medium / Upper-Medium
    (0, 1, 0, LOW_Q), (0, 1, 1, MED_Q), (0, 1, 2, UM_Q),
    # UAV, air POI: Medium / Upper-Medium / High
    (0, 0, 0, MED_Q), (0, 0, 1, UM_Q), (0, 0, 2, HIGH_Q),
    # UGV, ground POI: Medium / Upper-Medium / High
    (1, 1, 0, MED_Q), (1, 1, 1, UM_Q), (1, 1, 2, HIGH_Q),
    # UGV, air POI: Low / Medium / Upper-Medium
    (1, 0, 0, LOW_Q), (1, 0, 1, MED_Q), (1, 0, 2, UM_Q),
]


@pytest.mark.parametrize("robot,kind,nav,quality", TABLE_I)
def test_quality_table_cell(robot, kind, nav, quality):
    assert tables.QUALITY[robot, kind, nav] == quality


def test_quality_table_shape_and_all_cells_covered():
    assert tables.QUALITY.shape == (2, 2, 3)
    assert len({(r, k, n) for r, k, n, _ in TABLE_I}) == 12


# --- P_rc and t_bar -----------------------------------------------------------------------------

P_RC_CELLS = [
    (LOW_Q, 0, 0.5), (LOW_Q, 1, 0.3), (LOW_Q, 2, 0.1),
    (MED_Q, 0, 0.6), (MED_Q, 1, 0.4), (MED_Q, 2, 0.2),
    (UM_Q, 0, 0.7), (UM_Q, 1, 0.5), (UM_Q, 2, 0.3),
    (HIGH_Q, 0, 0.8), (HIGH_Q, 1, 0.6), (HIGH_Q, 2, 0.4),
]

T_BAR_CELLS = [
    (LOW_Q, 0, 45.0), (LOW_Q, 1, 125.0), (LOW_Q, 2, 245.0),
    (MED_Q, 0, 35.0), (MED_Q, 1, 95.0), (MED_Q, 2, 195.0),
    (UM_Q, 0, 25.0), (UM_Q, 1, 65.0), (UM_Q, 2, 145.0),
    (HIGH_Q, 0, 15.0), (HIGH_Q, 1, 35.0), (HIGH_Q, 2, 95.0),
]


@pytest.mark.parametrize("q,d,p", P_RC_CELLS)
def test_p_rc_cell(q, d, p):
    assert tables.P_RC[q, d] == pytest.approx(p, abs=1e-12)


@pytest.mark.parametrize("q,d,t", T_BAR_CELLS)
def test_t_bar_cell(q, d, t):
    assert tables.T_BAR[q, d] == t


def test_p_rc_and_t_bar_shapes():
    assert tables.P_RC.shape == (4, 3)
    assert tables.T_BAR.shape == (4, 3)


# --- F_d ----------------------------------------------------------------------------------------

# F_d = 1 / (1 + exp(0.04 (t_bar - 180))), by hand:
#   t=180: 1/(1+1) = 0.5
#   t=15:  exp(-6.6) = 0.0013603680375479 -> 0.9986414800495711
#   t=35:  exp(-5.8) = 0.0030275547453758 -> 0.9969815836752917
#   t=95:  exp(-3.4) = 0.0333732699603261 -> 0.9677045353015494
#   t=145: exp(-1.4) = 0.2465969639416064 -> 0.8021838885585818
#   t=195: exp(0.6)  = 1.8221188003905089 -> 0.3543436937742046
#   t=245: exp(2.6)  = 13.463738035001690 -> 0.0691384203433468
F_D_VALUES = [(180.0, 0.5), (15.0, 0.9986414800495711), (35.0, 0.9969815836752917),
              (95.0, 0.9677045353015494), (145.0, 0.8021838885585818),
              (195.0, 0.3543436937742046), (245.0, 0.0691384203433468)]


@pytest.mark.parametrize("t_bar,f_d", F_D_VALUES)
def test_decision_difficulty(t_bar, f_d):
    assert tables.decision_difficulty(t_bar) == pytest.approx(f_d, rel=1e-12)


def test_decision_difficulty_vectorised_and_f_d_table():
    got = tables.decision_difficulty(np.array([180.0, 15.0, 245.0]))
    np.testing.assert_allclose(got, [0.5, 0.9986414800495711, 0.0691384203433468], rtol=1e-12)
    # F_D[quality, difficulty] is F_d of the t_bar cell: High/low = t_bar 15, Medium/high = 195
    assert tables.F_D[HIGH_Q, 0] == pytest.approx(0.9986414800495711, rel=1e-12)
    assert tables.F_D[MED_Q, 2] == pytest.approx(0.3543436937742046, rel=1e-12)
    assert tables.F_D[UM_Q, 2] == pytest.approx(0.8021838885585818, rel=1e-12)


# --- fatigue F_f ---------------------------------------------------------------------------------

@pytest.mark.parametrize("hours,f_f", [
    (0.0, 1.0), (0.5, 1.0), (0.999, 1.0), (1.0, 1.0), (1.5, 0.85), (2.0, 0.7),
    (2.5, 0.55), (3.0, 0.4), (3.5, 0.4), (5.0, 0.4), (100.0, 0.4)])
def test_fatigue(hours, f_f):
    assert tables.fatigue(hours) == pytest.approx(f_f, abs=1e-12)


def test_fatigue_floor_parameter_and_vector():
    # with floor 0.1 the line continues: T=3 -> 0.4, T=4 -> 0.1, T=5 -> floor 0.1
    np.testing.assert_allclose(tables.fatigue(np.array([3.0, 4.0, 5.0]), floor=0.1),
                               [0.4, 0.1, 0.1], atol=1e-12)


# --- workload F_w --------------------------------------------------------------------------------

# low branch  -2.47 u^2 + 2.22 u + 0.5:  u=0 -> 0.5; u=0.2 -> -0.0988+0.444+0.5 = 0.8452;
#   u=0.44 -> -0.478192+0.9768+0.5 = 0.998608
# plateau 1 on [0.45, 0.65)
# high branch -4.08 u^2 + 5.31 u - 0.724: u=0.65 -> -1.7238+3.4515-0.724 = 1.0037;
#   u=0.8 -> -2.6112+4.248-0.724 = 0.9128; u=1 -> -4.08+5.31-0.724 = 0.506
@pytest.mark.parametrize("u,f_w", [
    (0.0, 0.5), (0.2, 0.8452), (0.44, 0.998608), (0.45, 1.0), (0.5, 1.0), (0.6499, 1.0),
    (0.65, 1.0037), (0.8, 0.9128), (1.0, 0.506)])
def test_workload(u, f_w):
    assert tables.workload(u) == pytest.approx(f_w, abs=1e-9)


def test_workload_boundaries_vector():
    # just below 0.45 the low quadratic (0.998825 at 0.45), at 0.45 the plateau
    got = tables.workload(np.array([0.45 - 1e-12, 0.45, 0.65 - 1e-12, 0.65]))
    np.testing.assert_allclose(got, [0.998825, 1.0, 1.0, 1.0037], atol=1e-9)


# --- P_hc ----------------------------------------------------------------------------------------

def test_human_success():
    # 0.5 + 0.5 * 0.85 * 1 * 0.6 * 0.5 = 0.5 + 0.1275
    assert tables.human_success(0.5, 0.6, 0.85, 1.0, 0.5) == pytest.approx(0.6275, abs=1e-12)
    # 0.5 + 0.4 * 0.7 * 0.9128 * 0.3 * 0.9677045353015494 = 0.5 + 0.07417... (by hand:
    # 0.4*0.7 = 0.28; *0.9128 = 0.255584; *0.3 = 0.0766752; *0.96770453530 = 0.0741989...)
    assert tables.human_success(0.4, 0.3, 0.7, 0.9128, 0.9677045353015494) == \
        pytest.approx(0.5741989, abs=1e-6)
    # extremes: nothing known -> 0.5; eta = lam = sqrt(2)/2 with all factors 1 -> 1
    assert tables.human_success(0.0, 0.7, 1.0, 1.0, 1.0) == 0.5
    assert tables.human_success(0.7071067811865476, 0.7071067811865476, 1.0, 1.0, 1.0) == \
        pytest.approx(1.0, abs=1e-12)


def test_human_success_vectorised():
    got = tables.human_success(np.array([0.5, 0.2]), np.array([0.6, 0.5]), np.array([1.0, 0.4]),
                               np.array([1.0, 0.5]), np.array([0.5, 1.0]))
    # 0.5 + 0.15 ; 0.5 + 0.2*0.4*0.5*0.5*1 = 0.52
    np.testing.assert_allclose(got, [0.65, 0.52], atol=1e-12)


# --- skill band ----------------------------------------------------------------------------------

@pytest.mark.parametrize("theta,band", [
    (0.0, 0), (0.1, 0), (PI_12 - 1e-9, 0), (PI_12, 1), (PI_12 + 1e-9, 1), (0.4, 1),
    (PI_6 - 1e-9, 1), (PI_6 + 1e-9, 2), (0.7, 2), (0.7853981633974483, 2)])
def test_skill_band(theta, band):
    assert int(tables.skill_band(theta)) == band


def test_skill_band_vector_dtype():
    got = tables.skill_band(np.array([0.05, 0.3, 0.6]))
    assert got.dtype.kind == "i"
    assert got.tolist() == [0, 1, 2]


# --- points, speeds, navigator class, expected points -------------------------------------------

def test_points():
    assert tables.POINTS.tolist() == [15.0, 25.0, 35.0]


def test_speed_multipliers():
    np.testing.assert_allclose(tables.SKILL_SPEED, [0.6666666666666666, 1.0, 1.5], rtol=1e-15)
    # testbed ratio 1 : 1.5 : 2.25
    np.testing.assert_allclose(tables.SKILL_SPEED / tables.SKILL_SPEED[0], [1.0, 1.5, 2.25])
    s = RobotModel.Settings()
    np.testing.assert_allclose(s.skill_speed, [0.6666666666666666, 1.0, 1.5], rtol=1e-15)
    assert (s.uav_speed, s.ugv_speed, s.capture_s) == (8.0, 3.0, 3.0)


def test_navigator_class():
    navigator = np.array([[-1, 0, 1], [1, -1, 0]])
    skill = np.array([[0, 2], [1, 0]])
    assert tables.navigator_class(navigator, skill).tolist() == [[1, 0, 2], [0, 1, 1]]


def test_expected_points():
    # 25 * (2*0.8 - 1) = 15 ; 35 * (2*0.3 - 1) = -14 ; 15 * (2*0.5 - 1) = 0
    np.testing.assert_allclose(
        tables.expected_points(np.array([25.0, 35.0, 15.0]), np.array([0.8, 0.3, 0.5])),
        [15.0, -14.0, 0.0], atol=1e-12)


# --- team settings, clock ------------------------------------------------------------------------

def test_team_settings_and_clock():
    assert (TEAM_SETTINGS["a"].humans, TEAM_SETTINGS["a"].robots, TEAM_SETTINGS["a"].tasks) == \
        (6, 8, 60)
    assert (TEAM_SETTINGS["b"].humans, TEAM_SETTINGS["b"].robots, TEAM_SETTINGS["b"].tasks) == \
        (12, 16, 130)
    c = Clock()
    assert (c.tick_s, c.epoch_s, c.horizon_s, c.n_epochs, c.ticks_per_epoch) == \
        (10.0, 60.0, 1800.0, 30, 6)
    m = load_session(str(BASELINE_MISSION), []).mission
    assert m.clock.n_epochs == 30 and m.sizes.humans == 6 and m.sizes.tasks == 60


def test_sampled_scenarios_follow_section_1():
    """Humans: theta ~ U(0, pi/4), eta = sin(theta_c), skill band from theta_s; robots: half
    UAVs at 8 m/s, half UGVs at 3 m/s; POI points by estimated difficulty."""
    s = load_session(str(BASELINE_MISSION), ["mission.scenarios=50", "mission.batch_size=50"])
    sim = Simulation(s.mission, s.registry, np.arange(50))
    inherent = sim.reset()
    h = sim.sim.groups["humans"]
    assert h.theta_c.min() >= 0 and h.theta_c.max() < 0.7853981633974483
    assert h.theta_s.min() >= 0 and h.theta_s.max() < 0.7853981633974483
    np.testing.assert_allclose(h.eta, np.sin(h.theta_c))
    np.testing.assert_allclose(h.lam, np.sin(h.theta_s))
    expected_skill = np.where(h.theta_s < PI_12, 0, np.where(h.theta_s < PI_6, 1, 2))
    assert (h.skill == expected_skill).all()
    assert set(np.unique(h.skill).tolist()) == {0, 1, 2}
    r = inherent["robots"]
    assert (r.col("uav")[:, :4] == 1).all() and (r.col("ugv")[:, 4:] == 1).all()
    assert (r.col("speed")[:, :4] == 8.0).all() and (r.col("speed")[:, 4:] == 3.0).all()
    t = inherent["tasks"]
    diff = t.col("difficulty").astype(int)
    assert (t.col("points") == np.choose(diff, [15.0, 25.0, 35.0])).all()


# --- the upper bound U ---------------------------------------------------------------------------

def _tiny_sim():
    s = load_session(str(BASELINE_MISSION), ["mission.setting='custom'", "mission.humans=2", "mission.robots=2",
                            "mission.tasks=3", "mission.scenarios=2", "mission.batch_size=2"])
    sim = Simulation(s.mission, s.registry, np.arange(2))
    sim.reset()
    return sim


def test_upper_bound_hand_computed():
    """Two scenarios, 2 humans, 2 robots, 3 POIs, U worked out by hand.

    Scenario 0: robots UAV, UGV; human 0 eta 0.6 lam 0.45 (medium), human 1 eta 0.3 lam 0.7
    (high): best navigator class 2, best eta*lam = 0.27.
      P0 true air/low:     UAV-air-high = High. P_rc 0.8; P_hc 0.5+0.27*F_d(15)=0.76963
                           -> P* 0.8 -> 15 * 0.6 = 9
      P1 true ground/high: UGV-ground-high = High. P_rc 0.4; P_hc 0.5+0.27*F_d(95)
                           = 0.5+0.27*0.9677045353 = 0.7612802245 -> 35*0.522560449 = 18.2896157
      P2 true ground/medium (estimated air/low): High. P_rc 0.6; P_hc 0.5+0.27*F_d(35)
                           = 0.5+0.27*0.9969815837 = 0.7691850276 -> 25*0.538370055 = 13.4592514
      U = 9 + 18.2896157172 + 13.4592513796 = 40.7488670968
    Scenario 1: robots UGV, UGV; both humans eta 0 (P_hc = 0.5) and low skill, so the best
    navigator class is auto (1):
      P0 air/low:   UGV-air-auto = Medium, P_rc 0.6 -> 15*0.2 = 3
      P1 ground/high: Upper-Medium, P_rc 0.3 -> negative, clipped to 0
      P2 air/high:  Medium, P_rc 0.2 -> negative, clipped to 0
      U = 3 (it would be 0 if auto did not count as class 1: UGV-air-low = Low, P_rc 0.5)
    """
    sim = _tiny_sim()
    h, r, t = (sim.sim.groups[g] for g in ("humans", "robots", "tasks"))
    h.eta = np.array([[0.6, 0.3], [0.0, 0.0]])
    h.lam = np.array([[0.45, 0.7], [0.5, 0.2]])
    h.skill = np.array([[1, 2], [0, 0]])
    r.type = np.array([[0, 1], [1, 1]])
    t.true_kind = np.array([[0, 1, 1], [0, 1, 0]])
    t.true_diff = np.array([[0, 2, 1], [0, 2, 2]])
    t.est_kind = np.array([[0, 1, 0], [0, 1, 0]])
    t.est_diff = np.array([[0, 2, 0], [0, 2, 2]])
    np.testing.assert_allclose(upper_bound(sim.sim), [40.7488670968, 3.0], atol=1e-8)
    # the episode-end hook stores it in the record
    sim.pm.hook.ata_episode_end(sim=sim.sim)
    np.testing.assert_allclose(sim.sim.record.upper_bound, [40.7488670968, 3.0], atol=1e-8)


def test_upper_bound_uses_true_attributes_not_estimate():
    """One POI whose estimate (air/low) differs from its truth (ground/high) with a UAV only
    and a navigator-less, classifier-less team (eta = 0): truth gives UAV-ground-auto = Medium,
    P_rc[Medium, high] = 0.2 -> 0; the estimate would give 15 * (2*0.7 - 1) = 6."""
    sim = _tiny_sim()
    h, r, t = (sim.sim.groups[g] for g in ("humans", "robots", "tasks"))
    h.eta = np.zeros((2, 2))
    h.lam = np.full((2, 2), 0.5)
    h.skill = np.ones((2, 2), dtype=np.int64)
    r.type = np.zeros((2, 2), dtype=np.int64)
    t.est_kind = np.zeros((2, 3), dtype=np.int64)
    t.est_diff = np.zeros((2, 3), dtype=np.int64)
    t.true_kind = np.array([[1, 0, 0], [0, 0, 0]])
    t.true_diff = np.array([[2, 0, 0], [0, 0, 0]])
    # scenario 0: POI0 -> 0, POI1, POI2 air/low: UAV-air-auto = Upper-Medium, P_rc 0.7 -> 6 each
    # scenario 1: three air/low POIs -> 18
    np.testing.assert_allclose(upper_bound(sim.sim), [12.0, 18.0], atol=1e-12)
