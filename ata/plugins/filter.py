"""The filter reconstructor: a classical estimate of S, with no learning (a grid posterior over
each human's hidden fatigue curve; the last fresh robot and task rows and their age).

Humans (docs/model.md, "Humans"). Each human's fatigue curve has a hidden onset
and slope, drawn uniformly over the public prior's ranges (`onset_range`, `slope_range` of the
published ``HumanConstants.fatigue_spread``). The filter keeps, per scenario and human, a
posterior over a grid of K = onsets x slopes curves at the midpoints of equal cells of those
ranges (one curve when the spread is 0). S shows the working time T exactly and the fatigue as
F_f(T) + N(0, sigma^2), drawn afresh at each epoch, so every epoch multiplies each curve's weight
by the Gaussian likelihood of the observation given that curve's F_f at T. It writes:

* ``humans``: the observed rows with ``fatigue`` replaced by the posterior mean of F_f now;
* the `BELIEF_KEYS` (each (B, H, K)): the grid's onsets and slopes (read-only views) and the
  normalised weights, which a planner turns into a `FatigueBelief` (`belief_from`) to project
  F_f ahead as work is booked.

sigma^2 is the filter's own ``variance`` if set, else the one the ``fatigue_noise`` injector
resolves (its ``variance``, else the mission's level), else 0 when the mission injects no
fatigue noise. A zero-noise observation would make the likelihood degenerate, so sigma is at
least ``sigma_floor``: one exact observation then leaves weight only on the curves within a few
floors of it.

Robots and tasks. Latency replaces a row, with probability p, by the one observed an epoch
before, so the observed row is already the last fresh one: the filter passes it on (``robots``,
``tasks``) with its age (``robots_age`` (B, R), ``tasks_age`` (B, P), floats): the epochs since
the row last changed. A row that changed was fresh, so the age is an upper bound on how stale
the row is; it is exact for a row that changes whenever it is fresh (a moving robot) and
overstates it for one that stands still. No dead reckoning: a robot with a human navigator
waits for that human's timeline, and the route may not be straight, so moving a stale position
toward the target would not be clearly right.

State lives on the instance (the kernel builds one per batch) and is reset at epoch 0. It reads
its arguments alone: the observation, the epoch and the published human constants.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ata import hookimpl
from ata.core.settings import param
from ata.core.state import DecisionView, Observation
from ata.model.fatigue import BELIEF_KEYS, individual, onset_range, slope_range
from ata.model.team import HumanConstants

STALE_GROUPS = ("robots", "tasks")
"""The groups whose rows the latency may hold back (docs/model.md: "Uncertainty")."""


def noise_variance(mission) -> float:
    """The fatigue noise variance the mission injects: the ``fatigue_noise`` injector's
    resolved value (its ``variance``, else the level's), 0 when it is not among the
    injectors."""
    if "fatigue_noise" not in mission.slots.injectors:
        return 0.0
    own = mission.component_settings.get("fatigue_noise")
    if own is not None and own.variance is not None:
        return float(own.variance)
    return float(mission.fatigue_variance)


def cell_midpoints(low: float, high: float, n: int) -> np.ndarray:
    """The midpoints of n equal cells of [low, high]: a uniform prior's quadrature points; one
    point when the range is empty."""
    if high <= low:
        return np.array([float(low)])
    return low + (np.arange(n) + 0.5) * ((high - low) / n)


def prior_grid(spread: float, onsets: int, slopes: int) -> tuple[np.ndarray, np.ndarray]:
    """(onset, slope), each (K,), of the grid over the public prior of spread s: K = onsets x
    slopes, onset-major; K = 1 (the population curve) when s = 0."""
    on = cell_midpoints(*onset_range(spread), onsets)
    sl = cell_midpoints(*slope_range(spread), slopes)
    on, sl = np.meshgrid(on, sl, indexing="ij")
    return on.ravel(), sl.ravel()


class FilterReconstructor:
    """A grid posterior over each human's fatigue curve, and the age of each robot and task
    row (see the module's docstring)."""

    @dataclass
    class Settings:
        onsets: int = param(15, min=1, max=201, help="grid points over the prior's onset range")
        slopes: int = param(15, min=1, max=201, help="grid points over the prior's slope range")
        variance: float | None = param(None, min=0.0, max=10.0,
                                       help="fatigue noise variance it assumes; default: the "
                                            "fatigue_noise injector's (0 without it)")
        # below the smallest gap (4.4e-4) between the distinct values the default grid's curves
        # take at one working time, so that an exact observation singles out the curves that
        # agree with it
        sigma_floor: float = param(1e-4, min=1e-9, max=1.0,
                                   help="least noise standard deviation it assumes, so that "
                                        "an exact observation keeps the curves within a few "
                                        "of this of it")
        observe: bool = param(True, help="weigh the fatigue observations (false: the prior "
                                         "alone, a yardstick of what the observations add)")

    def __init__(self, settings: "FilterReconstructor.Settings", mission):
        self.settings = settings
        variance = (settings.variance if settings.variance is not None
                    else noise_variance(mission))
        self.variance = max(float(variance), settings.sigma_floor ** 2)
        self.onset: np.ndarray | None = None       # (K,) the grid, the same for every human
        self.slope: np.ndarray | None = None
        self.floor = 0.0
        self.log_weight: np.ndarray | None = None  # (B, H, K), normalised
        self.rows: dict[str, np.ndarray] = {}      # the rows seen at the epoch before
        self.age: dict[str, np.ndarray] = {}

    def _reset(self, sim: DecisionView, batch: int, humans: int) -> None:
        constants = sim.published(HumanConstants)
        self.floor = constants.fatigue_floor
        self.onset, self.slope = prior_grid(constants.fatigue_spread, self.settings.onsets,
                                            self.settings.slopes)
        k = self.onset.size
        self.log_weight = np.full((batch, humans, k), -np.log(k))
        self.rows, self.age = {}, {}

    @hookimpl
    def ata_reconstruct(self, sim: DecisionView, obs: Observation, inherent: Observation,
                        out: dict[str, np.ndarray]) -> None:
        humans = obs["humans"]
        batch, count = humans.features.shape[:2]
        unknown = self.log_weight is None or self.log_weight.shape[:2] != (batch, count)
        if sim.epoch == 0 or unknown:
            self._reset(sim, batch, count)
        hours = humans.col("working_time")
        curves = individual(hours[..., None], self.onset, self.slope, self.floor)  # (B, H, K)
        miss = humans.col("fatigue")[..., None] - curves
        log_w = self.log_weight - (0.5 * miss * miss / self.variance
                                   if self.settings.observe else 0.0)
        top = log_w.max(-1, keepdims=True)
        # normalised in the log domain, so that weights never underflow over the epochs
        log_w -= top + np.log(np.exp(log_w - top).sum(-1, keepdims=True))
        self.log_weight = log_w
        weight = np.exp(log_w)
        weight /= weight.sum(-1, keepdims=True)
        rows = humans.copy()
        rows.set("fatigue", (weight * curves).sum(-1))
        out["humans"] = rows.features
        shape = weight.shape
        on_key, slope_key, weight_key = BELIEF_KEYS
        out[on_key] = np.broadcast_to(self.onset, shape)
        out[slope_key] = np.broadcast_to(self.slope, shape)
        out[weight_key] = weight
        for group in STALE_GROUPS:
            if group in obs:
                self._age(group, obs[group].features, out)

    def _age(self, group: str, rows: np.ndarray, out: dict[str, np.ndarray]) -> None:
        """The observed rows of `group` and the epochs since each last changed."""
        before = self.rows.get(group)
        if before is None or before.shape != rows.shape:
            age = np.zeros(rows.shape[:2])
        else:
            age = np.where((rows == before).all(-1), self.age[group] + 1.0, 0.0)
        self.rows[group], self.age[group] = rows.copy(), age
        out[group] = rows.copy()
        out[f"{group}_age"] = age.copy()


@hookimpl
def ata_register_components(register) -> None:
    register("reconstructor", "filter", FilterReconstructor)
