"""Helpers shared by the tests: kernel traces, tiny hand-built scenarios, small MILP
instances, kill-and-resume.

Tiny scenarios: robots start at the base (1000, 1000); positions are given relative to it.
Codes: kind 0 = air, 1 = ground; difficulty 0/1/2 = low/medium/high (15/25/35 points); quality
0..3 = Low/Medium/Upper-Medium/High; robot type 0 = UAV (8 m/s), 1 = UGV (3 m/s); skill band
0/1/2 = low/medium/high (speed x 2/3, 1, 1.5). Observed positions are divided by the 2000 m side.
"""

import inspect
import math

import numpy as np
import pytest

from ata import hookimpl
from ata.core.kernel import Simulation
from ata.session import BASELINE_MISSION, load_session, training_mission_for
from ata.core.state import Allocation
from ata.model import tables
from ata.plugins.policies import milp as M


# -- a tiny team for ATA-HRL's trainer and components (test_ata_hrl*.py) -----------------------

HRL_TINY = ["mission.setting='custom'", "mission.humans=3", "mission.robots=4", "mission.tasks=12",
            "mission.horizon_s=600", "ata_hrl.batch_size=2", "ata_hrl.samples=2",
            "ata_hrl.ita_steps=2", "ata_hrl.ctr_steps=2", "ata_hrl.aux_steps=3",
            "ata_hrl.aux_batches=1", "ata_hrl.eval_every=1", "ata_hrl.eval_scenarios=2",
            "ata_hrl.checkpoint_every=1", "ata_hrl.d_model=16", "ata_hrl.hidden=16",
            "ata_hrl.recon_hidden=8", "ata_hrl.status_steps=3", "ata_hrl.status_batches=1",
            "ata_hrl.status_hidden=8", "ata_hrl.status_levels=['high']"]


def greedy_pair_suite(scenarios: int, other: str) -> str:
    """A one-cell suite ((a), high, root seed 0) of greedy beside greedy deciding to reallocate
    at every epoch, named `other`: two quick methods whose rows differ."""
    return f"""[suite]
settings = ["a"]
uncertainty = ["high"]
scenarios = {scenarios}
seed = 0

[[method]]
name = "greedy"
mission = "builtin:greedy"

[[method]]
name = "{other}"
mission = "builtin:greedy"
set = ["components.condition=always"]
"""


def hrl_session(*extra, plugins=("ctr", "aux")):
    """The ATA-HRL training mission of `plugins` on the tiny team, with `extra` overrides."""
    return load_session(str(training_mission_for(list(plugins))), [*HRL_TINY, *extra])

BASE = 1000.0
AIR, GROUND = 0, 1
LOW, MED, HIGH = 0, 1, 2
UAV, UGV = 0, 1
INF = math.inf


def flat(text: str) -> str:
    """Whitespace collapsed, so that a message wrapped by rich still matches."""
    return " ".join(text.split())


def assert_user_error(result, *fragments: str) -> None:
    """A CLI result: exit 2, no traceback, exactly one message, holding every fragment."""
    assert result.exit_code == 2, result.output
    # typer.Exit(2), not an uncaught exception (CliRunner would report one as exit code 1)
    assert result.exception is None or isinstance(result.exception, SystemExit)
    assert "Traceback" not in result.output
    lines = result.output.splitlines()
    assert lines[0].startswith("error: ")
    assert sum(line.startswith("error:") for line in lines) == 1, result.output
    text = flat(result.output)
    for fragment in fragments:
        assert fragment in text, f"{fragment!r} not in {text!r}"


def assert_trace(actual, expected):
    """Events equal one by one; floats to 1e-9 s."""
    assert len(actual) == len(expected), f"trace {actual}\n  expected {expected}"
    for a, e in zip(actual, expected):
        assert len(a) == len(e), f"{a} != {e}"
        for x, y in zip(a, e):
            if isinstance(y, float):
                assert x == pytest.approx(y, rel=1e-12, abs=1e-9), f"{a} != {e}"
            else:
                assert x == y and type(x) is type(y), f"{a} != {e}"


