"""Does the auxiliary reconstruction show working robots as down? ATA-HRL's decoder start
counts a robot as down where the reconstructed `working` is below 0.5, so a false down would
keep a working robot out of pi_TR's re-plan. Runs the shipped ATA-HRL of a setting on 24
scenarios of root seed 99000017 and counts, over every robot at every epoch, the rows the
observation shows working and the reconstruction down, and the reverse.

Usage: python tools/round4/false_downs.py SETTING LEVEL   (e.g. b low)
"""

from __future__ import annotations

import sys
from pathlib import Path

from ata import hookimpl
from ata.core.kernel import Simulation
from ata.experiment.runner import load_session
from ata.plugins.ata_hrl.components import AuxReconstructor

ROOT = Path(__file__).resolve().parents[2]


def main(setting: str, level: str) -> None:
    mission = ROOT / "examples" / "missions" / f"ata_hrl_{setting}.toml"
    s = load_session(str(mission), [f"mission.uncertainty='{level}'", "mission.seed=99000017"])
    counts = {"robot-epochs": 0, "observed down": 0, "observed working, reconstructed down": 0,
              "observed down, reconstructed working": 0}

    class Counting(AuxReconstructor):
        @hookimpl
        def ata_reconstruct(self, sim, obs, inherent, out):
            super().ata_reconstruct(sim, obs, inherent, out)
            seen = obs["robots"].col("working") > 0.5
            rec = out["aux_robots"][..., 3] > 0.5
            counts["robot-epochs"] += seen.size
            counts["observed down"] += int((~seen).sum())
            counts["observed working, reconstructed down"] += int((seen & ~rec).sum())
            counts["observed down, reconstructed working"] += int((~seen & rec).sum())

    aux = Counting(AuxReconstructor.Settings(checkpoint=f"builtin:ata_hrl_{setting}"), s.mission)
    Simulation(s.mission, s.registry, list(range(24)), overrides={"reconstructors": aux}).run()
    print(setting, level, counts)


if __name__ == "__main__":
    main(*sys.argv[1:3])
