"""One run path under `ata run` and `ata eval`: a plan's work units run into an output folder.

`run_plan` does, for both commands alike: the executor (made and checked first), the output
folder (made and checked writable; a training run's folder refused; locked against a second
run at once), its durable record (`runlog.RunLog`: resumed where it stopped, a folder of another
plan refused unless forced), the resume message, the progress, the units themselves
(`units.run_units`), Ctrl-C (`Interrupted`, saying what was saved), and the writing of the
results while the folder is still held. The commands differ only in their `Plan` (runner's
`mission_plan`, evaluate's `eval_plan`) and in what they write at the end.
"""

from __future__ import annotations

import contextlib
import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, ContextManager, TypeVar

import numpy as np

from ata.backend import Backend
from ata.core.errors import MissionError
from ata.core.mission import Mission
from ata.core.registry import Register
from ata.experiment import runlog
from ata.experiment.units import make_units, run_units
from ata.runtime import memory
from ata.runtime.executors import make_executor
from ata.runtime.folders import cannot_write, prepare_out_dir

T = TypeVar("T")
Advance = Callable[[float], None]
ProgressFactory = Callable[[str, int, int], ContextManager[Advance]]
"""``progress(title, total scenarios, scenarios done before)``: a context whose value is told
of n more scenarios done (the CLI's progress bar)."""


@dataclass
class Plan:
    """The work of one output folder: each job's mission, registry, backend (where its
    decisions run: `ata.backend`) and chunks of scenario ids (a work unit each, in order), and
    what identifies the plan.

    :param key: the digest of everything that decides the rows (`runlog.plan_key`): a folder
        recorded under another key is another plan's.
    :param describe: what the plan is, for people (plan.json).
    :param unit_name: how messages name the units ("batches", "work units").
    :param title: the progress bar's label.
    :param default_out: makes the output folder when none is given.
    :param notes: what the user is told before the plan runs (how it was cut to fit memory).
    :param command: the command whose folder this is ("run", "eval": `folders.KINDS`),
        recorded in plan.json; a folder of another kind is refused.
    """

    missions: list[Mission]
    registries: list[Register]
    backends: list[Backend]
    chunks: list[list[np.ndarray]]
    key: str
    describe: dict[str, Any]
    unit_name: str
    title: str
    default_out: Callable[[], Path]
    notes: list[str] = field(default_factory=list)
    command: str = "run"

    @property
    def units(self) -> int:
        return sum(len(c) for c in self.chunks)

    @property
    def scenarios(self) -> int:
        return sum(int(ids.size) for chunks in self.chunks for ids in chunks)


@dataclass
class Done:
    """A plan run to its end: every unit's results in unit order, for the command to write.

    :param resumed: the units found done in the folder's record.
    :param executor: where the units ran (`Executor.describe`).
    """

    out_dir: Path
    parts: list[dict[str, Any]]
    wall_s: float
    resumed: int
    executor: dict[str, Any]


class Interrupted(Exception):
    """Ctrl-C stopped a plan: the message says what is saved and how to go on."""


def open_out_dir(path: str | Path, command: str = "run") -> Path:
    """An output folder given by the user: refused if another kind of command wrote it (a
    training run's, an evaluation's for `ata run`), then made and checked writable (before any
    work)."""
    return prepare_out_dir(Path(path), kind=command)


def resume_message(log: runlog.RunLog, out_dir: Path, what: str) -> str | None:
    """One line when an output folder's record already holds finished work."""
    if log.resumed == log.units:
        return f"resuming {out_dir}: all {log.units} {what} were done before"
    if log.resumed:
        return (f"resuming {out_dir}: {log.resumed} of {log.units} {what} were done before; "
                f"running the other {log.units - log.resumed}")
    return None


