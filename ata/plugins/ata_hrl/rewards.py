"""The paper's hierarchical rewards (docs/model.md: "Rewards"), computed from an episode's record.

    R_ITA = sum_t r_t - 0.2 * sum_{t >= 1, reallocated} ||a(t) - a_ITA||_F
    R_C   = sum_t r_t + sum Delta r - 0.4 * F_realloc / T
    R_TR  = sum_t r_t + sum Delta r - 0.2 * sum_{t reallocated} ||a(t) - a(t-1)||_F / T

Delta r is, at each reallocation epoch, r at that epoch minus r at the previous reallocation
epoch (the initial allocation, epoch 0, for the first one).

``r_t`` is the points the team gained in epoch t (``record.r_perf``), or, for training, their
expectation given how each classification was made (``record.r_expected``): the outcome draws
do not change what happens next, so this removes their noise from the reward without changing
its expectation.
"""

from __future__ import annotations

import numpy as np

from ata.core.state import Allocation, EpisodeRecord, frobenius_change


def _alloc(record: EpisodeRecord, t: int) -> Allocation:
    return Allocation.from_stack(record.allocations[:, t])


def delta_performance(r: np.ndarray, reallocated: np.ndarray) -> np.ndarray:
    """sum over reallocation epochs of r(t) - r(previous reallocation epoch), (B,)."""
    realloc = reallocated.copy()
    realloc[:, 0] = False
    T = r.shape[1]
    epochs = np.where(realloc, np.arange(T), 0)
    last = np.maximum.accumulate(epochs, axis=1)               # latest realloc epoch <= t
    prev = np.concatenate([np.zeros((r.shape[0], 1), dtype=int), last[:, :-1]], axis=1)
    deltas = r - np.take_along_axis(r, prev, axis=1)
    return np.where(realloc, deltas, 0.0).sum(axis=1)


def hierarchical_rewards(record: EpisodeRecord, expected: bool = False) -> dict[str, np.ndarray]:
    """R_ITA, R_C and R_TR per scenario, plus the total team performance (of r_perf, or of
    r_expected with ``expected``)."""
    r = record.r_expected if expected else record.r_perf
    B, T = r.shape
    total = r.sum(axis=1)
    realloc = record.reallocated.copy()
    realloc[:, 0] = False
    ita = _alloc(record, 0)
    from_ita = np.zeros(B)
    step_change = np.zeros(B)
    for t in range(1, T):
        if not realloc[:, t].any():
            continue
        now = _alloc(record, t)
        from_ita += np.where(realloc[:, t], frobenius_change(now, ita), 0.0)
        step_change += np.where(realloc[:, t], frobenius_change(now, _alloc(record, t - 1)), 0.0)
    delta = delta_performance(r, record.reallocated)
    n_realloc = realloc.sum(axis=1)
    return {"total": total,
            "R_ITA": total - 0.2 * from_ita,
            "R_C": total + delta - 0.4 * n_realloc / T,
            "R_TR": total + delta - 0.2 * step_change / T}


def to_go(x: np.ndarray) -> np.ndarray:
    """(B, T) per-epoch terms summed from each epoch to the end."""
    return np.flip(np.cumsum(np.flip(x, 1), 1), 1)


def rewards_to_go(record: EpisodeRecord, expected: bool = False) -> dict[str, np.ndarray]:
    """R_C and R_TR from each epoch on, (B, T): each reward is a sum of per-epoch terms (the
    points of epoch t', its Delta r if it reallocated, its share of the penalty), and a decision
    at epoch t is credited with the terms of epochs t' >= t only, which it can change; the
    sum at t = 1 is the reward of ``hierarchical_rewards`` less epoch 0's points. The same
    rewards, without the noise of what happened before the decision."""
    r = record.r_expected if expected else record.r_perf
    B, T = r.shape
    realloc = record.reallocated.copy()
    realloc[:, 0] = False
    epochs = np.where(realloc, np.arange(T), 0)
    last = np.maximum.accumulate(epochs, axis=1)
    prev = np.concatenate([np.zeros((B, 1), dtype=int), last[:, :-1]], axis=1)
    delta = np.where(realloc, r - np.take_along_axis(r, prev, axis=1), 0.0)
    change = np.zeros((B, T))
    for t in range(1, T):
        if realloc[:, t].any():
            change[:, t] = np.where(realloc[:, t], frobenius_change(_alloc(record, t),
                                                                   _alloc(record, t - 1)), 0.0)
    return {"R_C": to_go(r + delta - 0.4 * realloc / T),
            "R_TR": to_go(r + delta - 0.2 * change / T)}
