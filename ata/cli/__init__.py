"""The command line: `ata run`, `eval`, `report`, `compare`, `site`, `train`, `check`, `plugins`,
`show`. Thin: each command parses, calls the library (`ata.experiment`, `ata.site`, ...),
renders. The modules register their commands on import, in the order `ata --help` lists them."""

from ata.cli import running, results, site, training, listing  # noqa: F401,I001  (order: --help's)
from ata.cli.common import app

__all__ = ["app"]
