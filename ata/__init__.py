"""ata: a benchmark and reference implementation for adaptive task allocation in MH-MR teams."""

import pluggy

__version__ = "0.2.0"

hookimpl = pluggy.HookimplMarker("ata")
"""Marker for hook implementations: ``from ata import hookimpl``."""

__all__ = ["hookimpl", "__version__"]
