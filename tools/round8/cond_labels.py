"""What pi_C's decisions are worth, one at a time: for each scenario, the method is run once as
it is (the base row) and once per epoch f of FLIPS with pi_C's decision at f flipped (every
other decision as the method takes it, by its mode). The scenario's random streams are the same
in every row, so the difference of a flipped row and the base row, from epoch f on, is the
value of the other choice at f (in the paper's R_C and in expected points). A diagnostic on
selection scenarios (root seed 99000017); training uses the same rollouts on training ids.

Usage: python tools/round8/cond_labels.py SETTING LEVEL N [FLIPS] [-o FILE.npz]
FLIPS: how many epochs per scenario to flip (spread evenly at random; default all).
Prints the distribution of the differences at event and at quiet epochs.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from ata.core.kernel import Simulation
from ata.experiment.runner import load_session
from ata.plugins.ata_hrl.rewards import rewards_to_go, to_go

ROOT = Path(__file__).resolve().parents[2]


def session(setting: str, level: str, seed: int):
    sets = [f"mission.setting='{setting}'", f"mission.uncertainty='{level}'",
            f"mission.seed={seed}"]
    if setting == "b":
        sets += [f"{c}.checkpoint='builtin:ata_hrl_b_ft'" for c in ("attention", "ctr", "aux")]
    return load_session(str(ROOT / "examples" / "missions" / "ata_hrl_a.toml"), sets)


def play(s, ids: np.ndarray, change, watch=None):
    """Run ATA-HRL on scenarios `ids` of session `s`, each epoch's pi_C decision (epochs >= 1)
    passed through `change(cond, epoch, decision) -> decision`; `watch(cond, ctx, epoch,
    decision)` sees each decision taken. pi_C's memory of when it last reallocated follows
    the decision taken (at epoch 1, where it has no memory yet, the one it made itself stands
    in for it). Returns the episode's record."""
    sim = Simulation(s.mission, s.registry, ids)
    sim.reset()
    T = sim.sim.clock.n_epochs
    cond = sim.slot_component["condition"]
    while sim.sim.epoch < T:
        ctx = sim.begin_epoch()
        k = ctx.epoch
        if k == 0:
            sim.end_epoch(*sim.decide(ctx))
            continue
        before = None if cond.last_realloc is None else cond.last_realloc.copy()
        active = change(cond, k, np.asarray(sim._callers["condition"](ctx=ctx), bool))
        cond.last_realloc = np.where(active, k, before if before is not None
                                     else cond.last_realloc)
        if watch is not None:
            watch(cond, ctx, k, active)
        alloc = sim._callers["reallocation"](ctx=ctx, active=active) if active.any() else None
        sim.end_epoch(alloc, active)
    return sim.end_episode()


def run_flipped(s, ids: np.ndarray, flip: np.ndarray):
    """Run scenarios `ids` with pi_C's decision flipped at epoch flip[i] (-1: never). Returns
    (record, decisions (E, T) as taken, condition features (E, T, F) and prior (E, T))."""
    T = s.mission.clock.n_epochs
    E = len(ids)
    taken = np.zeros((E, T), bool)
    feats = np.zeros((E, T, len(FEATURES)), np.float32)
    prior = np.zeros((E, T), np.float32)

    def watch(cond, ctx, k, active):
        feats[:, k] = np.concatenate([cond.cond_feats, model_gain(cond, ctx)], 1)
        prior[:, k], taken[:, k] = cond.cond_prior, active

    record = play(s, ids, lambda cond, k, active: active ^ (flip == k), watch)
    return record, taken, feats, prior


def model_gain(cond, ctx) -> np.ndarray:
    """(E, 2) what greedy's model of worth expects a full greedy re-plan to add to the plan in
    force, net of its re-tasking cost: per point of the plan kept, and in points."""
    from ata.plugins.policies.greedy import RetaskCost, plan
    from ata.plugins.policies.plan import as_seen, plan_start
    ctx = as_seen(ctx)
    g = cond.greedy
    cost = RetaskCost.of(ctx)
    start = plan_start(ctx, g.s.capture_s)
    open_ = ctx.reallocatable
    keep = g.worth(ctx, start, ctx.previous, open_, cost)
    full = g.worth(ctx, start, plan(ctx, g.s, open_), open_, cost)
    scale = np.maximum(np.abs(keep), 1.0)
    return np.stack([(full - keep) / scale, full - keep], 1).astype(np.float32)


