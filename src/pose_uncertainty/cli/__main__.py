"""``python -m pose_uncertainty.cli``: the same as the ``pose-uncertainty`` command."""

import sys

from . import main

if __name__ == "__main__":  # importing this module (as the docs build's reference resolver may) runs nothing
    sys.exit(main())
