"""Training throughput of ATA-HRL: episodes per second with and without the networks, in one run.

Usage: python benchmarks/bench_training.py [--setting a] [--scenarios 16] [--samples 8]
                                           [--repeats 3] [--threads 2] [--device cpu]

Setting (a), medium uncertainty, one torch thread, an ITA step's rollout on `--threads` processes
and its update's parts on as many threads (``[ata_hrl] threads``, the recipe's 2; 1: all in
this process, on one thread), an untrained network of the shipped architecture; each
row is the median of ``repeats`` timings of ``scenarios x samples`` episodes (one training
step's worth). ``--device cuda`` runs the training steps' updates on a GPU
(``[ata_hrl] device``; the rollouts decode on the CPU) and adds the network's forward pass at
a decoding step's size on each device. The rows:

- the simulator with greedy (initial allocation and event-triggered reallocation): no network;
- the ITA decoder on greedy's prior alone (``learned = false``), no reallocation: the decoder's
  numpy work without the network;
- the ITA decoder with the network, taking the mode: the network's forward passes added;
- one ITA training step: sampled rollouts, then the update (recomputing every decision's
  log-probability, backward, Adam);
- one pi_C / pi_TR training step (ITA frozen), with the reconstruction: rollouts and update.

Compare the ratios within one run: machines are shared and noisy.
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
import time

import numpy as np
import torch
from rich.console import Console
from rich.table import Table

from ata.core.kernel import Simulation, build_component
from ata.session import BASELINE_MISSION, build_trainer, load_session, training_mission_for
from ata.plugins.ata_hrl.components import AttentionITA
from ata.plugins.ata_hrl.phases.policy import rewards


def timed(fn, repeats: int) -> tuple[float, dict]:
    times, info = [], {}
    for i in range(repeats):
        t0 = time.perf_counter()
        info = fn(i) or {}
        times.append(time.perf_counter() - t0)
    return statistics.median(times), info


def validations(steps: int, eval_every: int) -> int:
    """Validations of a policy phase of `steps` steps: at step 0, every `eval_every` steps,
    and at the last step (the phase loop's rule)."""
    return 1 + sum(1 for k in range(1, steps + 1) if k % eval_every == 0 or k == steps) \
        if steps else 0


def recipe_estimate(aux_steps: int = 20, ita_steps: int = 2, ctr_steps: int = 1,
                    overrides: list[str] = (), first_step: int = 0
                    ) -> list[tuple[str, float, int, int, float]]:
    """The built-in (a) recipe's wall time by part, extrapolated from a few calls of each part.

    The trainer of ata/missions/train_ata_hrl.toml is built as `ata train --plugins ctr,aux`
    builds it; its phases' own calls are timed: one teacher batch of reconstruction data
    (``aux.rows``), `aux_steps` aux steps, `ita_steps` ITA and `ctr_steps` CTR steps (each
    after one untimed step: a fresh trainer's first step costs up to twice a later one), one
    validation of each policy phase and one checkpoint write; `overrides` (``TABLE.KEY=VALUE``,
    as ``--set``) change the recipe's settings; the timed ITA and CTR steps are those after
    `first_step` (their scenarios: another `first_step`, other scenarios). Returns (part,
    measured seconds, calls measured, calls in the recipe, extrapolated seconds) rows: linear
    in the calls."""
    session = load_session(str(training_mission_for(["ctr", "aux"])), list(overrides))
    trainer = build_trainer(session)
    s, phases = trainer.s, trainer.phases()
    assert phases["status"] == 0 and phases["cond"] == 0, \
        "the recipe gained a phase this estimate does not time"
    torch.set_num_threads(1)          # as the trainer's run: s.threads parallels the update

    def clock(fn, n: int) -> float:
        t0 = time.perf_counter()
        for k in range(n):
            fn(k)
        return time.perf_counter() - t0

    def save(_k):
        with tempfile.TemporaryDirectory() as tmp:
            torch.save(trainer.checkpoint(), f"{tmp}/checkpoint.pt")

    def aux_data(_k):
        trainer.aux.data = trainer.aux.rows(0, 1)

    rows = [("teacher rollouts (reconstruction data)", clock(aux_data, 1), 1, s.aux_batches + 1),
            ("aux steps", clock(trainer.aux.step, aux_steps), aux_steps, phases["aux"])]
    for part in (trainer.ita, trainer.ctr):
        part.start()
        steps = phases[part.name]
        label = part.name.upper()
        n = ita_steps if part.name == "ita" else ctr_steps
        part.step(0)        # untimed: a fresh trainer's first step pays for its warm-up
        rows.append((f"{label} steps", clock(lambda k: part.step(first_step + k + 1), n), n,
                     steps))
        rows.append((f"{label} validations", clock(lambda _k: trainer.validate(part.name), 1), 1,
                     validations(steps, s.eval_every)))
    saves = sum(phases[p] // s.checkpoint_every + validations(phases[p], s.eval_every)
                for p in ("ita", "ctr")) + 4
    rows.append(("checkpoint writes", clock(save, 1), 1, saves))
    return [(part, sec, n, m, sec / max(n, 1) * m) for part, sec, n, m in rows]


def decode_step_forward(device: str, episodes: int = 128, pois: int = 60,
                        repeats: int = 200) -> float:
    """Milliseconds of one POI-step scoring at a decoding step's size by the network's torch
    forward pass: the step's numpy inputs to `device`, the scorer's forward pass without
    gradient (half of the POIs legal), the logits back to the CPU for the choice (median of
    `repeats`). A decode itself scores on the CPU with its compiled loop (`scorer_loop`)."""
    from ata.plugins.ata_hrl.network import FEATURES, ATAHRLNet, NetConfig
    net = ATAHRLNet(NetConfig()).to(device)
    scorer, d = net.ita.scorers["poi"], net.cfg.d_model
    gen = np.random.default_rng(0)
    feats = gen.random((episodes, pois, FEATURES["poi"]), dtype=np.float32)
    prior = gen.random((episodes, pois), dtype=np.float32)
    mask = gen.random((episodes, pois)) < 0.5
    cand = torch.zeros(episodes, pois, d, device=device)
    ctx = torch.zeros(episodes, d, device=device)
    times = []
    with torch.inference_mode():
        for _ in range(repeats):
            t0 = time.perf_counter()
            logits = scorer(torch.from_numpy(feats).to(device), cand, ctx,
                            torch.from_numpy(prior).to(device), torch.from_numpy(mask).to(device))
            logits.cpu()
            times.append(time.perf_counter() - t0)
    return 1000 * statistics.median(times)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--setting", default="a")
    parser.add_argument("--scenarios", type=int, default=16)
    parser.add_argument("--samples", type=int, default=8)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--threads", type=int, default=2, help="[ata_hrl] threads: processes "
                        "of an ITA step's rollout, threads of its update (the same weights)")
    parser.add_argument("--device", default="cpu", help="device of the training steps' "
                        "updates ([ata_hrl] device): cpu or cuda")
    args = parser.parse_args()
    torch.set_num_threads(1)
    B, K = args.scenarios, args.samples
    n = B * K
    common = [f"mission.setting='{args.setting}'", f"ata_hrl.batch_size={B}",
              f"ata_hrl.samples={K}", f"ata_hrl.device='{args.device}'",
              f"ata_hrl.threads={args.threads}"]
    session = load_session(str(training_mission_for(["ctr", "aux"])), common)
    trainer = build_trainer(session)
    mission = trainer.mission_of(args.setting, 777)
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

    def step(part):
        def run(i):
            t0 = time.perf_counter()
            record, rec = trainer.rollout(mission, ids(i), part.name, train=True)
            t1 = time.perf_counter()
            part.learn(rec, rewards(record))
            return {"rollout": t1 - t0, "update": time.perf_counter() - t1}
        return run

    rows = [("simulator + greedy (no network)", simulator),
            ("ITA decoder, prior alone (no network)", ita(False)),
            ("ITA decoder with the network (mode)", ita(True)),
            ("ITA training step (rollout + update)", step(trainer.ita)),
            ("pi_C / pi_TR training step (rollout + update)", step(trainer.ctr))]
    table = Table(title=f"ATA-HRL training throughput, setting ({args.setting}), {B} scenarios x "
                        f"{K} samples = {n} episodes, update on {args.threads} thread(s), updates "
                        f"on {args.device}")
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
    if args.device != "cpu":
        for device in ("cpu", args.device):
            print(f"POI scorer at a decoding step's size ({n} episodes x 60 POIs, inputs in "
                  f"and logits out) on {device}: {decode_step_forward(device):.3f} ms")


if __name__ == "__main__":
    main()
