"""``python -m orient``: see :mod:`orient.cli`."""

import sys

from orient.cli import main

sys.exit(main())
