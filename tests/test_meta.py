"""Meta-tests, after datasette's: every hook is documented with its exact signature in the
plugin author's pages (docs/plugins.md, hooks.md, decisions.md), the kernel calls every phase hook as often as the docs say, and no Python file
of the project is over 500 lines (docs/architecture.md)."""

from __future__ import annotations

import inspect
import re
from pathlib import Path

import numpy as np
import pytest

from ata import hookimpl
from ata.core import hookspecs
from ata.core.state import Allocation
from ata.core.registry import KINDS

ROOT = Path(__file__).resolve().parent.parent
DOCS = [ROOT / "docs" / name for name in ("plugins.md", "hooks.md", "decisions.md")]
"""The plugin author's pages: the guide, the hooks of the world, the decision hooks."""
DOC_TEXT = "\n".join(path.read_text(encoding="utf-8") for path in DOCS)
TESTS = Path(__file__).resolve().parent

HOOKS = sorted(name for name, obj in inspect.getmembers(hookspecs, inspect.isfunction)
               if hasattr(obj, "ata_spec"))


def normalise(text: str) -> str:
    """Quotes around annotations dropped, whitespace collapsed, no space inside brackets."""
    text = " ".join(text.replace('"', "").replace("'", "").split())
    return text.replace("( ", "(").replace(" )", ")")


def signature_text(name: str) -> str:
    return normalise(f"def {name}{inspect.signature(getattr(hookspecs, name))}:")


def test_the_hooks_are_the_documented_set():
    # a hook added or removed must be added to or removed from this list, and documented
    assert HOOKS == sorted([
        "ata_register_components", "ata_setup", "ata_inherent", "ata_observe", "ata_inject",
        "ata_reconstruct", "ata_reconstruct_reference", "ata_initial_allocation", "ata_should_reallocate", "ata_reallocate",
        "ata_allocation_changed", "ata_trained_on", "ata_peak_bytes", "ata_advance",
        "ata_epoch_end", "ata_episode_end", "ata_episode_scored"])


@pytest.mark.parametrize("name", HOOKS)
def test_hook_is_documented_with_its_exact_signature(name):
    doc = normalise(DOC_TEXT)
    spec = getattr(hookspecs, name).ata_spec
    marker = "@hookspec(firstresult=True)" if spec["firstresult"] else "@hookspec"
    assert f"{marker} {signature_text(name)}" in doc
    assert f"#### {name} " in doc                         # it has a section of its own


def test_signature_text_is_what_the_source_says():
    """The normalised signature matches the source line, so the doc can copy the source."""
    source = normalise(inspect.getsource(hookspecs))
    for name in HOOKS:
        assert signature_text(name) in source


def test_documented_hooks_all_exist():
    documented = set(re.findall(r"^def (ata_\w+)\(", DOC_TEXT, re.M))
    assert documented == set(HOOKS)


def test_doc_covers_kinds_settings_start_up_and_tracing():
    doc = DOC_TEXT
    for kind in KINDS:
        assert f"`{kind}`" in doc
    for topic in ("register(kind, name, factory)", "class Settings:", "param(",
                  "ATA_TRACE_HOOKS", "check_pending()", "[project.entry-points.ata]",
                  "HUMAN_STATE", "ROBOT_STATE", "TASK_STATE", "HUMAN_INHERENT",
                  "ROBOT_INHERENT", "TASK_INHERENT"):
        assert topic in doc, topic


def test_doc_lists_the_shared_columns_of_the_built_in_models():
    from ata.plugins import humans, robots, tasks

    doc = DOC_TEXT
    for columns in (humans.HUMAN_INHERENT, humans.HUMAN_STATE, robots.ROBOT_INHERENT,
                    robots.ROBOT_STATE, tasks.TASK_INHERENT, tasks.TASK_STATE):
        assert ", ".join(f"`{c}`" for c in columns) in doc, columns


class Counter:
    def __init__(self):
        self.calls: dict[str, int] = {}

    def _count(self, name):
        self.calls[name] = self.calls.get(name, 0) + 1


