"""``python -m iga`` is the same as the ``iga`` console script."""

import sys

from .cli import main

sys.exit(main())
