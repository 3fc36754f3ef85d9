"""Each built-in training recipe's training time on this machine beside its goal, and the
held-out paired difference of newly trained weights against the shipped ones.

Usage: python benchmarks/bench_recipes.py [--quick] [--only ata_hrl,tr_pomdp,atrl_tr] [--repeats N]
           [--trained RECIPE=DIR ...] [--paired EVAL_DIR --method NAME] [--skip-timing]

The recipes and their goals (issue 60): ATA-HRL (a) (ata/missions/train_ata_hrl.toml) at most
15 minutes, TR-POMDP (train_tr_pomdp.toml) and AtRL-TR (train_atrl_tr.toml) at most 30, on this
machine's cores (docs/training.md times them on 2).

Training time, by default *extrapolated*: the trainer of each recipe is built as `ata train`
builds it and a few of its own calls are timed (after one untimed call of each, which compiles
what numba's cache lacks), then each part is scaled linearly to the recipe's counts; beside the
wall time, the wall time scaled by this process's share of a core where it had less than one
(other work shared the machine): what an idle core would take, the recipes' rollouts running on
one thread. ATA-HRL's update takes its parts' gradients side by side on two threads (`threads`),
so on an idle 2-core machine it has more than a core, and its wall time stands. ATA-HRL:
`bench_training.recipe_estimate` (teacher rollouts, aux steps, ITA and CTR steps, one validation
of each phase and a checkpoint write). TR-POMDP and AtRL-TR: DQN steps at indices spread over
the recipe (epsilon decays over the steps; the replay fills as it would), one validation and one
checkpoint write (with its replay buffers). A full recipe takes 12 to 30 minutes,
which this does not spend. `--repeats N` times each recipe N times, a fresh trainer each, and
judges the median (each repeat times the next ITA and CTR steps, other scenarios; a recipe
near its goal can read on either side of it in single runs).

`--trained RECIPE=DIR` reads instead a finished training folder's *measured* time: its
trained.json (`wall_s`, the trainer's own clock), or, for a folder of seeds, each seed's.

`--paired EVAL_DIR --method NAME` pairs an evaluation of new weights (`ata eval` or `ata run` on
the held-out scenarios of the published set: seed 0, 500 scenarios a cell) with the published
rows of NAME (the shipped weights), on `expected_score` (the points in expectation over the
classification outcomes): A - B with its 95% interval (two-level across seeds where either has
several) and P(a seed of A beats a seed of B). For weights trained with `ata train -o DIR`:

    ata eval DIR -n 500 -o runs/new-eval          # DIR: a run folder or a folder of seeds
    python benchmarks/bench_recipes.py --skip-timing --paired runs/new-eval --method ATA-HRL

or both at once: `--skip-timing --weights DIR --method ATA-HRL` (DIR-heldout holds the rows).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

import numpy as np  # noqa: E402
import torch  # noqa: E402

import bench_training  # noqa: E402
from ata.session import build_trainer, load_session, training_mission_for  # noqa: E402

RECIPES = {
    # name: (label, plugins of its training mission, goal in minutes)
    "ata_hrl": ("ATA-HRL (a)", ["ctr", "aux"], 15),
    "tr_pomdp": ("TR-POMDP", ["trp"], 30),
    "atrl_tr": ("AtRL-TR", ["ita", "trp"], 30),
}


def dqn_estimate(plugins: list[str], steps: int = 8) -> tuple[list[tuple], dict]:
    """A tr_pomdp recipe's wall time by part, from `steps` DQN steps at indices spread over its
    steps (their epsilon; the replay fills over them, as in the recipe's first minutes), one
    validation and one checkpoint write (with the replay as it then is): (part, seconds, calls,
    recipe's calls, extrapolated seconds) rows, and the recipe's settings."""
    session = load_session(str(training_mission_for(plugins)), [])
    trainer = build_trainer(session)
    t = trainer.t
    torch.set_num_threads(t.threads)
    at = np.linspace(0, t.steps - 1, steps).round().astype(int)
    t0 = time.perf_counter()
    for k in at:
        trainer.step(int(k))
    step_s = time.perf_counter() - t0
    t0 = time.perf_counter()
    trainer.validate()
    val_s = time.perf_counter() - t0
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        torch.save(trainer.checkpoint(), f"{tmp}/checkpoint.pt")
    save_s = time.perf_counter() - t0
    vals = bench_training.validations(t.steps, t.eval_every) - 1   # none at step 0 here
    rows = [("DQN steps", step_s, steps, t.steps),
            ("validations", val_s, 1, vals),
            ("checkpoint writes", save_s, 1, t.steps // t.checkpoint_every + vals)]
    return [(p, s, n, m, s / n * m) for p, s, n, m in rows], \
        {"steps": t.steps, "batch_size": t.batch_size, "updates": t.updates}


def trained_time(folder: Path) -> tuple[float, str]:
    """Minutes of training a finished folder measured (trained.json's wall_s), and what: the
    run, or each seed of a folder of seeds (their mean, the longest)."""
    from ata.training.folders import is_seeds_folder, read_seeds
    dirs = read_seeds(folder)["dirs"] if is_seeds_folder(folder) else [folder]
    walls, steps = [], set()
    for d in dirs:
        path = d / "trained.json"
        if not path.is_file():
            raise SystemExit(f"{path}: no trained.json (the run has not finished)")
        data = json.loads(path.read_text())
        walls.append(float(data["wall_s"]) / 60)
        steps.add(", ".join(f"{v} {k}" for k, v in data.get("counters", {}).items()
                            if k != "episodes"))
    # the steps say whether the folder trained the recipe or a cut of it
    what = f"measured, {folder} ({'; '.join(sorted(steps))} steps)"
    if len(walls) == 1:
        return walls[0], what
    return float(np.mean(walls)), (f"mean of {len(walls)} seeds (longest {max(walls):.1f} "
                                   f"min), {what}")


def paired(eval_dir: Path, method: str, published: str = "published") -> None:
    """EVAL_DIR's methods (seeds grouped) - the published METHOD on expected_score."""
    from ata.core.errors import MissionError
    from ata.published import sets
    from ata.results import seeds
    from ata.results.rows import read_results
    mine = read_results(eval_dir)
    theirs, manifest, where = sets.read_published(published)
    try:
        sets.check_pairing(mine, eval_dir, manifest, [method])
    except MissionError as exc:
        print(f"paired difference: cannot pair with {where}: {exc}")
        return
    column = "expected_score" if "expected_score" in mine.columns else "score"
    tables = seeds.published_tables(mine, theirs, [method], column=column)
    for table in tables:
        print(f"{table.title} ({column}, {where})")
        for row in [table.header, *table.rows]:
            print("  " + " | ".join(row))
    if not tables:
        print(f"paired difference: no scenario of {eval_dir} is in {where}'s {method} rows")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true",
                        help="fewer calls timed: ATA-HRL 10 aux, 3 ITA, 1 CTR step; DQN 4 steps")
    parser.add_argument("--only", default=",".join(RECIPES), help="recipes to time")
    parser.add_argument("--repeats", type=int, default=1, metavar="N",
                        help="time each recipe N times, each with a fresh trainer, and judge "
                             "the median (a recipe near its goal flips between single runs)")
    parser.add_argument("--trained", action="append", default=[], metavar="RECIPE=DIR",
                        help="read RECIPE's time from a finished training folder instead")
    parser.add_argument("--skip-timing", action="store_true", help="time no recipe")
    parser.add_argument("--no-warm-up", action="store_true",
                        help="time the first calls too (compiling included)")
    parser.add_argument("--paired", type=Path, metavar="EVAL_DIR",
                        help="an evaluation of new weights on the published scenarios")
    parser.add_argument("--weights", type=Path, metavar="DIR",
                        help="a training run folder or folder of seeds: evaluate it (ata eval "
                             "DIR -n SCENARIOS) into DIR-heldout, then pair it as --paired")
    parser.add_argument("--scenarios", type=int, default=500,
                        help="held-out scenarios a cell for --weights (default 500)")
    parser.add_argument("--method", default="ATA-HRL", help="the published method of --paired")
    parser.add_argument("--published", default="published", help="the published set")
    args = parser.parse_args()
    trained = dict(item.split("=", 1) for item in args.trained)
    unknown = [r for r in [*trained, *args.only.split(",")] if r not in RECIPES]
    if unknown:
        parser.error(f"no recipe {unknown[0]!r}; recipes: {', '.join(RECIPES)}")
    if args.repeats < 1:
        parser.error("--repeats: at least 1")
    summary = []
    for name in [] if args.skip_timing else args.only.split(","):
        label, plugins, goal = RECIPES[name]
        if name in trained:
            minutes, how = trained_time(Path(trained[name]))
            cpu_text, judged = "     -", minutes
        else:
            if not args.no_warm_up:
                # every part once, untimed: a first call compiles what numba's cache lacks
                # (all of it after a file of ata.model changed), which the recipe pays once
                if name == "ata_hrl":
                    bench_training.recipe_estimate(1, 1, 1)
                else:
                    dqn_estimate(plugins, 1)
            walls, cpus, shares = [], [], []
            for k in range(args.repeats):
                wall0, cpu0 = time.perf_counter(), time.process_time()
                if name == "ata_hrl":
                    # ITA steps differ by their scenarios by a third: one step is too few
                    calls = (10, 3, 1) if args.quick else (20, 6, 2)
                    # each repeat times other steps: other scenarios
                    rows = bench_training.recipe_estimate(*calls, first_step=k * calls[1])
                else:
                    rows, _ = dqn_estimate(plugins, 4 if args.quick else 8)
                tag = f"[{name}]" if args.repeats == 1 else f"[{name} {k + 1}/{args.repeats}]"
                for part, sec, n, m, est in rows:
                    print(f"{tag} {part}: {sec:.1f} s for {n} -> {est:.0f} s for the recipe's "
                          f"{m}", flush=True)
                walls.append(sum(r[4] for r in rows) / 60)
                # this process's CPU seconds per second while it was timed: below 1 where other
                # work shared the cores (the recipes' rollouts run on one thread), so the
                # CPU-time figure is what an idle core would take; above 1 where an update's
                # parts ran side by side (ATA-HRL's `threads`): then the wall time stands
                shares.append((time.process_time() - cpu0) / (time.perf_counter() - wall0))
                cpus.append(walls[-1] * min(shares[-1], 1.0))
            minutes, judged = float(np.median(walls)), float(np.median(cpus))
            cpu_text = f"{judged:6.1f}"
            how = f"extrapolated from the calls above; it had {min(shares):.0%} of a core"
            if args.repeats > 1:
                how = (f"median of {args.repeats} extrapolations (CPU "
                       f"{', '.join(f'{c:.1f}' for c in cpus)}); at least {min(shares):.0%} of "
                       "a core")
        verdict = "meets it" if judged <= goal else f"{judged / goal:.1f}x over"
        summary.append(f"{label:12s} {minutes:6.1f} {cpu_text}   <= {goal} min  {verdict:10s} "
                       f"{how}")
    if summary:
        print(f"\nTraining time per recipe, minutes, on this machine ({os.cpu_count()} cores, "
              f"load average {os.getloadavg()[0]:.1f}; each recipe on its own `threads`). "
              "wall: as timed (a finished folder's: its measured training time); CPU: the wall "
              "time times this process's share of a core where below one, what an idle machine "
              "takes; the verdict is on CPU where timed:")
        print(f"  {'recipe':12s} {'wall':>6s} {'CPU':>6s}   goal     verdict    how")
        print("\n".join("  " + s for s in summary))
    if args.weights:
        args.paired = args.weights.with_name(args.weights.name + "-heldout")
        print(f"\nata eval {args.weights} -n {args.scenarios} -o {args.paired}", flush=True)
        subprocess.run([sys.executable, "-m", "ata.cli", "eval", str(args.weights), "-n",
                        str(args.scenarios), "-o", str(args.paired), "-q"], check=True)
    if args.paired:
        paired(args.paired, args.method, args.published)
    elif not args.skip_timing:
        print("\nHeld-out paired difference against the shipped weights: train (ata train -o "
              "DIR), ata eval DIR -n 500 -o EVAL, then --paired EVAL --method ATA-HRL")


if __name__ == "__main__":
    main()
