"""``python -m pose_uncertainty.cli``: the same as the ``pose-uncertainty`` command."""

import sys

from . import main

sys.exit(main())