def tiny_data(seed: int, P: int = 4, H: int = 2, R: int = 2) -> M.ScenarioData:
    gen = np.random.default_rng(seed)
    theta_s = gen.uniform(0, np.pi / 4, H)
    theta_s[0] = 0.7                       # one highly skilled human, so navigators are options
    kind, diff = gen.integers(0, 2, P), gen.integers(0, 3, P)
    xy, eta = gen.uniform(0, 2000, (P, 2)), np.sin(gen.uniform(0, np.pi / 4, H))
    hours = gen.uniform(0, 1.5, H)
    # the population line's F_f now and after a shift at the default cap (0.65 of 600 s)
    worn = hours + M.MilpSettings().human_utilisation_cap * 600.0 / 3600.0
    return M.ScenarioData(kind=kind, diff=diff, xy=xy, eta=eta, lam=np.sin(theta_s),
                          skill=tables.skill_band(theta_s), hours=hours,
                          fatigue_now=tables.fatigue(hours), fatigue_worn=tables.fatigue(worn),
                          rtype=np.array([0, 1] * (R // 2)), speed=np.array([8.0, 3.0] * (R // 2)),
                          area_m=2000.0, horizon_s=600.0, event_p=0.2,
                          fatigue_sigma=np.sqrt(0.1))


class Killed(Exception):
    """Raised from a trainer's log hook to kill a run mid-phase."""


def train(session, run_dir, *, resume: bool = False, on_row=None):
    """Build the mission's trainer and run it in run_dir (as `ata train` does); return it."""
    from ata.session import build_trainer
    from ata.training import TrainRun
    trainer = build_trainer(session)
    run = TrainRun(run_dir, session.mission.to_toml(), trainer.log_fields, resume=resume,
                   on_row=on_row)
    trainer.report = trainer.run(run, resume=resume)
    return trainer


def whole_and_killed(session, tmp_path, phase: str, step: str):
    """Train `session` to the end in tmp_path/whole; train it again in tmp_path/broken, killed
    when the log reaches (phase, step); resume the broken run from its folder and return both
    trainers."""
    from ata.session import load_session

    whole = train(session, tmp_path / "whole")

    def kill(row):
        if row["phase"] == phase and str(row["step"]) == step:
            raise Killed

    with pytest.raises(Killed):
        train(session, tmp_path / "broken", on_row=kill)
    again = load_session(str(tmp_path / "broken" / "mission.resolved.toml"))
    resumed = train(again, tmp_path / "broken", resume=True)
    logs = [(tmp_path / d / "log.csv").read_text().splitlines() for d in ("whole", "broken")]
    steps = [[tuple(line.split(",")[:2]) for line in log] for log in logs]
    assert steps[1] == steps[0]          # the steps done again are not logged twice
    return whole, resumed


# --- inline components and helpers ----------------------------------------------------------------

class Fixed:
    """A policy that allocates the given per-POI triples in every scenario, at t = 0 and at every
    reallocation; it remembers the contexts it saw."""

    def __init__(self, robot, navigator, classifier):
        self.triples = (robot, navigator, classifier)
        self.seen = []

    def _alloc(self, ctx):
        shape = ctx.reallocatable.shape
        return Allocation(*(np.broadcast_to(np.asarray(x, dtype=np.int64), shape).copy()
                            for x in self.triples))

    @hookimpl
    def ata_initial_allocation(self, ctx):
        self.seen.append(ctx)
        return self._alloc(ctx)

    @hookimpl
    def ata_reallocate(self, ctx, active):
        self.seen.append(ctx)
        return self._alloc(ctx)


class Scripted(Fixed):
    """A reallocation policy whose triples are a function of the epoch: script(epoch) -> triples."""

    def __init__(self, script):
        super().__init__(*script(0))
        self.script = script

    @hookimpl
    def ata_reallocate(self, ctx, active):
        self.seen.append((ctx.epoch, ctx.reallocatable.copy()))
        self.triples = self.script(ctx.epoch)
        return self._alloc(ctx)


def make_sim(triples, *, humans=1, robots=1, tasks=1, batch=1, condition="never",
             reallocation=None, extra=()):
    """A traced simulation of `batch` scenarios, reset, with no uncertainty at all and every
    human on the population's fatigue line (spread 0, so hand computations use 1.3 - 0.3 T);
    `extra` holds more --set overrides (the re-tasking costs, say)."""
    s = load_session(str(BASELINE_MISSION), ["human.fatigue_spread=0", *extra,
                                             "mission.setting='custom'",
                                             f"mission.humans={humans}",
                            f"mission.robots={robots}", f"mission.tasks={tasks}",
                            "mission.uncertainty='none'", f"mission.scenarios={batch}",
                            f"mission.batch_size={batch}", f"components.condition='{condition}'"])
    initial = Fixed(*triples)
    sim = Simulation(s.mission, s.registry, list(range(batch)), trace=True,
                     overrides={"initial": initial,
                                "reallocation": reallocation or Fixed(*triples)})
    sim.reset()
    sim.policy = initial
    return sim


def set_robots(sim, types, fail_time=None):
    r = sim.sim.groups["robots"]
    r.type[:] = types
    r.speed[:] = np.where(np.asarray(types) == UAV, 8.0, 3.0)
    if fail_time is not None:
        r.fail_time[:] = fail_time


def set_tasks(sim, spec):
    """spec: one (dx, dy, kind, difficulty, outcome_u) per POI; estimate = truth."""
    t = sim.sim.groups["tasks"]
    for p, (dx, dy, kind, diff, u) in enumerate(spec):
        t.pos[:, p] = (BASE + dx, BASE + dy)
        t.est_kind[:, p] = t.true_kind[:, p] = kind
        t.est_diff[:, p] = t.true_diff[:, p] = diff
        t.outcome_u[:, p] = u
        t.reveal_time[:, p] = INF


def set_humans(sim, spec):
    """spec: one (skill band, eta, lambda, t0 hours) per human."""
    h = sim.sim.groups["humans"]
    for i, (skill, eta, lam, t0) in enumerate(spec):
        h.skill[:, i], h.eta[:, i], h.lam[:, i], h.t0_h[:, i] = skill, eta, lam, t0


def run_epochs(sim, n=None):
    """Step n epochs (default: to the horizon); end the episode when the horizon is reached."""
    n = sim.sim.clock.n_epochs - sim.sim.epoch if n is None else n
    for _ in range(n):
        sim.step_epoch()
    if sim.sim.epoch == sim.sim.clock.n_epochs:
        sim.pm.hook.ata_episode_end(sim=sim.sim)


def observed_after(sim, n):
    """Step until epoch n has been observed; return that epoch's observed S."""
    while sim.sim.epoch <= n:
        sim.step_epoch()
    return sim.last_context.observed


def perf(sim, b=0):
    return {k: v for k, v in enumerate(sim.sim.record.r_perf[b]) if v != 0}


def small_mission(scenarios: int) -> str:
    """The text of a small custom mission (2 humans, 3 robots, 10 POIs) for the CLI's tests."""
    return (f'[mission]\nname = "small"\nsetting = "custom"\nhumans = 2\nrobots = 3\n'
            f'tasks = 10\nscenarios = {scenarios}\n')


def running_world():
    """The world (`SimState`) of the Simulation that called the caller, found up the call
    stack: how a deliberately peeking test component reads what no context hands it."""
    frame = inspect.currentframe()
    while not isinstance(frame.f_locals.get("self"), Simulation):
        frame = frame.f_back
    return frame.f_locals["self"].sim
