"""Running the decoder with a network: choose step by step (mode, sample or the prior alone),
and record what a training update needs to recompute each choice's log-probability
(``logprob``). The network is ``infer``'s, in numpy: deciding needs no torch."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from ata.core.state import Allocation
from ata.plugins.ata_hrl import fused, scorer_loop
from ata.plugins.ata_hrl.decoder import Decoder
from ata.plugins.ata_hrl.inputs import StepInputs
from ata.plugins.ata_hrl.arch import KINDS
from ata.plugins.ata_hrl.infer import AllocationPart

Chooser = Callable[[str, np.ndarray], np.ndarray]
"""(kind, logits (E, N)) -> chosen index per episode (E,)."""


def argmax_chooser(kind: str, logits: np.ndarray) -> np.ndarray:
    # numpy's argmax: the first of equal maxima
    return logits.argmax(-1)


def stream_sampler(uniform: Callable[[str, int, tuple], np.ndarray]) -> Chooser:
    """Sample by the Gumbel-max trick from each scenario's own random stream (evaluation), so a
    scenario's choices do not depend on its batch. `uniform(name, counter, shape)`."""
    counter = {"n": 0}

    def choose(kind: str, logits: np.ndarray) -> np.ndarray:
        counter["n"] += 1
        u = np.clip(uniform(f"ata_hrl.{kind}", counter["n"], tuple(logits.shape[1:])),
                    1e-12, 1 - 1e-12)
        g = (-np.log(-np.log(u))).astype(logits.dtype)
        return (logits + g).argmax(-1)

    return choose


@dataclass
class DecodeTrace:
    """Per sub-decision kind, per step: the inputs, the context indices and the choice; and
    pi_TR's keep step (its inputs and choices), when there was one."""

    steps: dict[str, dict[str, list[np.ndarray]]] = field(
        default_factory=lambda: {k: {"features": [], "mask": [], "prior": [], "choice": [],
                                     "active": [], "robot": [], "task": []} for k in KINDS})
    keep: dict[str, np.ndarray] | None = None

    def add(self, kind: str, inp: StepInputs, mask: np.ndarray, choice: np.ndarray,
            active: np.ndarray, robot: np.ndarray | None, task: np.ndarray | None) -> None:
        d = self.steps[kind]
        d["features"].append(inp.features)
        d["mask"].append(mask)
        d["prior"].append(inp.prior.astype(np.float32))
        d["choice"].append(choice)
        d["active"].append(active)
        zeros = np.zeros_like(choice)
        d["robot"].append(zeros if robot is None else robot)
        d["task"].append(zeros if task is None else task)

    @property
    def n_steps(self) -> int:
        return len(self.steps["poi"]["choice"])

    def stacked(self, kind: str) -> dict[str, np.ndarray]:
        return {k: np.stack(v) for k, v in self.steps[kind].items()}

    def take(self, rows: slice) -> "DecodeTrace":
        """The trace of the episodes `rows` alone (views of this one's arrays)."""
        out = DecodeTrace({kind: {k: [a[rows] for a in v] for k, v in d.items()}
                           for kind, d in self.steps.items()})
        if self.keep is not None:
            out.keep = {k: v[rows] for k, v in self.keep.items()}
        return out


def _finite(x: np.ndarray, **fill) -> np.ndarray:
    """`x` with nan and inf replaced (np.nan_to_num), without the copy when all is finite."""
    return x if np.isfinite(x).all() else np.nan_to_num(x, **fill)


def _clean(inp: StepInputs) -> StepInputs:
    """Finite inputs: episodes whose decoding is over carry dummy choices (a robot that is
    down, say), whose features may be inf - inf; their decisions are masked out anyway."""
    return StepInputs(_finite(inp.features, nan=0.0, posinf=10.0, neginf=-10.0),
                      inp.mask, _finite(inp.prior, nan=-1.0, posinf=1e3, neginf=-1e3),
                      inp.active)


SHRINK = 0.75
"""A decode without a trace goes on with the episodes still deciding once at most this share
of its working set is (a finished episode's choices are masked: dropping it changes none)."""


