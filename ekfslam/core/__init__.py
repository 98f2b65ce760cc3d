"""The core floor: the robot, sensor and world models and the EKF-SLAM filter.

Imports only the leaves (`ekfslam.errors`, `ekfslam.geometry`). Outside `core.filter` nothing
here imports the filter, so the models stay importable without numba."""