def run_plan(plan: Plan, write: Callable[[Done], T], out: str | Path | None = None, *,
             executor: str = "serial", workers: int | None = None, address: str | None = None,
             cache: str | Path | None = None, force: bool = False,
             notify: Callable[[str], None] | None = None,
             progress: ProgressFactory | None = None) -> T:
    """Run the plan's missing units into `out` (default: `plan.default_out()`), then
    `write(done)` while the folder is still held; its value is returned.

    :param executor: serial, process or ray (`ata.runtime.executors.make_executor`, with
        `workers` and `address`).
    :param cache: the cache folder of results that depend on the scenario alone (None: none).
    :param force: start over in a folder that holds another plan's results.
    :param notify: told of messages for the user (resuming).
    :raises Interrupted: on Ctrl-C, once the units under way are stopped.
    """
    with contextlib.ExitStack() as stack:
        pool = stack.enter_context(make_executor(executor, workers, address))
        if executor != "ray":             # Ray's workers are not on this machine
            memory.check(plan.missions, [max((int(c.size) for c in chunks), default=0)
                                         for chunks in plan.chunks],
                         pool.describe().get("workers", 1) if pool.parallel else 1)
        out_dir = open_out_dir(out, plan.command) if out is not None else plan.default_out()
        stack.enter_context(runlog.FolderLock(out_dir))
        if not force:
            changed_code(out_dir, plan)
        try:
            log = runlog.RunLog(out_dir, plan.key, plan.units, force=force,
                                describe={"command": plan.command, **plan.describe},
                                expected=[ids for chunks in plan.chunks for ids in chunks])
        except runlog.NotSaved as exc:
            raise MissionError("", None, f"{exc}; nothing was run") from None
        stack.callback(log.close)
        for backend in {id(b): b for b in plan.backends}.values():
            # what a backend keeps between batches ends with the plan
            backend.open(pool.parallel)
            stack.callback(backend.close)
        for message in plan.notes + [dropped_message(log), resume_message(log, out_dir,
                                                                          plan.unit_name)]:
            if message and notify is not None:
                notify(message)
        units = make_units(plan.missions, plan.chunks, cache=cache, executor=pool,
                           registries=plan.registries, backends=plan.backends)
        before = sum(int(np.asarray(p["scenario"]).size) for p in log.done.values())
        bar = progress(plan.title, plan.scenarios, before) if progress is not None \
            else contextlib.nullcontext(None)
        try:
            with bar as advance:
                parts, wall = run_units(units, pool, log=log, progress=advance)
        except KeyboardInterrupt:
            raise Interrupted(f"interrupted: {log.saved()} of {log.units} {plan.unit_name} are "
                              f"saved in {out_dir}; run the same command with --out {out_dir} "
                              "to go on") from None
        except runlog.NotSaved as exc:
            raise MissionError("", None, f"{exc}; {log.saved()} of {log.units} "
                               f"{plan.unit_name} are saved in {out_dir}: make room (or make "
                               f"it writable), then run the same command with --out {out_dir} "
                               "to go on") from None
        log.close()
        try:
            return write(Done(out_dir=out_dir, parts=parts, wall_s=wall, resumed=log.resumed,
                              executor=pool.describe()))
        except OSError as exc:
            raise MissionError("", None, f"{cannot_write(exc, out_dir)}; all {log.units} "
                               f"{plan.unit_name} are saved in {out_dir / runlog.UNITS}: make "
                               f"room (or make it writable), then run the same command with "
                               f"--out {out_dir} to write the results") from None


def dropped_message(log: runlog.RunLog) -> str | None:
    """One line when lines of the folder's record did not fit the plan (they run again)."""
    if not log.dropped:
        return None
    return (f"{len(log.dropped)} line(s) of {log.path} did not fit the plan and were dropped, "
            f"their work units to run again: {'; '.join(log.dropped)}")


def changed_code(out_dir: Path, plan: Plan) -> None:
    """Refuse to resume a folder whose results were made with other code of a component (its
    plan.json's ``code``), naming each component that changed and --force."""
    try:
        before = json.loads((out_dir / runlog.PLAN).read_text(encoding="utf-8")).get("code")
    except (OSError, ValueError, AttributeError):
        return
    now = plan.describe.get("code")
    if not isinstance(before, dict) or not isinstance(now, dict):
        return
    changed = [name for name, digest in now.items() if name in before and before[name] != digest]
    if changed:
        raise MissionError("--out", None, f"{out_dir} holds results made with other code of "
                           f"{', '.join(changed)} (its code changed since: "
                           + "; ".join(f"{n} {before[n]} there, {now[n]} here" for n in changed)
                           + "); run with --force to start afresh there, or choose another "
                           "folder")
