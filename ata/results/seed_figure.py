"""fig_seeds: every method with training seeds, across its seeds, per team setting and level.

A panel per setting, the uncertainty levels along x; per method with seeds (``NAME seed S``,
`ata.results.seeds`), side by side: the mean over its seeds with the two-level bootstrap 95%
interval (seeds, then scenarios) as an error bar, each seed's own mean as a small dot beside it,
and the plain run of the same name (``NAME``, the default weights), where the results have one,
as a hollow diamond. It shows at a glance how far the seeds lie apart, against the interval
that counts them, and where the default run stands among them.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ata.results.rows import RESAMPLES, Results
from ata.results.seeds import across_seeds, seed_matrix, seeded

STEM = "fig_seeds"
CAPTION = ("`fig_seeds`: each method with training seeds, across its seeds: the mean over the "
           "seeds with its two-level 95% bootstrap interval (seeds, then scenarios), each "
           "seed's mean as a dot, and the plain run of that name (the default weights) as a "
           "hollow diamond; a panel per setting, by uncertainty level.")


def _settings(res: Results, groups: dict[str, list[str]]) -> list[str]:
    return [s for s in res.settings if any(res.select(m, s, lv).any() for ms in groups.values()
                                           for m in ms for lv in res.levels)]


def drawn(res: Results) -> bool:
    """Whether `seeds_figure` draws a figure of these results (some method has seeds)."""
    return bool(_settings(res, seeded(res.methods)))


def seeds_figure(plt: Any, res: Results, resamples: int = RESAMPLES) -> Any | None:
    """The figure (see the module's doc), or None where no method has seeds."""
    groups = seeded(res.methods)
    settings = _settings(res, groups)
    if not settings:
        return None
    colours = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    fig, axes = plt.subplots(1, len(settings), squeeze=False, layout="constrained",
                             figsize=(1.0 + 4.4 * len(settings), 3.8))
    width = 0.8 / len(groups)
    for ax, setting in zip(axes[0], settings):
        levels = [lv for lv in res.levels
                  if any(res.select(m, setting, lv).any() for ms in groups.values() for m in ms)]
        for k, (name, methods) in enumerate(groups.items()):
            colour = colours[k % len(colours)]
            centre = np.arange(len(levels)) + (k - (len(groups) - 1) / 2) * width
            for x, level in zip(centre, levels):
                ran = [m for m in methods if res.select(m, setting, level).any()]
                if not ran:
                    continue
                scores = seed_matrix(res, ran, setting, level)[0]
                if scores.shape[1] == 0:
                    continue
                st = across_seeds(scores, name, setting, level, resamples)
                ax.errorbar([x], [st.mean], yerr=[[st.mean - st.low], [st.high - st.mean]],
                            marker="o", markersize=4, capsize=2, color=colour, linewidth=1.0)
                per_seed = scores.mean(axis=1)
                ax.scatter(np.full(per_seed.size, x + width * 0.28), per_seed, s=7,
                           color=colour, alpha=0.7, linewidths=0)
                plain = res.select(name, setting, level) if name in res.methods else None
                if plain is not None and plain.any():
                    ax.scatter([x - width * 0.28], [np.mean(res.columns["score"][plain])],
                               marker="D", s=16, facecolors="none", edgecolors=colour,
                               linewidths=1.0)
            ax.plot([], [], marker="o", color=colour, label=f"{name} ({len(methods)} seeds)")
        ax.scatter([], [], marker="D", s=16, facecolors="none", edgecolors="0.3",
                   label="the plain run (default weights)")
        ax.set_xticks(np.arange(len(levels)), levels)
        ax.set_xlabel("uncertainty")
        ax.set_ylabel("total team performance")
        ax.set_title(f"Across training seeds, setting {setting}")
        ax.grid(axis="y", color="0.9", linewidth=0.6)
        ax.set_axisbelow(True)
    axes[0][-1].legend(fontsize=7, loc="center left", bbox_to_anchor=(1.02, 0.5),
                       frameon=False)
    return fig
