"""The human model: P_hc, classification time, fatigue, workload, situational awareness, and one
first-come-first-served busy timeline per human (docs/model.md: "Humans").

Each human tires on an individual curve (`ata.model.fatigue.individual`): an onset and a slope
drawn at set-up within the ranges ``fatigue_spread`` sets, hidden from every decision-maker
(neither inherent information nor observed state). With ``fatigue_spread = 0`` every human has
the testbed's population line (`ata.model.tables.fatigue`), to the bit.

It owns group ``humans`` (`HumanState`).

A reallocation that changes a human's work (an item gained or lost, as navigator or classifier,
that had not started) re-briefs that human: busy for ``rebrief_s`` before the next item, and SA
drops as on a switch of robot (docs/model.md: "Re-tasking cost"); ``rebriefs`` counts them.

At set-up it publishes its constants for the policies, a `HumanConstants` (``sim.publish``).

Work items come through queues, into the human model's own lists of pending items:

* ``humans.classify`` (from the task model): ``b, p, ready, human, robot, quality,
  difficulty``, an image waiting for its human classifier since its capture;
* ``humans.navigate`` (from the robot model): ``b, r, ready, human, duration, deadline``, robot
  r's next leg waiting for its navigator (``ready = inf`` withdraws it; the robot fails at
  ``deadline``, after which the leg cannot start).

Each human takes the earliest-ready item among those addressed to them. Starting a leg goes to
``robots.leg_started`` (``b, r, begin, end``); a classification, once made, to
``tasks.classified`` (``b, p, time, p_ok``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ata import hookimpl
from ata.core.settings import param
from ata.core.queues import last_per_key, run_starts, scatter
from ata.core.state import Allocation, Observation, SimState
from ata.model import fatigue, tables, team
from ata.model.retask import retasked_humans
from ata.model.team import HumanConstants

HUMAN_INHERENT = ("cognitive", "expertise", "skill")
HUMAN_STATE = ("working_time", "fatigue", "idleness", "sa")


@dataclass
class HumanState:
    """Per scenario and human, (B, H) unless said."""

    theta_c: np.ndarray           # cognitive angle; eta = sin(theta_c)
    theta_s: np.ndarray           # expertise angle; lam = sin(theta_s)
    eta: np.ndarray
    lam: np.ndarray
    skill: np.ndarray             # skill band 0..2 (low, medium, high)
    t0_h: np.ndarray              # working hours at the start
    fatigue_onset: np.ndarray     # the hidden individual fatigue curve: onset, hours of work,
    fatigue_slope: np.ndarray     # and slope per hour after it
    busy_until: np.ndarray        # end of the last item booked
    booked_s: np.ndarray          # busy seconds booked so far
    busy_ticks: np.ndarray        # (B, H, n_ticks) busy seconds in each tick
    sa: np.ndarray                # situational awareness at sa_time
    sa_time: np.ndarray
    last_robot: np.ndarray        # the robot of the last item (-1: none)
    cls_count: np.ndarray         # classifications made, and under which conditions
    cls_fatigued: np.ndarray
    cls_u_low: np.ndarray
    cls_u_high: np.ndarray
    rebriefs: np.ndarray
    # pending work, (B, P) per POI and (B, R) per robot
    cls_ready: np.ndarray         # when POI p's image waits for its classifier (inf: none)
    cls_human: np.ndarray
    cls_robot: np.ndarray
    cls_quality: np.ndarray
    cls_diff: np.ndarray
    nav_ready: np.ndarray         # when robot r's next leg waits for its navigator (inf: none)
    nav_human: np.ndarray
    nav_duration: np.ndarray
    nav_deadline: np.ndarray      # the robot's failure time: the leg cannot start after it


class HumanModel:
    """Humans on site, with the performance model of docs/model.md, "Humans"."""

    @dataclass
    class Settings:
        theta_max: float = param(np.pi / 4, min=0.0, max=np.pi / 2,
                                 help="theta_c, theta_s ~ U(0, theta_max)")
        t0_max_h: float = param(1.5, min=0.0, max=24.0,
                                help="initial working hours ~ U(0, t0_max_h)")
        fatigue_floor: float = param(team.FATIGUE_FLOOR, min=0.0, max=1.0, help="lowest F_f")
        # above 1.5 the lowest slope, 0.3 (1 - 2s/3), would not be positive
        fatigue_spread: float = param(fatigue.FATIGUE_SPREAD, min=0.0, max=1.5,
                                      help="spread s of the hidden individual fatigue onsets "
                                           "and slopes (0: everyone on the population line)")
        window_s: float = param(team.WINDOW_S, min=1.0, help="utilisation window in seconds")
        sa_drop: float = param(team.SA_DROP, min=0.0, max=1.0, help="SA lost on switching robot")
        sa_recovery_per_min: float = param(team.SA_RECOVERY_PER_MIN, min=0.0, max=1.0,
                                           help="SA regained a minute")
        switch_cost_s: float = param(team.SWITCH_COST_S, min=0.0,
                                     help="extra busy time (1 - SA) * this")
        rebrief_s: float = param(team.REBRIEF_S, min=0.0, max=3600.0,
                                 help="re-briefing time of a human whose work a reallocation "
                                      "changes, s (0: reallocation costs humans nothing)")

    def __init__(self, settings: "HumanModel.Settings", mission: object):
        self.settings = s = settings
        self.constants = HumanConstants(
            fatigue_floor=s.fatigue_floor, fatigue_spread=s.fatigue_spread, window_s=s.window_s,
            sa_drop=s.sa_drop, sa_recovery_per_min=s.sa_recovery_per_min,
            switch_cost_s=s.switch_cost_s, rebrief_s=s.rebrief_s)

    @hookimpl
    def ata_setup(self, sim: SimState) -> None:
        B, H, s = sim.batch_size, sim.sizes.humans, self.settings
        P, R = sim.sizes.tasks, sim.sizes.robots
        sim.publish(self.constants)
        theta_c = sim.rng.uniform("humans.theta_c", 0, (H,)) * s.theta_max
        theta_s = sim.rng.uniform("humans.theta_s", 0, (H,)) * s.theta_max
        # streams of their own, so every other draw is what it was before individual fatigue
        on_lo, on_hi = fatigue.onset_range(s.fatigue_spread)
        sl_lo, sl_hi = fatigue.slope_range(s.fatigue_spread)
        onset = on_lo + sim.rng.uniform("humans.fatigue_onset", 0, (H,)) * (on_hi - on_lo)
        slope = sl_lo + sim.rng.uniform("humans.fatigue_slope", 0, (H,)) * (sl_hi - sl_lo)
        self.state = sim.own("humans", HumanState(
            theta_c=theta_c, theta_s=theta_s, eta=np.sin(theta_c), lam=np.sin(theta_s),
            skill=tables.skill_band(theta_s),
            t0_h=sim.rng.uniform("humans.t0", 0, (H,)) * s.t0_max_h,
            fatigue_onset=onset, fatigue_slope=slope,
            busy_until=np.zeros((B, H)), booked_s=np.zeros((B, H)),
            busy_ticks=np.zeros((B, H, sim.clock.n_ticks)), sa=np.ones((B, H)),
            sa_time=np.zeros((B, H)), last_robot=np.full((B, H), -1, dtype=np.int64),
            cls_count=np.zeros((B, H)), cls_fatigued=np.zeros((B, H)),
            cls_u_low=np.zeros((B, H)), cls_u_high=np.zeros((B, H)), rebriefs=np.zeros((B, H)),
            cls_ready=np.full((B, P), np.inf), cls_human=np.full((B, P), -1, dtype=np.int64),
            cls_robot=np.full((B, P), -1, dtype=np.int64),
            cls_quality=np.full((B, P), -1, dtype=np.int64),
            cls_diff=np.full((B, P), -1, dtype=np.int64),
            nav_ready=np.full((B, R), np.inf), nav_human=np.full((B, R), -1, dtype=np.int64),
            nav_duration=np.zeros((B, R)), nav_deadline=np.full((B, R), np.inf)))
        self._edges = np.arange(sim.clock.n_ticks) * sim.clock.tick_s

    @hookimpl
    def ata_inherent(self, sim: SimState, inherent: Observation) -> None:
        h = self.state
        inherent.add("humans", HUMAN_INHERENT,
                     np.stack([h.eta, h.lam, h.skill], axis=-1).astype(np.float64))

    @hookimpl
    def ata_observe(self, sim: SimState, obs: Observation) -> None:
        h, s, now, tick = self.state, self.settings, sim.now, sim.clock.tick_s
        hours = tables.working_hours(h.t0_h, h.busy_ticks, now, tick)
        sa = tables.awareness(h.sa, h.sa_time, now, s.sa_recovery_per_min)
        feats = np.stack([hours, self._fatigue(hours, ...),
                          1.0 - tables.utilisation(h.busy_ticks, now, tick, s.window_s), sa],
                         axis=-1)
        obs.add("humans", HUMAN_STATE, feats)
        for key, curve in zip(fatigue.CURVE_KEYS, (h.fatigue_onset, h.fatigue_slope)):
            obs.hide(key, curve.copy())

    def _fatigue(self, hours: np.ndarray, rows) -> np.ndarray:
        """True F_f at working time `hours` of the humans `rows` ((b, h) index arrays, or ...
        for all), on their individual curves."""
        h = self.state
        return fatigue.individual(hours, h.fatigue_onset[rows], h.fatigue_slope[rows],
                                  self.settings.fatigue_floor)

    def _take_work(self, sim: SimState) -> None:
        """Add the items the queues bring to the pending lists."""
        h = self.state
        cls = sim.queue("humans.classify").take()
        if cls is not None:
            scatter(h, cls, ("b", "p"), {"cls_ready": "ready", "cls_human": "human",
                                         "cls_robot": "robot", "cls_quality": "quality",
                                         "cls_diff": "difficulty"})
        nav = sim.queue("humans.navigate").take()
        if nav is not None:
            last = last_per_key(nav["b"], nav["r"])      # a later request replaces an earlier
            scatter(h, {k: v[last] for k, v in nav.items()}, ("b", "r"),
                    {"nav_ready": "ready", "nav_human": "human", "nav_duration": "duration",
                     "nav_deadline": "deadline"})

    @hookimpl
    def ata_advance(self, sim: SimState, t0: float, t1: float) -> None:
        self._take_work(sim)
        h = self.state
        H = sim.sizes.humans
        for _ in range(64):
            cb, cp = np.nonzero(h.cls_ready < t1)
            nb, nr = np.nonzero(h.nav_ready < t1)
            # a robot that fails before its navigator could take the leg has no leg left (its
            # failure is processed after this hook in the same tick): never start it
            can_start = np.maximum(h.busy_until[nb, h.nav_human[nb, nr]], h.nav_ready[nb, nr])
            alive = h.nav_deadline[nb, nr] > can_start
            nb, nr = nb[alive], nr[alive]
            if cb.size == 0 and nb.size == 0:
                return
            b = np.concatenate([cb, nb])
            entity = np.concatenate([cp, nr])
            is_nav = np.concatenate([np.zeros(cb.size, bool), np.ones(nb.size, bool)])
            owner = np.concatenate([h.cls_human[cb, cp], h.nav_human[nb, nr]])
            ready = np.concatenate([h.cls_ready[cb, cp], h.nav_ready[nb, nr]])
            key = b * H + owner
            # first come, first served; ties: classifications first, then the lower index
            order = np.lexsort((entity, is_nav, ready, key))
            first = order[run_starts(key[order])]     # each owner's first item in the order
            sb, sh = b[first], owner[first]
            start = np.maximum(h.busy_until[sb, sh], ready[first])
            ok = start < t1
            if not ok.any():
                return
            first, sb, sh, start = first[ok], sb[ok], sh[ok], start[ok]
            self._start_items(sim, sb, sh, start, entity[first], is_nav[first])
            # only a human whose new item ends within the tick may start another: the others
            # were busy past t1 already, or had nothing ready
            if not (h.busy_until[sb, sh] < t1).any():
                return

    def _start_items(self, sim: SimState, b: np.ndarray, hh: np.ndarray, start: np.ndarray,
                     entity: np.ndarray, is_nav: np.ndarray) -> None:
        """Start one work item for each (b, h) pair given: book it and apply its effects."""
        h, s = self.state, self.settings
        cls = ~is_nav
        robot = np.where(is_nav, entity, h.cls_robot[b, np.where(cls, entity, 0)])
        # situational awareness: recover since the last update, drop on a switch of robot
        sa = np.minimum(1.0, h.sa[b, hh] + s.sa_recovery_per_min * (start - h.sa_time[b, hh]) / 60)
        last = h.last_robot[b, hh]
        switch = (last >= 0) & (last != robot)
        sa = np.where(switch, np.maximum(0.0, sa - s.sa_drop), sa)
        begin = start + np.where(switch, (1.0 - sa) * s.switch_cost_s, 0.0)

        duration = np.empty(b.size)
        # navigation legs: the robot moves from `begin`
        if is_nav.any():
            nb, nr = b[is_nav], entity[is_nav]
            duration[is_nav] = h.nav_duration[nb, nr]
            sim.queue("robots.leg_started").put(b=nb, r=nr, begin=begin[is_nav],
                                                end=begin[is_nav] + duration[is_nav])
            h.nav_ready[nb, nr] = np.inf
        if cls.any():
            cb, cp, ch = b[cls], entity[cls], hh[cls]
            q, d = h.cls_quality[cb, cp], h.cls_diff[cb, cp]
            duration[cls] = tables.T_BAR[q, d]
            hours = h.t0_h[cb, ch] + h.booked_s[cb, ch] / 3600.0
            u = self._utilisation_at(sim, cb, ch, start[cls])
            f_f = self._fatigue(hours, (cb, ch))
            p_ok = tables.human_success(h.eta[cb, ch], h.lam[cb, ch], f_f, tables.workload(u),
                                        tables.F_D[q, d])
            sim.queue("tasks.classified").put(b=cb, p=cp, time=begin[cls] + duration[cls],
                                              p_ok=p_ok)
            h.cls_ready[cb, cp] = np.inf
            h.cls_count[cb, ch] += 1
            h.cls_fatigued[cb, ch] += f_f < tables.FATIGUED_BELOW
            h.cls_u_low[cb, ch] += u < tables.WORKLOAD_PLATEAU[0]
            h.cls_u_high[cb, ch] += u >= tables.WORKLOAD_PLATEAU[1]
        end = begin + duration
        self._book(sim, b, hh, start, end)
        h.sa[b, hh] = sa
        h.sa_time[b, hh] = start
        h.last_robot[b, hh] = robot
        if sim.trace is not None:
            for i in range(b.size):
                sim.log("start", "nav" if is_nav[i] else "classify", float(start[i]), int(b[i]),
                        int(hh[i]), int(entity[i]), float(end[i]))

    def _book(self, sim: SimState, b: np.ndarray, hh: np.ndarray, start: np.ndarray,
              end: np.ndarray) -> None:
        """Book [start, end) as busy time of the given (b, h) pairs (each pair at most once)."""
        h = self.state
        overlap = np.clip(np.minimum(end[:, None], self._edges + sim.clock.tick_s)
                          - np.maximum(start[:, None], self._edges), 0.0, None)
        h.busy_ticks[b, hh] += overlap
        h.booked_s[b, hh] += end - start
        h.busy_until[b, hh] = end

    @hookimpl
    def ata_allocation_changed(self, sim: SimState, changed: np.ndarray,
                               previous: Allocation | None) -> None:
        """Re-brief every human whose work the reallocation changes (docs/model.md).

        Only tasks not yet captured may change, so every navigation leg or classification that
        moves between humans had not started. A human re-briefed is busy for ``rebrief_s`` from
        the end of the item in hand (or now), and loses ``sa_drop`` of SA as on a switch.
        """
        s = self.settings
        if previous is None or s.rebrief_s <= 0:
            return
        touched = retasked_humans(previous, sim.allocation, changed, sim.sizes.humans)
        b, hh = np.nonzero(touched)
        if b.size == 0:
            return
        h = self.state
        start = np.maximum(h.busy_until[b, hh], sim.now)
        sa = np.minimum(1.0, h.sa[b, hh] + s.sa_recovery_per_min * (start - h.sa_time[b, hh])
                        / 60.0)
        self._book(sim, b, hh, start, start + s.rebrief_s)
        h.sa[b, hh] = np.maximum(0.0, sa - s.sa_drop)
        h.sa_time[b, hh] = start
        h.rebriefs[b, hh] += 1
        if sim.trace is not None:
            for i in range(b.size):
                sim.log("rebrief", float(start[i]), int(b[i]), int(hh[i]),
                        float(start[i] + s.rebrief_s))

    def _utilisation_at(self, sim: SimState, b: np.ndarray, hh: np.ndarray,
                        start: np.ndarray) -> np.ndarray:
        """Busy share of [start - window, start] for the given pairs; every booked item ends by
        `start`, so the busy time of a tick before it is all inside the window's range. The
        window's first tick is the first one wholly inside it (a tick straddling its lower edge
        is left out)."""
        h, tick, window = self.state, sim.clock.tick_s, self.settings.window_s
        k_hi = np.floor(start / tick).astype(np.int64) + 1
        k_lo = np.maximum(0, np.ceil((start - window) / tick).astype(np.int64))
        idx = np.arange(sim.clock.n_ticks)
        inside = (idx >= k_lo[:, None]) & (idx < k_hi[:, None])
        busy = (h.busy_ticks[b, hh] * inside).sum(axis=1)
        span = np.minimum(window, start)
        return np.where(span > 0, np.minimum(1.0, busy / np.maximum(span, 1e-9)), 0.0)

    @hookimpl
    def ata_episode_end(self, sim: SimState) -> None:
        h, m = self.state, sim.record.metrics
        n = np.maximum(h.cls_count.sum(axis=1), 1)
        m["human_classifications"] = h.cls_count.sum(axis=1)
        m["fatigued_share"] = h.cls_fatigued.sum(axis=1) / n
        m["underloaded_share"] = h.cls_u_low.sum(axis=1) / n
        m["overloaded_share"] = h.cls_u_high.sum(axis=1) / n
        m["rebriefs"] = h.rebriefs.sum(axis=1)


@hookimpl
def ata_register_components(register) -> None:
    register("human_model", "human", HumanModel)
