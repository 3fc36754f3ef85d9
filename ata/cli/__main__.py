"""`python -m ata.cli`."""

import sys

from ata.cli import app

sys.exit(app())
