"""A trainer's rollouts on its `threads` processes: an ITA step's, and every validation's.

A rollout (an ITA step's: its episodes' sampled initial allocations, then the episodes played
with nothing reallocated; a validation's: every decision by its mode) is one thread's work, its
decode and the simulation alike, while the update after it takes both cores. Here the episodes
are split into `threads` parts of whole rows, the first played in this process and each other in
a worker process forked from the trainer (the network's weights sent with each part). An
episode's play reads its own rows alone, so the parts' records, joined, are the record of one
process. An ITA step samples every choice with the trainer's torch generator: its noise is drawn
first, for as many steps as the decode may take, in the order the step-by-step loop draws it
(`gumbel_block`); each part chooses with its rows of it (`block_sampler`); then the generator is
put where one process's loop leaves it. So the record, the recorded decisions and the generator
are those of one process, to the bit, whatever the parts (tests/test_rollouts.py).
"""

from __future__ import annotations

import dataclasses
import multiprocessing
import signal
from typing import Any, Callable

import numpy as np
import torch

from ata.core.kernel import Simulation
from ata.core.state import EpisodeRecord
from ata.plugins.ata_hrl import decode as D
from ata.plugins.ata_hrl.arch import KINDS
from ata.plugins.ata_hrl.components import Recorder

_HOST: Any = None
"""The trainer whose rollouts the worker processes play (they inherit it: forked)."""


def gumbel_block(gen: torch.Generator, steps: int, E: int, widths: tuple[int, ...]
                 ) -> list[np.ndarray]:
    """log(-log(u)) of the uniforms `logprob.torch_sampler` would draw with `gen` over `steps`
    steps of a decode whose sub-decisions have `widths` candidates: per width, a
    (steps, E, width) float32 array. (Torch's CPU generator gives one draw the numbers of the
    draws it stands for, in turn.)"""
    W = sum(widths)
    u = torch.rand(steps * E * W, generator=gen).clamp(1e-12, 1 - 1e-12)
    g = torch.log(-torch.log(u)).numpy().reshape(steps, E * W)
    out, at = [], 0
    for n in widths:
        out.append(np.ascontiguousarray(g[:, at:at + E * n]).reshape(steps, E, n))
        at += E * n
    return out


def block_sampler(noise: list[np.ndarray]) -> D.Chooser:
    """`logprob.torch_sampler`'s choices from its noise drawn beforehand (`gumbel_block`): the
    first maximum of the logits less the noise of the call's step and kind."""
    calls = [0]

    def choose(kind: str, logits: np.ndarray) -> np.ndarray:
        step, i = divmod(calls[0], len(KINDS))
        calls[0] += 1
        g = noise[i][step]
        assert KINDS[i] == kind and g.shape == logits.shape, (kind, g.shape, logits.shape)
        return (logits - g).argmax(-1)

    return choose


class StackedTrace(D.DecodeTrace):
    """A `decode.DecodeTrace` whose steps are stacked: per kind, arrays (S, E, ...)."""

    def __init__(self, arrays: dict[str, dict[str, np.ndarray]]):
        super().__init__()
        self.arrays = arrays

    @property
    def n_steps(self) -> int:
        return self.arrays["poi"]["choice"].shape[0]

    def stacked(self, kind: str) -> dict[str, np.ndarray]:
        return self.arrays[kind]

    def take(self, rows: slice) -> "StackedTrace":
        return StackedTrace({kind: {k: v[:, rows] for k, v in d.items()}
                             for kind, d in self.arrays.items()})


class Rollouts:
    """The rollouts of trainer `host` on `workers` processes: an ITA step's, sampled and
    recorded (`ita`), and any phase's by the mode (`mode`, a validation's)."""

    def __init__(self, host: Any, workers: int):
        self.host, self.workers = host, workers
        self.pool: list[_Worker] = []

    def ita(self, mission: Any, ids: np.ndarray) -> tuple[EpisodeRecord, Recorder]:
        """An ITA step's rollout of scenarios `ids`, the step-by-step loop's to the bit."""
        host, gen = self.host, self.host.gen
        s = mission.sizes
        widths = (s.tasks, s.robots, s.humans + 1, s.humans + 1)
        E = ids.size
        state = gen.get_state()
        noise = gumbel_block(gen, s.tasks, E, widths)      # a step gives one POI away
        parts = self._split(ids, "ita", lambda r: (mission, ids[r], [
            np.ascontiguousarray(n[:, r]) for n in noise]))
        record = concat_records([p[0] for p in parts])
        rec = Recorder(inherent={g: np.concatenate([p[1].inherent[g] for p in parts])
                                 for g in parts[0][1].inherent},
                       ita=concat_traces([StackedTrace({k: p[1].ita.stacked(k) for k in KINDS})
                                          for p in parts]))
        gen.set_state(state)       # then the draws of the steps taken alone
        torch.rand(rec.ita.n_steps * E * sum(widths), generator=gen)
        return record, rec

    def mode(self, mission: Any, ids: np.ndarray, phase: str) -> EpisodeRecord:
        """Scenarios `ids` as `phase` plays them, every decision by its mode."""
        return concat_records(self._split(ids, "mode", lambda r: (mission, ids[r], phase)))

    def _split(self, ids: np.ndarray, job: str, args: Callable[[np.ndarray], tuple]
               ) -> list[tuple]:
        """The job on parts of the rows of `ids`, the first here, each other in a worker."""
        rows = np.array_split(np.arange(ids.size), max(1, min(self.workers, ids.size)))
        if len(rows) == 1 or not self._start():
            return [_job(self.host, job, *args(np.arange(ids.size)))]
        weights = {k: v.detach().cpu().numpy().copy()
                   for k, v in self.host.net.state_dict().items()}
        for worker, r in zip(self.pool, rows[1:]):
            worker.send(weights, job, *args(r))
        try:
            first = _job(self.host, job, *args(rows[0]))
        finally:
            rest = [worker.result() for worker in self.pool]
        return [first] + rest

    def _start(self) -> bool:
        """Whether worker processes play (a daemonic process may not start any: it plays
        every part itself)."""
        if not self.pool and self.workers > 1:
            global _HOST
            _HOST = self.host
            if multiprocessing.current_process().daemon:
                self.workers = 1
            else:
                self.pool = [_Worker() for _ in range(self.workers - 1)]
        return bool(self.pool)

    def close(self) -> None:
        for worker in self.pool:
            worker.close()
        self.pool = []


