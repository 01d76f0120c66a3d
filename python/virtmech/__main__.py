"""``python -m virtmech``: the virtmech command."""

import sys

from .cli import main

sys.exit(main())
