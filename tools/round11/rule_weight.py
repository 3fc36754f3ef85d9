"""A copy of an ATA-HRL checkpoint whose pi_C rule has one weight set to a value, every other
tensor the same: a diagnostic of which condition feature drives a fitted rule (round 11: the
weight of the time since the last re-plan, feature 5, set to 0). Nothing shipped is made this
way. The ten features, in order (`condition_features` in ata/plugins/ata_hrl/components.py):
0 an event, 1 robots newly down / R, 2 POIs newly changed / P, 3 reallocatable POIs held by a
down robot / P, 4 epoch / T, 5 epochs since the last re-plan / T, 6-8 the humans' mean, max and
min utilisation, 9 the share of POIs shown unvisited. The rule's weights act on them as they
are (its standardisation is folded in).

Usage: python tools/round11/rule_weight.py CHECKPOINT OUT FEATURE VALUE
(CHECKPOINT: a path or builtin:NAME)
"""

from __future__ import annotations

import sys

import torch

from ata.training import resolve


def main(checkpoint: str, out: str, feature: str, value: str) -> None:
    data = torch.load(resolve(checkpoint), weights_only=True)
    weight = data["model"].get("cond.linear.weight")
    if weight is None or not data["config"].get("cond_rule"):
        sys.exit(f"{checkpoint} has no fitted pi_C rule")
    before = float(weight[0, int(feature)])
    weight[0, int(feature)] = float(value)
    torch.save(data, out)
    print(f"{out}: {checkpoint} with the rule's weight {feature} {before:+.3f} -> {float(value):+.3f}")


if __name__ == "__main__":
    if len(sys.argv) != 5:
        sys.exit(__doc__)
    main(*sys.argv[1:])
