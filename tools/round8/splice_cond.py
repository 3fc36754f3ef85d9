"""pi_C's linear residual of one ATA-HRL checkpoint in another: a copy of TARGET whose network
gains SOURCE's `cond.linear` (fitted by a cond phase with cond_fit = "features", or "rule":
then the rule, which decides at event epochs in the network's place), every other
tensor TARGET's. A diagnostic (the (a)-fitted residual in the (b) weights); nothing shipped is
made this way.

Usage: python tools/round8/splice_cond.py SOURCE TARGET OUT
(SOURCE, TARGET: paths or builtin:NAME)
"""

from __future__ import annotations

import sys

import torch

from ata.training import resolve


def main(source: str, target: str, out: str) -> None:
    src = torch.load(resolve(source), weights_only=True)
    dst = torch.load(resolve(target), weights_only=True)
    if not src["config"].get("cond_linear"):
        sys.exit(f"{source} has no linear residual in pi_C")
    dst["config"] = {**dst["config"], "cond_linear": True,
                     "cond_rule": bool(src["config"].get("cond_rule"))}
    dst["model"] = {**dst["model"], **{k: v for k, v in src["model"].items()
                                       if k.startswith("cond.linear.")}}
    torch.save(dst, out)
    print(f"{out}: {target} with pi_C's linear residual of {source}")


if __name__ == "__main__":
    if len(sys.argv) != 4:
        sys.exit(__doc__)
    main(*sys.argv[1:])