def decode(dec: Decoder, net: AllocationPart, emb: dict[str, np.ndarray], choose: Chooser,
           *, residual: bool = True, trace: DecodeTrace | None = None) -> Allocation:
    """Decode every POI left in `dec` with the network's scorers (no gradient). Without a
    trace, and taking the mode, the whole decode runs compiled (`fused`) where the fatigue
    projections are of one curve, else the steps work on the episodes still deciding alone."""
    root, rows_in_root = dec, np.arange(dec.E)
    shrink = trace is None and choose is argmax_chooser
    steps = _Steps(net, emb, choose, residual, trace)
    if shrink and fused.fits(dec):
        # the mode, nothing recorded: the whole decode in one compiled loop
        fused.decode_mode(dec, steps.weights, steps.tokens["tasks"], steps.tokens["robots"],
                          steps.cand_hidden, residual)
        return dec.finish()
    while True:
        pi = dec.poi_inputs()
        active = pi.active
        n_active = int(active.sum())
        if n_active == 0:
            break
        if shrink and n_active <= SHRINK * dec.E:
            keep = np.flatnonzero(active)
            dec.put(root, rows_in_root)
            dec, rows_in_root = dec.take(keep), rows_in_root[keep]
            steps = steps.take(keep)
            pi = dec.poi_inputs()
            active = pi.active
        p = steps.pick("poi", pi, active, dec.r_ff, None)
        ri = dec.robot_inputs(p)
        r = steps.pick("robot", ri, active, None, p)
        ni = dec.nav_inputs(p, r)
        n = steps.pick("nav", ni, active, r, p) - 1
        ci = dec.cls_inputs(p, r, n)
        c = steps.pick("cls", ci, active, r, p) - 1
        dec.commit(active, p, r, n, c)
    if dec is not root:
        dec.put(root, rows_in_root)
    return root.finish()


class _Steps:
    """The network's side of a decode: the tokens and the candidates' projections, as arrays
    made once per decode, and the choice of each sub-decision from its inputs, its logits by the
    compiled scorer (`scorer_loop`)."""

    def __init__(self, net: AllocationPart, emb: dict[str, np.ndarray], choose: Chooser,
                 residual: bool, trace: DecodeTrace | None):
        self.choose, self.residual, self.trace = choose, residual, trace
        self.weights = net.scorers
        self.tokens = {g: _array(emb[g]) for g in ("tasks", "robots")}
        E = self.tokens["tasks"].shape[0]
        self.zeros = np.zeros(E, np.int64)
        # the candidates are the same at every step: their projection once per decode
        self.cand_hidden = {}
        for k in KINDS:
            cand = _array(net.candidates(k, emb))
            Ek, N, d = cand.shape
            self.cand_hidden[k] = scorer_loop.project(
                cand.reshape(Ek * N, d), self.weights[k].cand_w).reshape(Ek, N, -1)

    def take(self, rows: np.ndarray) -> "_Steps":
        """The same for episodes `rows` alone."""
        out = _Steps.__new__(_Steps)
        out.choose, out.residual, out.trace = self.choose, self.residual, self.trace
        out.weights = self.weights
        out.tokens = {g: v[rows] for g, v in self.tokens.items()}
        out.zeros = np.zeros(len(rows), np.int64)
        out.cand_hidden = {k: v[rows] for k, v in self.cand_hidden.items()}
        return out

    def pick(self, kind: str, inp: StepInputs, active: np.ndarray, robot, task) -> np.ndarray:
        """The choice of sub-decision `kind` in every episode (recorded in the trace)."""
        inp = _clean(inp)
        mask = inp.mask
        n = mask.shape[1]
        hid = self.cand_hidden[kind]
        if n != hid.shape[1]:
            hid = np.ascontiguousarray(hid[:, :n])
        logits = scorer_loop.logits(
            kind, self.weights[kind], inp.features, inp.prior, mask, hid,
            self.tokens["tasks"], self.tokens["robots"],
            self.zeros if robot is None else robot, self.zeros if task is None else task,
            self.residual)
        choice = self.choose(kind, logits)
        if self.trace is not None:
            self.trace.add(kind, inp, mask, choice, active, robot, task)
        return choice


def _array(t: np.ndarray) -> np.ndarray:
    """Tokens as a contiguous float32 array."""
    return np.ascontiguousarray(t, dtype=np.float32)


DECODE, KEEP, HEURISTIC = 0, 1, 2
"""pi_TR's first step, per POI: decode it again, keep its triple, take greedy's."""


def decide_keep(inputs: StepInputs, net: AllocationPart, emb: dict[str, np.ndarray],
                choose: Chooser, *, residual: bool = True,
                trace: DecodeTrace | None = None) -> np.ndarray:
    """pi_TR's first step: (E, P) DECODE, KEEP or HEURISTIC per POI (-1 where nothing is
    decided)."""
    inputs = _clean(inputs)
    logits = net.keep(inputs.features, emb["tasks"], inputs.prior.astype(np.float32),
                      inputs.mask, residual)
    choice = choose("keep", logits)
    decided = inputs.mask.any(-1)
    if trace is not None:
        trace.keep = {"features": inputs.features, "mask": inputs.mask,
                      "prior": inputs.prior.astype(np.float32), "choice": choice,
                      "decided": decided}
    return np.where(decided, choice, -1)
