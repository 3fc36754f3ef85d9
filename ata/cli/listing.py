"""`ata plugins`: every component by name."""

from __future__ import annotations

from typing import List, Optional

import typer
from rich.padding import Padding
from rich.table import Table
from rich.text import Text

from ata.cli.common import PluginsOption, _split, app, user_errors
import ata.cli.terminal as terminal
from ata.cli.terminal import console


@app.command()
@user_errors
def plugins(verbose: bool = typer.Option(False, "--verbose", "-v",
                                         help="Also list each component's hooks and settings "
                                              "(type, default, allowed values)."),
            optional: Optional[str] = PluginsOption) -> None:
    """List every component by name, the plugin it comes from and its version. Optional
    plugins (the learned methods) are listed too, marked with the --plugins name that loads
    them."""
    from rich import box   # on use: start-up time

    from ata.core.registry import (OPTIONAL_PLUGINS, collect_components,  # start-up time
                                   get_plugin_manager)
    from ata.core.settings import describe   # on use: start-up time

    pm = get_plugin_manager(optional=_split(optional))
    loaded = {pm.get_name(p) for p in pm.get_plugins()}
    # every optional plugin, loaded or not, so that a user can discover them here
    everything = get_plugin_manager(optional=list(OPTIONAL_PLUGINS))
    registry = collect_components(everything, declared=True)
    optional_of = {module: name for name, module in OPTIONAL_PLUGINS.items()}
    table = Table(title="ata plugins", box=box.SIMPLE_HEAD, title_justify="left")
    table.add_column("component", no_wrap=True)
    table.add_column("kind", no_wrap=True)
    table.add_column("plugin (in ata.plugins)", overflow="fold")
    table.add_column("version", no_wrap=True)
    for info in sorted(registry.components.values(), key=lambda c: (c.kind, c.name)):
        plugin = info.plugin.removeprefix("ata.plugins.")
        if info.plugin in optional_of:
            plugin = f"{plugin} (--plugins {optional_of[info.plugin]})"
        table.add_row(info.name, info.kind, plugin, info.dist)
    console.print(terminal.add_broken_plugins(table, registry.broken))
    missing = [n for n, mod in OPTIONAL_PLUGINS.items() if mod not in loaded]
    if missing:
        console.print(f"Optional plugins (the learned methods) load when a mission names one "
                      f"of their components, or with --plugins NAME; not loaded now: "
                      f"{', '.join(missing)}.",
                      highlight=False, markup=False)
    if verbose:
        # one block per component, a key per line: readable at any terminal width
        for info in sorted(registry.components.values(), key=lambda c: (c.kind, c.name)):
            cls = getattr(info.factory, "Settings", None)
            hooks = ", ".join(h for h in sorted(dir(info.factory))
                              if h.startswith("ata_") and h != "ata_register_components")
            console.print()
            console.print(Text(f"[{info.name}]", style="bold") + Text(
                f" {info.kind}, from {info.plugin}; hooks: {hooks or 'none'}"))
            rows = describe(cls) if cls else []
            if not rows:
                console.print("  no settings", highlight=False)
            for key, tp, default, allowed, text in rows:
                kind = f"{tp}, {allowed}" if allowed else tp
                console.print(Text(f"  {key}", style="cyan") + Text(f" = {default!r}  ({kind})"))
                console.print(Padding(Text(text), (0, 0, 0, 6)))
