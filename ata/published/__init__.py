"""Published rows: an evaluation's per-scenario rows shipped with what made them (`sets`: the
format, `publish`, reading, and the checks before a pairing), and a suite's method read from
them instead of run (`backend.PublishedRows`). The shipped sets are the folders beside this
package's modules (``paper``)."""

from ata.published.backend import PublishedRows, check_models, published_method
from ata.published.sets import (DEFAULT, PREFIX, PUBLISHED, check_pairing, is_published, locate,
                                publish, read_published)

__all__ = ["DEFAULT", "PREFIX", "PUBLISHED", "PublishedRows", "check_models", "check_pairing",
           "is_published", "locate", "publish", "published_method", "read_published"]
