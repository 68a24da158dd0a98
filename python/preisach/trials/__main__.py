"""``python -m preisach.trials run|check ...`` (the same as ``preisach trial``)."""

import sys

from .cli import _main

sys.exit(_main())
