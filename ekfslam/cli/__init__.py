"""The command line (`python -m ekfslam`). Only `ekfslam.__main__` imports it."""