class Spy(Counter):
    """Counts the calls of every phase hook the kernel broadcasts (in an injector's place)."""

    @hookimpl
    def ata_setup(self, sim):
        self._count("ata_setup")

    @hookimpl
    def ata_inherent(self, sim, inherent):
        self._count("ata_inherent")

    @hookimpl
    def ata_observe(self, sim, obs):
        self._count("ata_observe")

    @hookimpl
    def ata_inject(self, sim, obs):
        self._count("ata_inject")

    @hookimpl
    def ata_reconstruct(self, sim, obs, inherent, out):
        self._count("ata_reconstruct")

    @hookimpl
    def ata_allocation_changed(self, sim, changed, previous):
        self._count("ata_allocation_changed")

    @hookimpl
    def ata_advance(self, sim, t0, t1):
        self._count("ata_advance")

    @hookimpl
    def ata_epoch_end(self, sim, epoch):
        self._count("ata_epoch_end")

    @hookimpl
    def ata_episode_end(self, sim):
        self._count("ata_episode_end")


class Deciders(Counter):
    """Fills the decision slots, counting their calls (a decision-maker implements no hook
    that hands it the world, so it is no Spy)."""

    @hookimpl
    def ata_episode_scored(self, episode):
        self._count("ata_episode_scored")

    @hookimpl
    def ata_initial_allocation(self, ctx):
        self._count("ata_initial_allocation")
        B, P = ctx.reallocatable.shape
        none = np.full((B, P), -1)
        return Allocation(np.arange(B * P).reshape(B, P) % ctx.sizes.robots, none, none.copy())

    @hookimpl
    def ata_should_reallocate(self, ctx):
        self._count("ata_should_reallocate")
        return np.full(ctx.reallocatable.shape[0], ctx.epoch % 2 == 0)

    @hookimpl
    def ata_reallocate(self, ctx, active):
        self._count("ata_reallocate")
        return ctx.previous


class Reference(Counter):
    """A reference reconstructor (the only kind of component the kernel hands the truth)."""

    reference = True

    @hookimpl
    def ata_reconstruct_reference(self, sim, truth, obs, inherent, out):
        self._count("ata_reconstruct_reference")


def test_the_kernel_calls_every_phase_hook_as_often_as_it_says():
    from ata.core.kernel import Simulation
    from ata.session import BASELINE_MISSION, load_session

    session = load_session(str(BASELINE_MISSION), [
        "mission.setting='custom'", "mission.humans=2", "mission.robots=2", "mission.tasks=6",
        "mission.horizon_s=600.0", "mission.scenarios=2", "mission.batch_size=2"])
    clock = session.mission.clock
    spy, deciders, reference = Spy(), Deciders(), Reference()
    overrides = {"injectors": spy, "initial": deciders, "condition": deciders,
                 "reallocation": deciders, "reconstructors": reference}
    Simulation(session.mission, session.registry, [0, 1], overrides=overrides).run()
    T, ticks = clock.n_epochs, clock.n_ticks
    assert spy.calls == {"ata_setup": 1, "ata_inherent": 1, "ata_observe": T, "ata_inject": T,
                         "ata_reconstruct": T, "ata_advance": ticks, "ata_epoch_end": T,
                         "ata_episode_end": 1, "ata_allocation_changed": 1}
    assert reference.calls == {"ata_reconstruct_reference": T}
    assert deciders.calls["ata_initial_allocation"] == 1
    assert deciders.calls["ata_episode_scored"] == 1
    assert deciders.calls["ata_should_reallocate"] == T - 1      # every epoch after the first
    assert deciders.calls["ata_reallocate"] == len(range(2, T, 2))   # when it said yes
    # the start-up hook, ata_trained_on (asked by `ata eval`) and ata_peak_bytes (by the memory
    # check, tests/test_faults_memory.py) are tested where they are used
    assert set(spy.calls) | set(deciders.calls) | set(reference.calls) == set(HOOKS) - {
        "ata_register_components", "ata_trained_on", "ata_peak_bytes"}


def test_no_python_file_of_the_project_is_over_500_lines():
    files = [p for top in ("ata", "tests", "benchmarks", "tools", "experiments")
             for p in (ROOT / top).rglob("*.py")]
    assert len(files) > 50
    long = {str(p.relative_to(ROOT)): n for p in files
            if (n := len(p.read_text(encoding="utf-8").splitlines())) > 500}
    assert long == {}
