"""Meta-tests, after datasette's: every hook is documented with its exact signature in
docs/plugins.md, and every hook is exercised by a test."""

from __future__ import annotations

import inspect
import re
from pathlib import Path

import pytest

from ata import hookspecs
from ata.core.registry import KINDS

ROOT = Path(__file__).resolve().parent.parent
DOC = ROOT / "docs" / "plugins.md"
TESTS = Path(__file__).resolve().parent

HOOKS = sorted(name for name, obj in inspect.getmembers(hookspecs, inspect.isfunction)
               if hasattr(obj, "ata_spec"))


def normalise(text: str) -> str:
    """Quotes around annotations dropped, whitespace collapsed, no space inside brackets."""
    text = " ".join(text.replace('"', "").replace("'", "").split())
    return text.replace("( ", "(").replace(" )", ")")


def signature_text(name: str) -> str:
    return normalise(f"def {name}{inspect.signature(getattr(hookspecs, name))}:")


def test_there_are_hooks():
    assert len(HOOKS) >= 14
    assert {"ata_register_components", "ata_setup", "ata_inject", "ata_reallocate",
            "ata_episode_end"} <= set(HOOKS)
    assert all(name.startswith("ata_") for name in HOOKS)


@pytest.mark.parametrize("name", HOOKS)
def test_hook_is_documented_with_its_exact_signature(name):
    doc = normalise(DOC.read_text(encoding="utf-8"))
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
    documented = set(re.findall(r"^def (ata_\w+)\(", DOC.read_text(encoding="utf-8"), re.M))
    assert documented == set(HOOKS)


def test_doc_covers_kinds_settings_start_up_and_tracing():
    doc = DOC.read_text(encoding="utf-8")
    for kind in KINDS:
        assert f"`{kind}`" in doc
    for topic in ("register(kind, name, factory)", "class Settings:", "param(",
                  "ATA_TRACE_HOOKS", "check_pending()", "[project.entry-points.ata]",
                  "HUMAN_STATE", "ROBOT_STATE", "TASK_STATE", "HUMAN_INHERENT",
                  "ROBOT_INHERENT", "TASK_INHERENT"):
        assert topic in doc, topic


def test_doc_lists_the_shared_columns_of_the_built_in_models():
    from ata.plugins import humans, robots, tasks

    doc = DOC.read_text(encoding="utf-8")
    for columns in (humans.HUMAN_INHERENT, humans.HUMAN_STATE, robots.ROBOT_INHERENT,
                    robots.ROBOT_STATE, tasks.TASK_INHERENT, tasks.TASK_STATE):
        assert ", ".join(f"`{c}`" for c in columns) in doc, columns


@pytest.mark.parametrize("name", HOOKS)
def test_hook_has_a_test(name):
    files = [p for p in TESTS.rglob("*.py") if p.name != Path(__file__).name]
    using = [p.name for p in files if re.search(rf"\b{name}\b", p.read_text(encoding="utf-8"))]
    assert using, f"no test under tests/ mentions {name}"