def labels(s, ids: np.ndarray, flips: int, rng: np.random.Generator, batch: int = 8):
    T = s.mission.clock.n_epochs
    out = {k: [] for k in ("id", "epoch", "base_choice", "d_rc", "d_exp", "feats", "prior")}
    for i in range(0, len(ids), batch):
        chunk = ids[i:i + batch]
        rows, flip = [], []
        for sid in chunk:
            ep = np.arange(1, T) if flips >= T - 1 else np.sort(rng.choice(np.arange(1, T),
                                                                            flips, False))
            rows += [sid] * (len(ep) + 1)
            flip += [-1] + list(ep)
        rows, flip = np.array(rows), np.array(flip)
        rec, taken, feats, prior = run_flipped(s, rows, flip)
        rc = rewards_to_go(rec, expected=True)["R_C"]
        exp_to_go = to_go(rec.r_expected)
        base_row = {}
        for j, (sid, f) in enumerate(zip(rows, flip)):
            if f < 0:
                base_row[sid] = j
        for j, (sid, f) in enumerate(zip(rows, flip)):
            if f < 0:
                continue
            b = base_row[sid]
            out["id"].append(sid)
            out["epoch"].append(f)
            out["base_choice"].append(taken[b, f])
            out["d_rc"].append(rc[j, f] - rc[b, f])
            out["d_exp"].append(exp_to_go[j, f] - exp_to_go[b, f])
            out["feats"].append(feats[b, f])
            out["prior"].append(prior[b, f])
        print(f"  {i + len(chunk)}/{len(ids)} scenarios", flush=True)
    return {k: np.array(v) for k, v in out.items()}


FEATURES = ("event", "failed", "changed", "held_by_down", "epoch", "since_realloc",
            "util_mean", "util_max", "util_min", "unvisited", "gain_rel", "gain_abs")
"""pi_C's ten condition features (components.condition_features), then `model_gain`'s two."""


def _logistic(X: np.ndarray, t: np.ndarray, w: np.ndarray, l2: float = 1e-2,
              iters: int = 3000, lr: float = 0.5) -> np.ndarray:
    """Weights of a logistic regression of t on X (with a bias), each row weighted by w."""
    Xb = np.c_[X, np.ones(len(X))]
    b = np.zeros(Xb.shape[1])
    for _ in range(iters):
        p = 1.0 / (1.0 + np.exp(-Xb @ b))
        b -= lr * (Xb.T @ ((p - t) * w) / w.sum() + l2 * b)
    return b


def analyse(d: dict) -> None:
    """The differences by kind of epoch, their correlation with each feature, and what a
    decision rule fitted on half of the scenarios gains on the other half."""
    y, F, ids = d["d_exp"], d["feats"], d["id"]
    n_sc = len(set(ids.tolist()))
    print(f"{n_sc} scenarios, {len(y)} flipped decisions; expected points from the flipped "
          "epoch on, flipped row - base row")
    for name, m in (("event epochs (reallocates; flip: keep)", d["base_choice"]),
                    ("quiet epochs (keeps; flip: reallocate)", ~d["base_choice"])):
        x = y[m]
        if x.size < 2:
            continue
        print(f"{name}: n {x.size}, mean {x.mean():+.2f} ± {1.96 * x.std(ddof=1) / np.sqrt(x.size):.2f}"
              f", sd {x.std(ddof=1):.1f}, share > 0 {np.mean(x > 0):.2f}, R_C: mean "
              f"{d['d_rc'][m].mean():+.2f}")
        corr = [f"{FEATURES[j]} {np.corrcoef(F[m, j], x)[0, 1]:+.2f}"
                for j in range(F.shape[1]) if F[m, j].std() > 0]
        print("  correlation with the difference: " + ", ".join(corr))
        # a rule fitted on half of the scenarios (flip where the fitted probability that
        # flipping gains is above 1/2), applied to the other half
        X = F[m]
        X = (X - X.mean(0)) / (X.std(0) + 1e-9)
        sid = ids[m]
        scen = np.unique(sid)
        np.random.default_rng(0).shuffle(scen)
        first = np.isin(sid, scen[: len(scen) // 2])
        for fit_on, test in ((first, ~first), (~first, first)):
            b = _logistic(X[fit_on], (x[fit_on] > 0).astype(float), np.abs(x[fit_on]))
            p = 1.0 / (1.0 + np.exp(-np.c_[X[test], np.ones(test.sum())] @ b))
            flip = p > 0.5
            per = len(set(sid[test].tolist()))
            print(f"  fitted rule, other half: flips {flip.sum()} of {test.sum()}, their sum "
                  f"{x[test][flip].sum() / per:+.2f} per scenario (flipping only the gains: "
                  f"{np.clip(x[test], 0, None).sum() / per:+.2f})")


def load(files: list[str]) -> dict[str, np.ndarray]:
    """The records of several runs together (the features all of them have)."""
    d = [dict(np.load(f)) for f in files]
    width = min(x["feats"].shape[1] for x in d)
    for x in d:
        x["feats"] = x["feats"][:, :width]
    return {k: np.concatenate([x[k] for x in d]) for k in d[0]}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("setting", help="a or b, or 'analyse' and then the .npz files")
    ap.add_argument("level")
    ap.add_argument("n", type=int)
    ap.add_argument("flips", type=int, nargs="?", default=99)
    ap.add_argument("--seed", type=int, default=99000017)
    ap.add_argument("--first", type=int, default=0)
    ap.add_argument("-o", default="")
    if len(sys.argv) > 1 and sys.argv[1] == "analyse":
        analyse(load(sys.argv[2:]))
        return
    a = ap.parse_args()
    s = session(a.setting, a.level, a.seed)
    d = labels(s, np.arange(a.first, a.first + a.n), a.flips, np.random.default_rng(a.seed))
    analyse(d)
    if a.o:
        np.savez(a.o, **d)


if __name__ == "__main__":
    main()
