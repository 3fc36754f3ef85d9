"""Training throughput of ATA-HRL: episodes per second with and without the networks, in one run.

Usage: python benchmarks/bench_training.py [--setting a] [--scenarios 16] [--samples 8]
                                           [--repeats 3]

Setting (a), medium uncertainty, one torch thread, an untrained network of the shipped
architecture; each row is the median of ``repeats`` timings of ``scenarios x samples`` episodes
(one training step's worth):

- the simulator with greedy (initial allocation and event-triggered reallocation): no network;
- the ITA decoder on greedy's prior alone (``learned = false``), no reallocation: the decoder's
  numpy work without the network;
- the ITA decoder with the network, taking the mode: the network's forward passes added;
- one ITA training step: sampled rollouts, then the update (recomputing every decision's
  log-probability, backward, Adam);
- one pi_C / pi_TR training step (ITA frozen), with the reconstruction: rollouts and update.

Compare the ratios within one run: machines are shared and noisy.

`recipe_estimate` times the built-in (a) training recipe (ata/missions/train_ata_hrl.toml) by
its parts, through the trainer's own phase methods on a few steps, and extrapolates to the
recipe's step counts (bench_fast.py prints it).
"""

from __future__ import annotations

import argparse
import dataclasses
import statistics
import tempfile
import time

import numpy as np
import torch
from rich.console import Console
from rich.table import Table

from ata.core.kernel import Simulation, build_component
from ata.experiment.runner import BASELINE_MISSION, build_trainer, load_session, training_mission_for
from ata.plugins.ata_hrl.components import AttentionITA
from ata.training import TrainRun


def timed(fn, repeats: int) -> tuple[float, dict]:
    times, info = [], {}
    for i in range(repeats):
        t0 = time.perf_counter()
        info = fn(i) or {}
        times.append(time.perf_counter() - t0)
    return statistics.median(times), info


def validations(steps: int, eval_every: int) -> int:
    """Validations of a policy phase of `steps` steps: at step 0, every `eval_every` steps,
    and at the last step (the trainer's rule in ``train_policy``)."""
    return 1 + sum(1 for k in range(1, steps + 1) if k % eval_every == 0 or k == steps) \
        if steps else 0


