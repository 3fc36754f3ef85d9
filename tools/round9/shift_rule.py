"""A copy of a checkpoint whose pi_C rule (cond_fit = "rule") has its bias lowered by DELTA:
the same ranking of event epochs, fewer of them reallocated. A diagnostic of how many events
the rule should keep; nothing shipped is made this way.

Usage: python tools/round9/shift_rule.py CHECKPOINT DELTA OUT
"""

from __future__ import annotations

import sys

import torch

from ata.plugins.ata_hrl.checkpoint import KIND
from ata.training import read_checkpoint


def main(argv: list[str]) -> None:
    if len(argv) != 3:
        sys.exit(__doc__)
    data = read_checkpoint(argv[0], KIND)
    if not (data["config"].get("cond_rule") and "cond.linear.on" in data["model"]):
        sys.exit(f"{argv[0]}: pi_C has no fitted rule (cond_fit = 'rule')")
    data["model"]["cond.linear.bias"] = data["model"]["cond.linear.bias"] - float(argv[1])
    torch.save(data, argv[2])


if __name__ == "__main__":
    main(sys.argv[1:])
