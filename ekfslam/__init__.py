"""ekfslam: landmark EKF SLAM for teaching, after the UCSD CSE276A HW3 report (the "seed").

The package is a house with floors (ARCHITECTURE.md); each subpackage is one:

- `ekfslam.errors`, `ekfslam.geometry`  the leaves everything may use
- `ekfslam.core`       robot, camera and arena models; `ekfslam.core.filter`, the EKF (eqs. 1-16)
- `ekfslam.teaching`   sympy derivations, the literal F_x reference, the notebooks' helpers
- `ekfslam.logs`, `ekfslam.sim`, `ekfslam.vision`  data sources: logs, the simulator, cameras
- `ekfslam.pipeline`   a log source joined to the filter (`replay`)
- `ekfslam.team`       a team of robots' logs joined to one filter (`replay_team`)
- `ekfslam.analysis`   alignment (eq. 17), scores, consistency: what the notebooks compute
- `ekfslam.viz`, `ekfslam.ui`, `ekfslam.cli`  figures, the live tuner, the command line

The names below are the public API the notebooks use. They are loaded on first use (PEP 562), so
``import ekfslam`` alone imports neither the filter nor numba.
"""

from __future__ import annotations

import importlib
import os
from typing import TYPE_CHECKING, Any

# OpenCV, its FFmpeg and its codecs print their own warnings on stderr (a damaged mp4 printed
# 5,174 FFmpeg lines before our one-line error). They read these variables once, when cv2 is
# first imported, and every cv2 import in ekfslam comes after this package's __init__.
os.environ.setdefault("OPENCV_LOG_LEVEL", "OFF")
os.environ.setdefault("OPENCV_FFMPEG_LOGLEVEL", "-8")  # AV_LOG_QUIET

if TYPE_CHECKING:
    from ekfslam.analysis.alignment import (
        Alignment,
        align,
        align_least_squares,
        align_mean_distance,
    )
    from ekfslam.analysis.evaluation import RunSummary, ate_rmse, summarize
    from ekfslam.core.arena import SEED_ARENA, Arena, Tag
    from ekfslam.core.filter.config import FilterConfig, FilterCounts
    from ekfslam.core.filter.ekf import EKFSLAM
    from ekfslam.core.filter.history import History
    from ekfslam.core.kinematics import MecanumGeometry, twist_to_wheels, wheels_to_twist
    from ekfslam.core.noise import NoiseConfig, default_noise
    from ekfslam.errors import AlignmentError, EkfSlamError, InputError
    from ekfslam.logs.arrays import run_from_arrays
    from ekfslam.logs.runlog import RunLog, read_run, write_run
    from ekfslam.pipeline import ReplayResult, replay
    from ekfslam.sim.simulation import SimulationConfig, simulate
    from ekfslam.strategies import HiddenIds, KnownIds, Start
    from ekfslam.team import TeamResult, replay_team

__version__ = "0.1.0"

# each public name -> the module that defines it
_EXPORTS: dict[str, str] = {
    "Alignment": "ekfslam.analysis.alignment",
    "AlignmentError": "ekfslam.errors",
    "Arena": "ekfslam.core.arena",
    "EKFSLAM": "ekfslam.core.filter.ekf",
    "EkfSlamError": "ekfslam.errors",
    "FilterConfig": "ekfslam.core.filter.config",
    "FilterCounts": "ekfslam.core.filter.config",
    "HiddenIds": "ekfslam.strategies",
    "History": "ekfslam.core.filter.history",
    "InputError": "ekfslam.errors",
    "KnownIds": "ekfslam.strategies",
    "MecanumGeometry": "ekfslam.core.kinematics",
    "NoiseConfig": "ekfslam.core.noise",
    "ReplayResult": "ekfslam.pipeline",
    "RunLog": "ekfslam.logs.runlog",
    "RunSummary": "ekfslam.analysis.evaluation",
    "SEED_ARENA": "ekfslam.core.arena",
    "SimulationConfig": "ekfslam.sim.simulation",
    "Start": "ekfslam.strategies",
    "Tag": "ekfslam.core.arena",
    "TeamResult": "ekfslam.team",
    "align": "ekfslam.analysis.alignment",
    "align_least_squares": "ekfslam.analysis.alignment",
    "align_mean_distance": "ekfslam.analysis.alignment",
    "ate_rmse": "ekfslam.analysis.evaluation",
    "default_noise": "ekfslam.core.noise",
    "read_run": "ekfslam.logs.runlog",
    "replay": "ekfslam.pipeline",
    "replay_team": "ekfslam.team",
    "run_from_arrays": "ekfslam.logs.arrays",
    "simulate": "ekfslam.sim.simulation",
    "summarize": "ekfslam.analysis.evaluation",
    "twist_to_wheels": "ekfslam.core.kinematics",
    "wheels_to_twist": "ekfslam.core.kinematics",
    "write_run": "ekfslam.logs.runlog",
}
_SUBMODULES = frozenset(
    {
        "analysis",
        "cli",
        "core",
        "errors",
        "geometry",
        "logs",
        "pipeline",
        "schedule",
        "sim",
        "strategies",
        "team",
        "teaching",
        "ui",
        "viz",
        "vision",
    }
)

__all__ = [
    "EKFSLAM",
    "SEED_ARENA",
    "Alignment",
    "AlignmentError",
    "Arena",
    "EkfSlamError",
    "FilterConfig",
    "FilterCounts",
    "HiddenIds",
    "History",
    "InputError",
    "KnownIds",
    "MecanumGeometry",
    "NoiseConfig",
    "ReplayResult",
    "RunLog",
    "RunSummary",
    "SimulationConfig",
    "Start",
    "Tag",
    "TeamResult",
    "align",
    "align_least_squares",
    "align_mean_distance",
    "ate_rmse",
    "default_noise",
    "read_run",
    "replay",
    "replay_team",
    "run_from_arrays",
    "simulate",
    "summarize",
    "twist_to_wheels",
    "wheels_to_twist",
    "write_run",
]


def __getattr__(name: str) -> Any:
    module = _EXPORTS.get(name)
    if module is not None:
        value = getattr(importlib.import_module(module), name)
        globals()[name] = value  # later look-ups skip this function
        return value
    if name in _SUBMODULES:
        return importlib.import_module(f"{__name__}.{name}")
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted({*globals(), *_EXPORTS, *_SUBMODULES})
