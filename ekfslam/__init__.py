"""ekfslam: landmark EKF SLAM for teaching, after the UCSD CSE276A HW3 report (the "seed").

The concepts, one module each:

- `ekfslam.kinematics`   mecanum wheels <-> body twist (eq. 4)
- `ekfslam.models`       motion (eqs. 5-7), observation (eqs. 13-14), inverse observation (eq. 12)
- `ekfslam.derivations`  the same models derived with sympy, the lifts F_x (eq. 8) and F_x,j
- `ekfslam.filter`       the EKF-SLAM filter with block updates (eqs. 1-16)
- `ekfslam.reference`    the seed's equations written literally with F_x: the test oracle
- `ekfslam.alignment`    eq. (17): aligning the estimated map to the true tags
- `ekfslam.arena`, `ekfslam.simulation`  the seed's arena and a simulator of its robot
- `ekfslam.runlog`, `ekfslam.mrclam`, `ekfslam.fetch`  logs: our format, UTIAS MRCLAM
- `ekfslam.replay`, `ekfslam.evaluation`, `ekfslam.plotting`  replay, scores, figures

The names below are the public API the notebooks use.
"""

import os

# OpenCV, its FFmpeg and its codecs print their own warnings on stderr (a damaged mp4 printed
# 5,174 FFmpeg lines before our one-line error). They read these variables once, when cv2 is
# first imported, and every cv2 import in ekfslam comes after this package's __init__.
os.environ.setdefault("OPENCV_LOG_LEVEL", "OFF")
os.environ.setdefault("OPENCV_FFMPEG_LOGLEVEL", "-8")  # AV_LOG_QUIET

from ekfslam.alignment import Alignment, align, align_least_squares, align_mean_distance
from ekfslam.arena import SEED_ARENA, Arena, Tag
from ekfslam.errors import AlignmentError, EkfSlamError, InputError
from ekfslam.evaluation import RunSummary, ate_rmse, summarize
from ekfslam.filter import EKFSLAM, FilterConfig, FilterCounts
from ekfslam.history import History
from ekfslam.kinematics import MecanumGeometry, twist_to_wheels, wheels_to_twist
from ekfslam.replay import NoiseConfig, ReplayResult, default_noise, replay
from ekfslam.runlog import RunLog, read_run, write_run
from ekfslam.simulation import SimulationConfig, simulate

__version__ = "0.1.0"

__all__ = [
    "EKFSLAM",
    "SEED_ARENA",
    "Alignment",
    "AlignmentError",
    "Arena",
    "EkfSlamError",
    "FilterConfig",
    "FilterCounts",
    "History",
    "InputError",
    "MecanumGeometry",
    "NoiseConfig",
    "ReplayResult",
    "RunLog",
    "RunSummary",
    "SimulationConfig",
    "Tag",
    "align",
    "align_least_squares",
    "align_mean_distance",
    "ate_rmse",
    "default_noise",
    "read_run",
    "replay",
    "simulate",
    "summarize",
    "twist_to_wheels",
    "wheels_to_twist",
    "write_run",
]
