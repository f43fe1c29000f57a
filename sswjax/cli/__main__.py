"""``python -m sswjax.cli``: the console script ``sswjax``."""

import sys

from sswjax.cli.app import main

sys.exit(main())
