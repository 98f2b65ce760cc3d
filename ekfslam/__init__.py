"""ekfslam: landmark EKF SLAM for teaching, after the UCSD CSE276A HW3 report (the "seed")."""

__version__ = "0.1.0"
