"""The cumulative busy-time grid of a human's projected load, its formulas written once for
arrays and for numbers (`ata.model.generic`): `ata.model.load.HumanLoad` runs them on arrays,
`ata.model.scalar` compiles these same functions for the decoder's loops.

A human's grid holds, at edges ``bin_s`` apart from time 0, the seconds the human is busy from
the start of the trailing window before the plan's start to that edge; between two edges it is
read linearly. One flat array holds every human's grid, each starting at its ``base`` index.
"""

from __future__ import annotations

import numpy as np

from ata.model.generic import as_int, take


def cum_at(flat, base, last_edge, n_edges, bin_s, t):
    """Cumulative busy seconds by time `t` of the grid starting at flat[base] (linear within
    a bin; `t` held to [0, last_edge])."""
    x = np.minimum(np.maximum(t, 0.0), last_edge) / bin_s
    k = np.minimum(as_int(x), n_edges - 2)
    frac = x - k
    lo = take(flat, base + k)
    return lo + frac * (take(flat, base + k + 1) - lo)


def utilisation(flat, base, last_edge, n_edges, bin_s, window_s, t):
    """The busy share of [t - window_s, t] read from the grid (docs/model.md: "Humans")."""
    busy = (cum_at(flat, base, last_edge, n_edges, bin_s, t)
            - cum_at(flat, base, last_edge, n_edges, bin_s, t - window_s))
    span = np.minimum(window_s, np.maximum(t, 1e-9))
    return np.minimum(np.maximum(busy / span, 0.0), 1.0)


def busy_ramp(edges, a, span):
    """What booking a human busy over [a, a + span) adds to the grid at `edges`."""
    return np.minimum(np.maximum(edges - a, 0.0), span)
