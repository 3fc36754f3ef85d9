"""The humans' projected load while a plan is built step by step: when each is free, the work
booked, and from it the fatigue (the plan start's `FatigueBelief` read at the hours booked) and
the utilisation over the trailing window (docs/model.md: "Humans") at any time of the plan, in
expectation. For policies that decode an allocation member by member (the ATA-HRL decoder)."""

from __future__ import annotations

import numpy as np

from ata.model import grid, tables
from ata.model.plan import PlanStart

BIN_S = 10.0
"""Width of the time bins of the cumulative busy-time grid (`ata.model.grid`)."""


class HumanLoad:
    """The projected load of every human of E plans, (E, H), from a `PlanStart`.

    :param fatigue_now: (E, H) the fatigue estimate now (raw or reconstructed S), kept as
        ``fatigue_now`` for the decoder's features; the projection reads the start's belief
        (``start.belief``) at the hours booked.
    :param util_now: (E, H) each human's utilisation over the trailing window now, spread
        evenly over that window; the plan's bookings add to it.
    """

    def __init__(self, start: PlanStart, fatigue_now: np.ndarray, util_now: np.ndarray,
                 window_s: float):
        self.start = start
        self.window_s = window_s
        self.free = start.human_free.copy()
        self.booked = np.maximum(start.human_free - start.now, 0.0)
        self.fatigue_now = np.clip(fatigue_now, start.fatigue_floor, 1.0)
        self.util_now = np.clip(util_now, 0.0, 1.0)
        # cumulative busy seconds of each human at the grid's edges
        self.edges = np.arange(0.0, start.horizon + window_s + BIN_S, BIN_S)
        ramp = np.clip(self.edges - (start.now - window_s), 0.0, window_s)
        self.cum = self.util_now[..., None] * ramp
        # constant over the plan, and what changes only when work is booked (the fatigue
        # projections, read at every candidate of every step), computed once in between
        self.eta_lam = start.eta * start.lam
        self._eta_lam = self.eta_lam[:, None, :]
        self._fatigue: np.ndarray | None = None
        self._fatigue_greedy: np.ndarray | None = None

    def fatigue_at(self) -> np.ndarray:
        """Projected F_f of every human (E, H) after the work booked so far: the belief at the
        working hours now plus the hours booked."""
        if self._fatigue is None:
            self._fatigue = self.start.belief.at(self.start.hours + self.booked / 3600.0)
        return self._fatigue

    def fatigue_greedy(self) -> np.ndarray:
        """F_f of every human (E, H) as the greedy planner projects it: the belief at the
        working hours now plus the time until the human is free."""
        if self._fatigue_greedy is None:
            self._fatigue_greedy = self.start.belief.ahead(self.start.hours, self.free,
                                                           self.start.now)
        return self._fatigue_greedy

    def _base(self, rows: np.ndarray | None) -> np.ndarray:
        """(E, 1, H): the flat index of each human's first grid edge, for rows of plans `rows`
        (default: row i is plan i)."""
        E, H = self.free.shape
        plans = np.arange(E) if rows is None else rows
        return ((plans[:, None] * H + np.arange(H)[None, :]) * self.edges.size)[:, None, :]

    def utilisation_at(self, t: np.ndarray, rows: np.ndarray | None = None) -> np.ndarray:
        """Projected busy share of [t - window, t] of every human, t (E, N, H); `rows` as in
        `classification`."""
        return grid.utilisation(self.cum.reshape(-1), self._base(rows), self.edges[-1],
                                self.edges.size, BIN_S, self.window_s, t)

    def classification(self, q: np.ndarray, d: np.ndarray, arrive: np.ndarray,
                       greedy: bool = False, rows: np.ndarray | None = None
                       ) -> tuple[np.ndarray, ...]:
        """For every human, classifying an image of quality q and difficulty d captured at
        `arrive` (each (E, N)): (success probability, finish, begin, utilisation, F_w, F_f),
        each (E, N, H). greedy: as the greedy planner projects it (F_w = 1, utilisation and
        F_w None, F_f the belief at the working hours now plus the time until the human is
        free). `rows` (E,): the plan of each row of q, d and arrive, for a caller that asks
        about some (plan, POI) pairs only (default: row i is plan i)."""
        sel = slice(None) if rows is None else rows
        begin = np.maximum(arrive[..., None], self.free[sel][:, None, :])
        finish = begin + tables.T_BAR[q, d][..., None]
        f_d = tables.F_D[q, d][..., None]
        if greedy:
            f_f = self.fatigue_greedy()[sel][:, None, :]
            f_w = u = None
            p = tables.human_success(self._eta_lam[sel], 1.0, f_f, 1.0, f_d)
        else:
            f_f = self.fatigue_at()[sel][:, None, :]
            u = self.utilisation_at(begin, rows)
            f_w = tables.workload(u)
            p = tables.human_success(self._eta_lam[sel], 1.0, f_f, f_w, f_d)
        return p, finish, begin, u, f_w, f_f

    def take(self, rows: np.ndarray) -> "HumanLoad":
        """The load of plans `rows` alone (a copy; the grid's edges shared)."""
        out = HumanLoad.__new__(HumanLoad)
        out.start, out.window_s, out.edges = self.start.take(rows), self.window_s, self.edges
        for name in ("free", "booked", "fatigue_now", "util_now", "cum", "eta_lam",
                     "_fatigue", "_fatigue_greedy"):
            v = getattr(self, name)
            setattr(out, name, None if v is None else v[rows])
        out._eta_lam = out.eta_lam[:, None, :]
        return out

    def book(self, e: np.ndarray, h: np.ndarray, a: np.ndarray, b: np.ndarray) -> None:
        """Book human h of plan e busy over [a, b) (each (n,))."""
        self.cum[e, h] += grid.busy_ramp(self.edges[None, :], a[:, None], (b - a)[:, None])
        self.booked[e, h] += b - a
        self.free[e, h] = np.maximum(self.free[e, h], b)
        self.forget()

    def forget(self) -> None:
        """Drop the fatigue projections computed from the bookings so far (after booking in
        the load's arrays in place: `ata.model.scalar.book`)."""
        self._fatigue = self._fatigue_greedy = None
