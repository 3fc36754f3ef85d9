"""Dynamics of the built-in models (docs/model.md to 6), on tiny hand-built scenarios.

Each test builds a team of one to three humans and robots and a few POIs, overwrites the
sampled state after ``reset()`` (positions, kinds, difficulties, human traits, the pre-drawn
outcome uniforms, failure times), forces the allocation with an inline policy, and asserts on
the recorded event trace and the record with numbers worked out by hand in the comments.

Conventions: robots start at the base (1000, 1000); positions are given relative to it. Codes:
kind 0 = air, 1 = ground; difficulty 0/1/2 = low/medium/high (15/25/35 points); quality
0..3 = Low/Medium/Upper-Medium/High; robot type 0 = UAV (8 m/s), 1 = UGV (3 m/s); skill band
0/1/2 = low/medium/high (speed x 2/3, 1, 1.5). Observed positions are divided by the 2000 m side.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from _support import (AIR, GROUND, HIGH, INF, LOW, MED, UAV, UGV, Scripted, assert_trace,
                      make_sim, observed_after, perf, run_epochs, set_humans, set_robots,
                      set_tasks)


def F_D(t_bar):
    return 1.0 / (1.0 + math.exp(0.04 * (t_bar - 180.0)))


def F_W(u):
    if u < 0.45:
        return -2.47 * u * u + 2.22 * u + 0.5
    return 1.0 if u < 0.65 else -4.08 * u * u + 5.31 * u - 0.724


# --- robots: autonomous legs ----------------------------------------------------------------------

def test_autonomous_legs_capture_time_quality_onboard_outcome_and_points():
    # One UAV, two POIs, auto navigation, onboard classification, two identical scenarios that
    # differ only in the outcome uniform: just below P_rc (a win) and just above (a loss).
    sim = make_sim(([0, 0], [-1, -1], [-1, -1]), tasks=2, batch=2)
    set_robots(sim, [UAV])
    #  POI 0: 80 m east, ground, low.  80 / 8 + 3 = 13.0 s. UAV/ground/auto -> Medium (1).
    #         P_rc[Medium, low] = 0.6.
    #  POI 1: 480 m north of POI 0, air, high. leaves at 13, 480 / 8 + 3 = 63 -> 76.0 s.
    #         UAV/air/auto -> Upper-Medium (2). P_rc[Upper-Medium, high] = 0.3.
    set_tasks(sim, [(80, 0, GROUND, LOW, 0.0), (80, 480, AIR, HIGH, 0.0)])
    t = sim.sim.groups["tasks"]
    t.outcome_u[0] = [0.6 - 1e-9, 0.3 - 1e-9]
    t.outcome_u[1] = [0.6 + 1e-9, 0.3 + 1e-9]
    obs1 = observed_after(sim, 1)
    run_epochs(sim)
    assert_trace(sim.sim.trace, [
        ("allocate", 0, 2),
        ("capture", 13.0, 0, 0, 0, 1), ("capture", 13.0, 1, 0, 0, 1),
        ("capture", 76.0, 0, 0, 1, 2), ("capture", 76.0, 1, 0, 1, 2)])
    # points credited in the epoch of the (instant) onboard classification: 13 s -> epoch 0,
    # 76 s -> epoch 1; a loss costs the same points
    assert perf(sim, 0) == {0: 15.0, 1: 35.0}
    assert perf(sim, 1) == {0: -15.0, 1: -35.0}
    np.testing.assert_array_equal(sim.sim.record.total, [50.0, -50.0])
    np.testing.assert_array_equal(t.classified_at, [[13.0, 76.0]] * 2)
    np.testing.assert_array_equal(t.quality, [[1, 2]] * 2)
    # observed at t = 60: the robot is 47 s into the 60 s travel of leg 2:
    # y = 1000 + 480 * 47 / 60 = 1376 -> 0.688; x = 1080 -> 0.54. It moved all of epoch 0
    # (13 s leg, then the next leg from 13 s): idleness 0. POI 0 classified, POI 1 unvisited.
    robots, tasks = obs1["robots"], obs1["tasks"]
    assert robots.col("x")[0, 0] == pytest.approx(0.54)
    assert robots.col("y")[0, 0] == pytest.approx(0.688)
    assert robots.col("idleness")[0, 0] == pytest.approx(0.0)
    assert robots.col("target")[0, 0] == 1
    np.testing.assert_array_equal(tasks.features[0, :, :3], [[0, 0, 1], [1, 0, 0]])
    # idleness of epoch 1 (seen at t = 120): moved 60..76 = 16 s -> 1 - 16/60
    sim2 = make_sim(([0, 0], [-1, -1], [-1, -1]), tasks=2)
    set_robots(sim2, [UAV])
    set_tasks(sim2, [(80, 0, GROUND, LOW, 0.0), (80, 480, AIR, HIGH, 0.0)])
    obs2 = observed_after(sim2, 2)
    assert obs2["robots"].col("idleness")[0, 0] == pytest.approx(44 / 60)
    assert obs2["robots"].col("x")[0, 0] == pytest.approx(0.54)
    assert obs2["robots"].col("y")[0, 0] == pytest.approx(0.74)


def test_ugv_speed_and_table_one_qualities_for_auto_legs():
    # A UGV (3 m/s) and a UAV, each with one POI 90 m / 240 m away, kinds swapped against their
    # strengths: UGV on an air POI -> Medium (1); UAV on a ground POI -> Medium (1).
    # Then the favourable ones: UGV ground -> Upper-Medium (2), UAV air -> Upper-Medium (2).
    sim = make_sim(([0, 1, 0, 1], [-1] * 4, [-1] * 4), robots=2, tasks=4)
    set_robots(sim, [UGV, UAV])
    set_tasks(sim, [(90, 0, AIR, LOW, 0.0),        # UGV: 90 / 3 + 3 = 33
                    (0, 240, GROUND, LOW, 0.0),    # UAV: 240 / 8 + 3 = 33
                    (90, 150, GROUND, LOW, 0.0),   # UGV from POI 0: 150 / 3 + 3 = 53 -> 86
                    (0, 400, AIR, LOW, 0.0)])      # UAV from POI 1: 160 / 8 + 3 = 23 -> 56
    run_epochs(sim, 3)
    assert_trace(sim.sim.trace, [
        ("allocate", 0, 1),
        ("capture", 33.0, 0, 0, 0, 1), ("capture", 33.0, 0, 1, 1, 1),
        ("capture", 56.0, 0, 1, 3, 2), ("capture", 86.0, 0, 0, 2, 2)])
    # P_rc: Medium/low 0.6, Upper-Medium/low 0.7; all outcome_u = 0: all won, 15 points each
    assert perf(sim) == {0: 45.0, 1: 15.0}


def test_nearest_neighbour_order_from_where_the_robot_is():
    # POI 1 is 80 m east; POI 2 is 240 m north; POI 0 is 280 m east. From the base the order
    # by distance would be 1, 2, 0; from POI 1, POI 0 is 200 m away and POI 2 sqrt(80^2 + 240^2)
    # = 253 m, so nearest-neighbour goes 1, 0, 2.
    sim = make_sim(([0, 0, 0], [-1] * 3, [-1] * 3), tasks=3)
    set_robots(sim, [UAV])
    set_tasks(sim, [(280, 0, AIR, LOW, 0.0), (80, 0, AIR, LOW, 0.0), (0, 240, AIR, LOW, 0.0)])
    run_epochs(sim, 3)
    # 1: 80/8 + 3 = 13; 0: 13 + 200/8 + 3 = 41; 2: 41 + sqrt(280^2 + 240^2)/8 + 3
    last = 41.0 + math.hypot(280.0, 240.0) / 8.0 + 3.0
    assert_trace(sim.sim.trace, [("allocate", 0, 1), ("capture", 13.0, 0, 0, 1, 2),
                                 ("capture", 41.0, 0, 0, 0, 2), ("capture", last, 0, 0, 2, 2)])


# --- humans: navigation ---------------------------------------------------------------------------

def test_human_navigator_skill_sets_speed_and_image_quality():
    # Human 0 is highly skilled (speed x 1.5, quality one level up), human 1 low (x 2/3, one
    # level down); robot 2 drives itself. All UAVs but robot 2 (a UGV), onboard classification.
    sim = make_sim(([0, 1, 2], [0, 1, -1], [-1, -1, -1]), humans=2, robots=3, tasks=3)
    set_robots(sim, [UAV, UAV, UGV])
    set_humans(sim, [(HIGH, 0.5, 0.5, 0.0), (LOW, 0.5, 0.5, 0.0)])
    set_tasks(sim, [(120, 0, GROUND, LOW, 0.0),    # 120 / 12 + 3 = 13;  UAV/ground/high: UM (2)
                    (0, 160, AIR, LOW, 0.0),       # 160 / (16/3) + 3 = 33; UAV/air/low: Med (1)
                    (-90, 0, GROUND, LOW, 0.0)])   # UGV auto 90 / 3 + 3 = 33; UGV/ground: UM (2)
    run_epochs(sim, 2)
    # The robots ask at tick 0 (after the humans' turn), the humans take the legs at the next
    # tick from their ready time 0: the human's leg is travel + capture.
    assert_trace(sim.sim.trace, [
        ("allocate", 0, 1),
        ("start", "nav", 0.0, 0, 0, 0, 13.0), ("start", "nav", 0.0, 0, 1, 1, 33.0),
        ("capture", 13.0, 0, 0, 0, 2),
        ("capture", 33.0, 0, 1, 1, 1), ("capture", 33.0, 0, 2, 2, 2)])
    # P_rc: UM/low 0.7, Med/low 0.6 -> all won (outcome_u 0)
    assert perf(sim) == {0: 45.0}


def test_robot_waits_for_a_busy_navigator_and_the_wait_is_idleness():
    # One medium-skill human navigates both UAVs. Robot 0's leg: 560 m east, 70 + 3 = 73 s.
    # Robot 1 (POI 1, 160 m west) must wait for the human from 0 to 73; switching from robot 0
    # to robot 1 drops SA 1 -> 0.75 and costs (1 - 0.75) * 30 = 7.5 s, so its leg runs
    # 80.5 .. 80.5 + 160/8 + 3 = 103.5, and the human is busy from 73 to 103.5.
    sim = make_sim(([0, 1], [0, 0], [-1, -1]), robots=2, tasks=2)
    set_robots(sim, [UAV, UAV])
    set_humans(sim, [(MED, 0.5, 0.5, 0.25)])
    set_tasks(sim, [(560, 0, GROUND, LOW, 0.0), (-160, 0, AIR, LOW, 0.0)])
    obs1 = observed_after(sim, 1)
    r = obs1["robots"]
    # at t = 60 robot 1 still waits where it was (the base), targeting POI 1; robot 0 is at
    # 1000 + 560 * 60/70 = 1480. Epoch 0 idleness: robot 0 moved all 60 s, robot 1 none.
    np.testing.assert_allclose(r.col("x")[0], [0.74, 0.5])
    np.testing.assert_allclose(r.col("y")[0], [0.5, 0.5])
    np.testing.assert_array_equal(r.col("target")[0], [0, 1])
    np.testing.assert_allclose(r.col("idleness")[0], [0.0, 1.0])
    # POI 0's leg is under way: not reallocatable; POI 1's robot only waits: reallocatable
    np.testing.assert_array_equal(sim.last_context.reallocatable[0], [False, True])
    # human at t = 60: busy the whole 60 s, SA 1, working time 0.25 h + 60 s
    hum = obs1["humans"]
    assert hum.col("working_time")[0, 0] == pytest.approx(0.25 + 60 / 3600)
    assert hum.col("idleness")[0, 0] == pytest.approx(0.0)
    assert hum.col("sa")[0, 0] == pytest.approx(1.0)
    obs2 = observed_after(sim, 2)
    # epoch 1 (60..120): robot 0 moved 60..73 = 13 s, robot 1 80.5..103.5 = 23 s
    np.testing.assert_allclose(obs2["robots"].col("idleness")[0], [47 / 60, 37 / 60])
    np.testing.assert_allclose(obs2["robots"].col("x")[0], [0.78, 0.42])
    # human at t = 120: busy 103.5 s of the 120 elapsed; SA 0.75 + 0.1 * (120 - 73)/60
    hum = obs2["humans"]
    assert hum.col("working_time")[0, 0] == pytest.approx(0.25 + 103.5 / 3600)
    assert hum.col("idleness")[0, 0] == pytest.approx(16.5 / 120)
    assert hum.col("sa")[0, 0] == pytest.approx(0.75 + 0.1 * 47 / 60)
    assert_trace(sim.sim.trace, [
        ("allocate", 0, 1),
        ("start", "nav", 0.0, 0, 0, 0, 73.0), ("start", "nav", 73.0, 0, 0, 1, 103.5),
        ("capture", 73.0, 0, 0, 0, 1), ("capture", 103.5, 0, 1, 1, 2)])


def test_navigation_and_classification_share_one_fcfs_timeline():
    # One medium human, three UAVs.
    #  robot 0: POI 0 (80 m east, ground, high), auto, classified by the human.
    #      capture 13, quality Medium -> t_bar[Medium, high] = 195: human busy 13 .. 208.
    #  robot 1: POI 2 (240 m north, air, low), auto, onboard: capture 33 (15 points, epoch 0);
    #      then POI 1 (80 m further north, ground, low) navigated by the human: ready at 33.
    #  robot 2: POI 3 (400 m west, air, medium), auto, classified by the human: capture 53.
    # At 208 two items wait: the leg of robot 1 (ready 33) and POI 3 (ready 53): the leg first.
    #   leg: switch robot 0 -> 1, SA 1 -> 0.75, +7.5 s: 215.5 .. 215.5 + 80/8 + 3 = 228.5.
    #   POI 3 at 228.5: switch robot 1 -> 2: SA 0.75 + 0.1 * 20.5/60 - 0.25 = 0.5341667,
    #   + (1 - SA) * 30 = 13.975 s: 242.475 .. + t_bar[UM, medium] = 65 -> 307.475.
    sim = make_sim(([0, 1, 1, 2], [-1, 0, -1, -1], [0, -1, -1, 0]), robots=3, tasks=4)
    set_robots(sim, [UAV, UAV, UAV])
    set_humans(sim, [(MED, 0.5, 0.5, 0.0)])
    set_tasks(sim, [(80, 0, GROUND, HIGH, 0.0), (0, 320, GROUND, LOW, 0.0),
                    (0, 240, AIR, LOW, 0.0), (-400, 0, AIR, MED, 0.0)])
    obs3 = observed_after(sim, 3)
    # robot 1 waited at POI 2 from 33 to 215.5: still there at t = 180, idle all of epoch 2
    assert obs3["robots"].col("x")[0, 1] == pytest.approx(0.5)
    assert obs3["robots"].col("y")[0, 1] == pytest.approx(0.62)
    assert obs3["robots"].col("idleness")[0, 1] == pytest.approx(1.0)
    run_epochs(sim)
    sa2 = 0.75 + 0.1 * 20.5 / 60 - 0.25
    begin3 = 228.5 + (1 - sa2) * 30
    assert begin3 == pytest.approx(242.475)
    assert_trace(sim.sim.trace, [
        ("allocate", 0, 1),
        ("capture", 13.0, 0, 0, 0, 1),
        ("start", "classify", 13.0, 0, 0, 0, 208.0),
        ("capture", 33.0, 0, 1, 2, 2),
        ("capture", 53.0, 0, 2, 3, 2),
        ("start", "nav", 208.0, 0, 0, 1, 228.5),
        ("start", "classify", 228.5, 0, 0, 3, begin3 + 65.0),
        ("capture", 228.5, 0, 1, 1, 1)])
    # points (all outcomes won): POI 2 onboard at 33 -> epoch 0 (15); POI 0 at 208 (35) and
    # POI 1 onboard at 228.5 (15) -> epoch 3; POI 3 at 307.475 -> epoch 5 (25)
    assert perf(sim) == {0: 15.0, 3: 50.0, 5: 25.0}


# --- humans: classification -----------------------------------------------------------------------

def test_classification_probability_fatigue_and_overload():
    # A UGV navigated by a medium human (x 1) 891 m east: 891/3 + 3 = 300 s, then classified by
    # the same human (no switch) from 300 s: t_bar[UM, medium] = 65 -> 365 (epoch 6).
    #   working time T = 1.5 h + 300 s = 1.58333 h -> F_f = 1.3 - 0.3 T = 0.825;
    #   utilisation over the trailing 300 s = 300/300 = 1 -> F_w = -4.08 + 5.31 - 0.724 = 0.506;
    #   F_d = 1 / (1 + exp(0.04 (65 - 180))); P_hc = 0.5 + 0.6 * 0.825 * 0.506 * 0.5 * F_d.
    # Two scenarios bracket P_hc: outcome_u just below it wins, just above loses.
    p_hc = 0.5 + 0.6 * 0.825 * 0.506 * 0.5 * F_D(65.0)
    sim = make_sim(([0], [0], [0]), batch=2)
    set_robots(sim, [UGV])
    set_humans(sim, [(MED, 0.6, 0.5, 1.5)])
    set_tasks(sim, [(891, 0, GROUND, MED, 0.0)])
    sim.sim.groups["tasks"].outcome_u[:, 0] = [p_hc - 1e-9, p_hc + 1e-9]
    run_epochs(sim)
    assert_trace(sim.sim.trace, [
        ("allocate", 0, 2),
        ("start", "nav", 0.0, 0, 0, 0, 300.0), ("start", "nav", 0.0, 1, 0, 0, 300.0),
        ("capture", 300.0, 0, 0, 0, 2), ("capture", 300.0, 1, 0, 0, 2),
        ("start", "classify", 300.0, 0, 0, 0, 365.0),
        ("start", "classify", 300.0, 1, 0, 0, 365.0)])
    assert perf(sim, 0) == {6: 25.0}
    assert perf(sim, 1) == {6: -25.0}


def test_classification_probability_fatigue_floor_and_underload():
    # A UAV navigated by a medium human to POI 0 (80 m east, 13 s, onboard), then driving itself
    # to POI 1 (160 m further east: 13 + 23 = 36 s, air, high), which the human classifies from
    # 36 s (same robot: no switch): t_bar[UM, high] = 145 -> 181 (epoch 3).
    #   T = 4 h + 13 s -> 1.3 - 0.3 T < 0.4: F_f = 0.4 (floor);
    #   u = 13 busy s / 36 elapsed s -> rising branch of F_w.
    u = 13.0 / 36.0
    p_hc = 0.5 + 0.7 * 0.4 * F_W(u) * 0.6 * F_D(145.0)
    sim = make_sim(([0, 0], [0, -1], [-1, 0]), tasks=2, batch=2)
    set_robots(sim, [UAV])
    set_humans(sim, [(MED, 0.7, 0.6, 4.0)])
    set_tasks(sim, [(80, 0, GROUND, LOW, 0.0), (240, 0, AIR, HIGH, 0.0)])
    sim.sim.groups["tasks"].outcome_u[:, 1] = [p_hc - 1e-9, p_hc + 1e-9]
    run_epochs(sim)
    assert_trace(sim.sim.trace, [
        ("allocate", 0, 2),
        ("start", "nav", 0.0, 0, 0, 0, 13.0), ("start", "nav", 0.0, 1, 0, 0, 13.0),
        ("capture", 13.0, 0, 0, 0, 1), ("capture", 13.0, 1, 0, 0, 1),
        ("capture", 36.0, 0, 0, 1, 2), ("capture", 36.0, 1, 0, 1, 2),
        ("start", "classify", 36.0, 0, 0, 1, 181.0),
        ("start", "classify", 36.0, 1, 0, 1, 181.0)])
    assert perf(sim, 0) == {0: 15.0, 3: 35.0}
    assert perf(sim, 1) == {0: 15.0, 3: -35.0}


def test_situational_awareness_switch_cost_and_recovery():
    # One human classifies four images: POI 0, 2, 3 from robot 0 and POI 1 from robot 1.
    #   captures: POI 0 at 13 (80 m), POI 1 at 23 (160 m, robot 1), POI 2 at 26 (80 m on),
    #   POI 3 at 39 (80 m on). t_bar: Medium/low 35 for ground POIs, UM/low 25 for air POI 1.
    #   POI 0: 13 .. 48, first item, no switch, SA 1.
    #   POI 1 at 48: switch 0 -> 1: SA min(1, 1 + ...) - 0.25 = 0.75, +7.5 s: 55.5 .. 80.5.
    #   POI 2 at 80.5: switch 1 -> 0: SA 0.75 + 0.1 * 32.5/60 - 0.25 = 0.5541667,
    #       + 0.4458333 * 30 = 13.375 s: 93.875 .. 128.875.
    #   POI 3 at 128.875: same robot, no cost: 128.875 .. 163.875;
    #       SA 0.5541667 + 0.1 * 48.375/60 = 0.6347917.
    sim = make_sim(([0, 1, 0, 0], [-1] * 4, [0] * 4), robots=2, tasks=4)
    set_robots(sim, [UAV, UAV])
    set_humans(sim, [(MED, 0.5, 0.5, 0.0)])
    set_tasks(sim, [(80, 0, GROUND, LOW, 0.0), (-160, 0, AIR, LOW, 0.0),
                    (160, 0, GROUND, LOW, 0.0), (240, 0, GROUND, LOW, 0.0)])
    sa = []
    for k in (1, 2, 3):
        sa.append(observed_after(sim, k)["humans"].col("sa")[0, 0])
    obs3 = sim.last_context.observed["humans"]
    run_epochs(sim)
    # observed SA: 0.75 + 0.1 * 12/60; 0.5541667 + 0.1 * 39.5/60; 0.6347917 + 0.1 * 51.125/60
    assert sa == pytest.approx([0.77, 0.62, 0.72])
    # at t = 180: busy 35 + 32.5 + 48.375 + 35 = 150.875 s (switch costs are busy time)
    assert obs3.col("working_time")[0, 0] == pytest.approx(150.875 / 3600)
    assert obs3.col("idleness")[0, 0] == pytest.approx(1 - 150.875 / 180)
    assert obs3.col("fatigue")[0, 0] == 1.0
    # a robot's captures in one tick are logged in robot order (POI 2 at 26, then POI 1 at 23)
    assert_trace(sim.sim.trace, [
        ("allocate", 0, 1),
        ("capture", 13.0, 0, 0, 0, 1),
        ("start", "classify", 13.0, 0, 0, 0, 48.0),
        ("capture", 26.0, 0, 0, 2, 1), ("capture", 23.0, 0, 1, 1, 2),
        ("capture", 39.0, 0, 0, 3, 1),
        ("start", "classify", 48.0, 0, 0, 1, 80.5),
        ("start", "classify", 80.5, 0, 0, 2, 128.875),
        ("start", "classify", 128.875, 0, 0, 3, 163.875)])
    assert perf(sim) == {0: 15.0, 1: 15.0, 2: 30.0}


# --- uncertainty: robot failure, attribute change -------------------------------------------------

def test_robot_failure_mid_leg_aborts_the_leg_and_shows_from_the_next_epoch():
    # Robot 0 (UAV) heads for POI 0, 800 m east (would capture at 103) and fails at 70 s;
    # robot 1 captures POI 1 (80 m west) at 13. No reallocation: POI 0 scores 0.
    sim = make_sim(([0, 1], [-1, -1], [-1, -1]), robots=2, tasks=2)
    set_robots(sim, [UAV, UAV], fail_time=[70.0, INF])
    set_tasks(sim, [(800, 0, GROUND, LOW, 0.0), (-80, 0, GROUND, LOW, 0.0)])
    obs1 = observed_after(sim, 1)
    np.testing.assert_array_equal(obs1["robots"].col("working")[0], [1, 1])
    np.testing.assert_array_equal(sim.last_context.reallocatable[0], [False, False])
    obs2 = observed_after(sim, 2)
    # failed at 70: shows at the epoch after (t = 120), stopped 70/100 of the way: x = 1560
    np.testing.assert_array_equal(obs2["robots"].col("working")[0], [0, 1])
    assert obs2["robots"].col("x")[0, 0] == pytest.approx(0.78)
    np.testing.assert_array_equal(obs2["robots"].col("target")[0], [-1, -1])
    # epoch 1: robot 0 moved 60 .. 70 -> idleness 50/60
    assert obs2["robots"].col("idleness")[0, 0] == pytest.approx(50 / 60)
    # the aborted leg no longer holds POI 0: reallocatable again; POI 1 is captured
    np.testing.assert_array_equal(sim.last_context.reallocatable[0], [True, False])
    np.testing.assert_array_equal(obs2["tasks"].col("unvisited")[0], [1, 0])
    run_epochs(sim)
    assert_trace(sim.sim.trace, [("allocate", 0, 1), ("capture", 13.0, 0, 1, 1, 1),
                                 ("fail", 70.0, 0, 0)])
    t = sim.sim.groups["tasks"]
    assert t.capture_time[0, 0] == INF and t.classified_at[0, 0] == INF and t.gain[0, 0] == 0
    assert perf(sim) == {0: 15.0}
    # POI 0 stays with the failed robot for the whole episode
    np.testing.assert_array_equal(sim.sim.record.allocations[0, :, 0, 0], np.zeros(30))
    assert sim.sim.record.metrics["robot_failures"][0] == 1.0


def test_reallocation_after_a_failure_lets_another_robot_capture():
    # As above, with reallocation at every epoch ('always'). The policy moves POI 0 to robot 1
    # at epochs 1 and 2, and tries to move both POIs back to robot 0 afterwards.
    #   epoch 1 (t = 60): POI 0's leg is under way -> kept with robot 0 (0 changed);
    #   epoch 2 (t = 120): the leg was aborted at 70 -> moved to robot 1 (1 changed). Robot 1
    #     (parked at POI 1 since 13) leaves at 120: 880 m, 110 + 3 -> captures at 233 (epoch 3);
    #   epoch 3: POI 0 under way again, POI 1 captured -> nothing changes; epochs 4, 5: both
    #     captured -> nothing changes.
    def script(epoch):
        if epoch in (1, 2):
            return [1, 1], [-1, -1], [-1, -1]
        return [0, 0], [-1, -1], [-1, -1]

    policy = Scripted(script)
    sim = make_sim(([0, 1], [-1, -1], [-1, -1]), robots=2, tasks=2, condition="always",
                   reallocation=policy)
    set_robots(sim, [UAV, UAV], fail_time=[70.0, INF])
    set_tasks(sim, [(800, 0, GROUND, LOW, 0.0), (-80, 0, GROUND, LOW, 0.0)])
    run_epochs(sim, 6)
    assert_trace(sim.sim.trace, [
        ("allocate", 0, 1), ("capture", 13.0, 0, 1, 1, 1),
        ("reallocate", 1, 1, 0), ("fail", 70.0, 0, 0),
        ("reallocate", 2, 1, 1), ("reallocate", 3, 1, 0), ("capture", 233.0, 0, 1, 0, 1),
        ("reallocate", 4, 1, 0), ("reallocate", 5, 1, 0)])
    assert [e for e, _ in policy.seen] == [1, 2, 3, 4, 5]
    np.testing.assert_array_equal(np.array([m[0] for _, m in policy.seen]),
                                  [[False, False], [True, False], [False, False],
                                   [False, False], [False, False]])
    rec = sim.sim.record
    np.testing.assert_array_equal(rec.reallocated[0, :6], [False, True, True, True, True, True])
    np.testing.assert_array_equal(rec.allocations[0, :6, 0, 0], [0, 0, 1, 1, 1, 1])
    np.testing.assert_array_equal(rec.allocations[0, :6, 1, 0], [1] * 6)
    assert perf(sim) == {0: 15.0, 3: 15.0}


def test_attribute_change_outcomes_use_the_truth_and_show_when_revealed():
    # POI 0: estimated air/low, truly ground/high, revealed at 90 s; robot 0 (UAV, onboard)
    #   reaches it 1600 m east at 200 + 3 = 203 s. Quality from the true kind: UAV/ground/auto
    #   -> Medium (the estimate would give Upper-Medium); P_rc[Medium, high] = 0.2, so
    #   outcome_u = 0.5 loses 35 points (the estimate would have won 15 with P_rc 0.7).
    # POI 1: estimated ground/high, truly air/low, never revealed before its capture at 13 by
    #   robot 1; the human classifies it from 13 for t_bar[UM, low] = 25 s (estimate: 195 s).
    sim = make_sim(([0, 1], [-1, -1], [-1, 0]), robots=2, tasks=2)
    set_robots(sim, [UAV, UAV])
    set_humans(sim, [(MED, 0.5, 0.5, 0.0)])
    set_tasks(sim, [(1600, 0, GROUND, HIGH, 0.5), (0, 80, AIR, LOW, 0.0)])
    t = sim.sim.groups["tasks"]
    t.est_kind[0] = [AIR, GROUND]
    t.est_diff[0] = [LOW, HIGH]
    t.reveal_time[0] = [90.0, INF]
    seen = [observed_after(sim, k)["tasks"] for k in range(5)]
    # observed (kind, difficulty) per epoch: the estimate until revealed (POI 0 at 90 s, so
    # from t = 120; POI 1 by its capture at 13, so from t = 60)
    kinds = [np.stack([tab.col("kind")[0], tab.col("difficulty")[0]], axis=-1).tolist()
             for tab in seen]
    assert kinds == [[[AIR, LOW], [GROUND, HIGH]],
                     [[AIR, LOW], [AIR, LOW]],
                     [[GROUND, HIGH], [AIR, LOW]],
                     [[GROUND, HIGH], [AIR, LOW]],
                     [[GROUND, HIGH], [AIR, LOW]]]
    run_epochs(sim)
    assert_trace(sim.sim.trace, [
        ("allocate", 0, 1), ("capture", 13.0, 0, 1, 1, 2),
        ("start", "classify", 13.0, 0, 0, 1, 38.0), ("capture", 203.0, 0, 0, 0, 1)])
    assert perf(sim) == {0: 15.0, 3: -35.0}


def test_a_human_never_starts_navigating_a_robot_that_has_failed():
    # The human navigates robot 0 to POI 0 (816 m east: 102 + 3 = 105 s) while robot 1 waits
    # for it (POI 1); robot 1 fails at 102, before the human is free at 105. The human must not
    # take robot 1's leg: it goes on to classify POI 0 (captured at 105, same robot, no switch,
    # t_bar[Medium, low] = 35) from 105.
    sim = make_sim(([0, 1], [0, 0], [0, -1]), robots=2, tasks=2)
    set_robots(sim, [UAV, UAV], fail_time=[INF, 102.0])
    set_humans(sim, [(MED, 0.5, 0.5, 0.0)])
    set_tasks(sim, [(816, 0, GROUND, LOW, 0.0), (0, 80, GROUND, LOW, 0.0)])
    obs = observed_after(sim, 3)
    run_epochs(sim)
    assert_trace(sim.sim.trace, [
        ("allocate", 0, 1), ("start", "nav", 0.0, 0, 0, 0, 105.0),
        ("capture", 105.0, 0, 0, 0, 1), ("fail", 102.0, 0, 1),
        ("start", "classify", 105.0, 0, 0, 0, 140.0)])
    assert obs["humans"].col("sa")[0, 0] == pytest.approx(1.0)
    assert obs["humans"].col("working_time")[0, 0] == pytest.approx(140 / 3600)
    assert perf(sim) == {2: 15.0}


def test_expected_score_is_the_score_without_the_outcome_draws():
    # per scenario, expected_score sums each classification's expected points; over scenarios it
    # is an unbiased estimate of the score (the draws change nothing else), with less spread
    from ata.session import BASELINE_MISSION, load_session
    from ata.experiment.runner import run_mission
    r = run_mission(load_session(str(BASELINE_MISSION), ["mission.scenarios=200",
                                                         "mission.batch_size=200"]))
    expected, score = r.metrics["expected_score"], r.total
    diff = score - expected
    assert abs(diff.mean()) < 4 * diff.std(ddof=1) / np.sqrt(diff.size)
    assert diff.std() > 1.0                  # the draws do move the score
    assert expected.std() < score.std()
