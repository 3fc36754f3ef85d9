"""Average the networks of several ATA-HRL checkpoints (uniform weight averaging, a "model soup").

    python tools/average_checkpoints.py OUT.pt RUN_OR_CHECKPOINT [RUN_OR_CHECKPOINT ...]

A run folder stands for its ``checkpoint.pt`` (its last step). Every input must be an ATA-HRL
checkpoint of the same architecture that trained the ITA, and all should start from one network
(runs continued from one ``init_from``): averaging networks trained apart from different starts
means nothing. The output is the first input's checkpoint with the averaged ``model`` and the
union of the inputs' ``scenario_ranges`` (so ``ata eval`` still refuses every scenario any of them
trained on); the optimiser state, the counters and the random number generators' states are the
first input's and make no sense for the average, so the output is for ``ita_from`` / evaluation,
not for ``--resume``. It loads with ``torch.load(..., weights_only=True)`` like any checkpoint.
"""

from __future__ import annotations

import sys
from pathlib import Path

import torch

from ata.plugins.ata_hrl.checkpoint import KIND, net_from_checkpoint
from ata.training import CheckpointError, read_checkpoint


def average(paths: list[Path]) -> dict:
    datas = []
    for p in paths:
        path = p / "checkpoint.pt" if p.is_dir() else p
        data = read_checkpoint(path)
        if data.get("kind") != KIND or "ita" not in data.get("trained", []):
            raise CheckpointError(path, "is not an ATA-HRL checkpoint that trained the ITA")
        net_from_checkpoint(data, path)          # refuses another architecture
        if datas and data["config"] != datas[0]["config"]:
            raise CheckpointError(path, "has another architecture than the first input")
        datas.append(data)
    out = dict(datas[0])
    out["model"] = {k: (torch.stack([d["model"][k].double() for d in datas]).mean(0)
                        .to(v.dtype) if v.is_floating_point() else v)
                    for k, v in datas[0]["model"].items()}
    ranges = sorted({tuple(r) for d in datas for r in d.get("scenario_ranges", [])})
    out["scenario_ranges"] = [list(r) for r in ranges]
    out["averaged_from"] = [str(p) for p in paths]
    return out


def main(argv: list[str]) -> int:
    if len(argv) < 3:
        print(__doc__.strip().splitlines()[2].strip(), file=sys.stderr)
        return 2
    out = Path(argv[1])
    try:
        data = average([Path(a) for a in argv[2:]])
    except CheckpointError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 1
    tmp = out.with_suffix(out.suffix + ".tmp")
    torch.save(data, tmp)
    tmp.replace(out)
    print(f"{out}: the average of {len(argv) - 2} checkpoints")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
