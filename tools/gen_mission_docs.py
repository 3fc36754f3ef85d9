"""Regenerate the key tables of docs/missions.md from the code (the prose above them stays).

Usage: python tools/gen_mission_docs.py   (tests/test_docs.py checks the result)
"""

from pathlib import Path

from ata.core.mission import ComponentSlots, MissionSettings
from ata.core.registry import OPTIONAL_PLUGINS, collect_components, get_plugin_manager
from ata.core.settings import describe

DOC = Path(__file__).resolve().parent.parent / "docs" / "missions.md"
MARK = "## `[mission]`"


def table(cls) -> list[str]:
    rows = ["| key | type | default | allowed | meaning |", "|---|---|---|---|---|"]
    for key, tp, default, allowed, text in describe(cls):
        shown = "(from the level)" if default is None and key in ("variance", "probability") \
            else repr(default)
        rows.append(f"| `{key}` | {tp} | `{shown}` | {allowed} | {text} |")
    return rows


def main() -> None:
    registry = collect_components(get_plugin_manager(optional=OPTIONAL_PLUGINS,
                                                    entry_points=False), declared=True)
    lines = [MARK, "", *table(MissionSettings), "", "## `[components]`", "",
             *table(ComponentSlots), ""]
    kinds: dict[str, list[str]] = {}
    for info in registry.components.values():
        kinds.setdefault(info.name, []).append(info.kind)
    done = set()
    for info in sorted(registry.components.values(), key=lambda c: (c.kind, c.name)):
        if info.name in done:
            continue
        done.add(info.name)
        cls = getattr(info.factory, "Settings", None)
        lines += [f"### `[{info.name}]` ({', '.join(sorted(kinds[info.name]))})", ""]
        lines += (table(cls) if cls is not None else ["No settings."]) + [""]
    head = DOC.read_text().split(MARK, 1)[0]
    DOC.write_text(head + "\n".join(lines))


if __name__ == "__main__":
    main()