def recipe_estimate(aux_steps: int = 20, ita_steps: int = 2, ctr_steps: int = 1
                    ) -> list[tuple[str, float, int, int, float]]:
    """The built-in (a) recipe's wall time by part, extrapolated from a short run of each
    phase. The trainer of ata/missions/train_ata_hrl.toml is built as `ata train --plugins
    ctr,aux` builds it and its phase methods run as ``run`` calls them, with fewer steps, one
    teacher batch for the reconstruction data, and validations only at a phase's first and
    last step; the teacher rollouts (``aux_data``), validations (``evaluate``) and checkpoint
    writes (``save``) are timed apart, and the rest of a phase is its steps.

    Returns (part, measured seconds, calls measured, calls in the recipe, extrapolated
    seconds) rows: the extrapolation is linear in the calls."""
    recipe = load_session(str(training_mission_for(["ctr", "aux"])))
    full = build_trainer(recipe).s
    session = load_session(str(training_mission_for(["ctr", "aux"])), [
        f"ata_hrl.aux_steps={aux_steps}", f"ata_hrl.ita_steps={ita_steps}",
        f"ata_hrl.ctr_steps={ctr_steps}", "ata_hrl.aux_batches=1",
        f"ata_hrl.eval_every={max(ita_steps, ctr_steps) + 1}"])
    trainer = build_trainer(session)
    assert trainer.phases()["status"] == 0 and trainer.phases()["cond"] == 0, \
        "the recipe gained a phase this estimate does not time"
    spent = {"aux_data": [0.0, 0], "evaluate": [0.0, 0], "save": [0.0, 0]}

    def timed_method(name):
        inner = getattr(trainer, name)

        def wrapper(*a, **k):
            t0 = time.perf_counter()
            try:
                return inner(*a, **k)
            finally:
                spent[name][0] += time.perf_counter() - t0
                spent[name][1] += 1
        setattr(trainer, name, wrapper)     # the instance's: the phase loops call it

    for name in spent:
        timed_method(name)
    torch.set_num_threads(trainer.s.threads)
    phase_s = {}
    with tempfile.TemporaryDirectory() as tmp:
        trainer.run_folder = TrainRun(tmp, session.mission.to_toml(), trainer.log_fields)
        for phase, call in (("aux", trainer.train_aux), ("ita", lambda: trainer.train_policy(
                "ita")), ("ctr", lambda: trainer.train_policy("ctr"))):
            before = {k: v[0] for k, v in spent.items()}
            t0 = time.perf_counter()
            call()
            phase_s[phase] = (time.perf_counter() - t0
                              - sum(spent[k][0] - before[k] for k in spent))
            if phase == "ita":
                ita_val = spent["evaluate"][:]
    ctr_val = [spent["evaluate"][0] - ita_val[0], spent["evaluate"][1] - ita_val[1]]
    saves = full.ita_steps // full.checkpoint_every + full.ctr_steps // full.checkpoint_every \
        + validations(full.ita_steps, full.eval_every) \
        + validations(full.ctr_steps, full.eval_every) + 4
    rows = [("teacher rollouts (reconstruction data)", *spent["aux_data"],
             full.aux_batches + 1),
            ("aux steps", phase_s["aux"], aux_steps, full.aux_steps),
            ("ITA steps", phase_s["ita"], ita_steps, full.ita_steps),
            ("ITA validations", *ita_val, validations(full.ita_steps, full.eval_every)),
            ("CTR steps", phase_s["ctr"], ctr_steps, full.ctr_steps),
            ("CTR validations", *ctr_val, validations(full.ctr_steps, full.eval_every)),
            ("checkpoint writes", *spent["save"], saves)]
    return [(part, sec, n, m, sec / max(n, 1) * m) for part, sec, n, m in rows]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--setting", default="a")
    parser.add_argument("--scenarios", type=int, default=16)
    parser.add_argument("--samples", type=int, default=8)
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    torch.set_num_threads(1)
    B, K = args.scenarios, args.samples
    n = B * K
    common = [f"mission.setting='{args.setting}'", f"ata_hrl.batch_size={B}",
              f"ata_hrl.samples={K}"]
    session = load_session(str(training_mission_for(["ctr", "aux"])), common)
    trainer = build_trainer(session)
    mission = trainer._mission(args.setting, 777)
    ids = lambda i: np.repeat(np.arange(B) + 1000 * i, K)  # noqa: E731
    greedy = load_session(str(BASELINE_MISSION), [f"mission.setting='{args.setting}'"])

    def simulator(i):
        Simulation(greedy.mission.replace(seed=777), greedy.registry, ids(i)).run()

    def ita(learned: bool):
        def run(i):
            settings = AttentionITA.Settings(learned=learned)
            pol = AttentionITA(settings, mission, net=trainer.net)
            reg = trainer.registry
            never = build_component(reg, mission, "condition", "never")
            keep = build_component(reg, mission, "policy", "keep")
            identity = build_component(reg, mission, "reconstructor", "identity")
            Simulation(mission, reg, ids(i),
                       overrides={"initial": pol, "condition": never, "reallocation": keep,
                                  "reconstructors": identity}).run()
        return run

    def step(phase: str):
        def run(i):
            t0 = time.perf_counter()
            record, rec = trainer.rollout(mission, ids(i), phase, train=True)
            t1 = time.perf_counter()
            _, loss = trainer.rewards_and_loss(phase, record, rec)
            trainer.update(loss)
            return {"rollout": t1 - t0, "update": time.perf_counter() - t1}
        return run

    rows = [("simulator + greedy (no network)", simulator),
            ("ITA decoder, prior alone (no network)", ita(False)),
            ("ITA decoder with the network (mode)", ita(True)),
            ("ITA training step (rollout + update)", step("ita")),
            ("pi_C / pi_TR training step (rollout + update)", step("ctr"))]
    table = Table(title=f"ATA-HRL training throughput, setting ({args.setting}), {B} scenarios x "
                        f"{K} samples = {n} episodes, 1 torch thread")
    for col in ("what", "seconds", "episodes/s", "x simulator", "rollout s", "update s"):
        table.add_column(col, justify="left" if col == "what" else "right")
    base = None
    for label, fn in rows:
        seconds, info = timed(fn, args.repeats)
        rate = n / seconds
        base = base or rate
        table.add_row(label, f"{seconds:.2f}", f"{rate:.1f}", f"{rate / base:.2f}",
                      f"{info['rollout']:.2f}" if "rollout" in info else "-",
                      f"{info['update']:.2f}" if "update" in info else "-")
    Console(width=160).print(table)


if __name__ == "__main__":
    main()
