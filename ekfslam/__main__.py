"""``python -m ekfslam``: see `ekfslam.cli.main`."""

import sys

from ekfslam.cli.main import main

sys.exit(main())
