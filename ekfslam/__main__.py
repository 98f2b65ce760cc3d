"""``python -m ekfslam``: see `ekfslam.cli`."""

import sys

from ekfslam.cli import main

sys.exit(main())
