"""Task attribute change: with probability p a POI's true kind or difficulty differs from the
satellite estimate; the truth shows at a uniform random time, or at capture if sooner. The
changes go to the task model through the queue ``tasks.attribute_change``."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ata import hookimpl
from ata.core.settings import param
from ata.core.state import SimState


class AttributeChange:
    """docs/model.md. A changed POI's difficulty is redrawn to one of the two other levels,
    and its kind is flipped with probability ``kind_flip`` (so every changed POI differs)."""

    @dataclass
    class Settings:
        probability: float | None = param(None, min=0.0, max=1.0,
                                          help="per-POI probability; default: the level's p")
        kind_flip: float = param(0.5, min=0.0, max=1.0,
                                 help="probability that a changed POI's kind flips")

    def __init__(self, settings: "AttributeChange.Settings", mission):
        self.p = (settings.probability if settings.probability is not None
                  else mission.event_probability)
        self.kind_flip = settings.kind_flip

    @hookimpl
    def ata_setup(self, sim: SimState) -> None:
        t, P = sim.group("tasks"), sim.sizes.tasks
        changed = sim.rng.uniform("attribute_change.event", 0, (P,)) < self.p
        shift = 1 + sim.rng.integers("attribute_change.diff", 0, 2, (P,))
        flip = sim.rng.uniform("attribute_change.kind", 0, (P,)) < self.kind_flip
        when = sim.rng.uniform("attribute_change.time", 0, (P,)) * sim.clock.horizon_s
        b, p = np.nonzero(changed)
        sim.queue("tasks.attribute_change").put(
            b=b, p=p, difficulty=(t.est_diff[b, p] + shift[b, p]) % 3,
            kind=np.where(flip[b, p], 1 - t.est_kind[b, p], t.est_kind[b, p]), reveal=when[b, p])
        self.changed = changed

    @hookimpl
    def ata_episode_end(self, sim: SimState) -> None:
        sim.record.metrics["attribute_changes"] = self.changed.sum(axis=1).astype(float)


@hookimpl
def ata_register_components(register) -> None:
    register("perturbation", "attribute_change", AttributeChange)
