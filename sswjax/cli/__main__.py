"""``python -m sswjax.cli``: the console script ``sswjax``."""

import sys

from sswjax.cli.app import console

sys.exit(console())
