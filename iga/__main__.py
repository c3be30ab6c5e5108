"""``python -m iga`` is the same as the ``iga`` console script."""

import sys

from iga.app.cli import main

sys.exit(main())