class _Worker:
    """A worker process forked from the trainer, serving parts over a pipe (no thread in the
    trainer's process); it ends when told, or when the trainer's end of the pipe closes."""

    def __init__(self):
        context = multiprocessing.get_context("fork")
        self.conn, child = context.Pipe()
        self.proc = context.Process(target=_serve, args=(child,), daemon=True)
        self.proc.start()
        child.close()

    def send(self, *message: Any) -> None:
        self.conn.send(message)

    def result(self) -> Any:
        ok, value = self.conn.recv()
        if not ok:
            raise value
        return value

    def close(self) -> None:
        try:
            self.conn.send(None)
        except OSError:
            pass
        self.proc.join(timeout=10)
        if self.proc.is_alive():
            self.proc.terminate()
        self.conn.close()


def _serve(conn: Any) -> None:
    """A worker's loop: each message a part to play (`_remote`), its result or error sent
    back. Ctrl-C is the trainer's to handle: the worker ignores it."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    while True:
        try:
            message = conn.recv()
        except EOFError:
            return
        if message is None:
            return
        try:
            conn.send((True, _remote(*message)))
        except Exception as exc:        # noqa: BLE001 - raised again in the trainer
            conn.send((False, exc))


def play(host: Any, mission: Any, ids: np.ndarray, net: Any, sampler: D.Chooser
         ) -> tuple[EpisodeRecord, Recorder]:
    """Episodes `ids` of an ITA step with network `net`, each choice sampled by `sampler`
    (`block_sampler`; `logprob.torch_sampler` draws as it goes) and recorded."""
    rec = Recorder()
    overrides = host.overrides(mission, "ita", None, None)
    overrides["initial"].train_with(net, rec, sampler)
    return Simulation(mission, host.registry, ids, overrides=overrides).run(), rec


def play_mode(host: Any, mission: Any, ids: np.ndarray, phase: str) -> EpisodeRecord:
    """Episodes `ids` as `phase` plays them, every decision by its mode."""
    return Simulation(mission, host.registry, ids,
                      overrides=host.overrides(mission, phase, None, None)).run()


def _job(host: Any, job: str, *args: Any) -> Any:
    if job == "ita":
        mission, ids, noise = args
        return play(host, mission, ids, host.net, block_sampler(noise))
    return play_mode(host, *args)


def _remote(weights: dict[str, np.ndarray], job: str, *args: Any) -> tuple:
    """`play` or `play_mode` in a worker process, its trainer's network given the weights
    sent."""
    _HOST.net.load_state_dict({k: torch.from_numpy(v) for k, v in weights.items()})
    return _job(_HOST, job, *args)


def concat_records(records: list[EpisodeRecord]) -> EpisodeRecord:
    """The records of consecutive parts of a batch as one (every field is per scenario)."""
    if len(records) == 1:
        return records[0]
    out = {}
    for f in dataclasses.fields(EpisodeRecord):
        values = [getattr(r, f.name) for r in records]
        if f.name == "metrics":
            out[f.name] = {k: np.concatenate([v[k] for v in values]) for k in values[0]}
        elif f.name == "warnings":
            out[f.name] = [w for v in values for w in v]
        elif values[0] is None:
            out[f.name] = None
        else:
            out[f.name] = np.concatenate(values)
    return EpisodeRecord(**out)


def concat_traces(traces: list[StackedTrace]) -> StackedTrace:
    """The traces of consecutive parts of a batch as one: each part's steps, then zero rows
    (an episode that takes no step) up to the longest part's."""
    if len(traces) == 1:
        return traces[0]
    S = max(t.n_steps for t in traces)
    out: dict[str, dict[str, np.ndarray]] = {}
    for kind in KINDS:
        out[kind] = {}
        for key in traces[0].arrays[kind]:
            parts = []
            for t in traces:
                a = t.arrays[kind][key]
                pad = np.zeros((S - a.shape[0],) + a.shape[1:], a.dtype)
                parts.append(np.concatenate([a, pad]) if pad.shape[0] else a)
            out[kind][key] = np.concatenate(parts, axis=1)
    return StackedTrace(out)
