"""The results page (`ata site`): a static folder of leaderboards, figures and a page per method
with its provenance, built from published sets and result folders (`build`), with each set's
trust tier (`verify`: reproduced by a rerun of a sample of its rows, or reported)."""

from ata.site.build import Site, build_site
from ata.site.verify import REPORTED, REPRODUCED, tier, verify

__all__ = ["REPORTED", "REPRODUCED", "Site", "build_site", "tier", "verify"]
