"""MRCLAM's logged commands against what the robots did: an optional, documented correction.

The robots of MRCLAM move after their logged odometry commands, and less far than they say (the
motion Vicon saw lags the commands and falls short of them). `fit_command_calibration` measures
one lag and two scales against the ground truth; `calibrate_commands` applies them to a run
(``python -m ekfslam convert mrclam --calibrate``); `MRCLAM_CALIBRATION` is the fit on Dataset 7.
Off by default: the filter replays the commands as logged.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ekfslam.logs.runlog import Controls, RunLog

Array = NDArray[np.float64]


@dataclass(frozen=True)
class CommandCalibration:
    """How the logged commands relate to the motion the robot made (fitted against Vicon).

    The motion over [t, t + W] is taken to be the commands over [t - lag_s, t + W - lag_s],
    scaled: forward distance by `v_scale`, turned angle by `w_scale`.
    """

    lag_s: float = 0.0
    v_scale: float = 1.0
    w_scale: float = 1.0


_LAGS = tuple(0.05 * k for k in range(9))  # 0 to 0.4 s

#: Fitted by `fit_command_calibration` on Dataset 7, pooled over robots 1-5 (1 s windows).
MRCLAM_CALIBRATION = CommandCalibration(lag_s=0.25, v_scale=0.90, w_scale=0.935)


def calibrate_commands(run: RunLog, calibration: CommandCalibration) -> RunLog:
    """The run with its controls shifted later by ``lag_s`` and (v, ω) scaled.

    Data handling, not filtering: the filter still integrates whatever twist it is given. The
    start pose stays where it was (before the shifted first command the robot stands still).
    """
    c = run.controls
    values = np.array(c.values, dtype=np.float64) * [calibration.v_scale, 1.0, calibration.w_scale]
    controls = Controls(t=c.t + calibration.lag_s, kind=c.kind, values=values)
    return dataclasses.replace(run, controls=controls)


def fit_command_calibration(
    runs: list[RunLog], lags: ArrayLike = _LAGS, window_s: float = 1.0
) -> CommandCalibration:
    """Fit one lag and two scales to several runs' commands against their ground truth.

    For every lag, the commanded forward distance and turned angle over consecutive windows of
    `window_s` are regressed (least squares through the origin, pooled over all runs) on the
    distance and the heading change that Vicon saw; the lag with the smallest residual in the
    heading wins (the heading is what the filter cannot recover afterwards).
    """
    best = None
    for lag in np.asarray(lags, dtype=float).tolist():
        pairs = [_window_motion(run, lag, window_s) for run in runs]
        cmd = np.concatenate([p[0] for p in pairs])
        true = np.concatenate([p[1] for p in pairs])
        scales = np.sum(cmd * true, axis=0) / np.sum(cmd * cmd, axis=0)
        residual = float(np.sqrt(np.mean((cmd[:, 1] * scales[1] - true[:, 1]) ** 2)))
        if best is None or residual < best[0]:
            best = (residual, CommandCalibration(lag, float(scales[0]), float(scales[1])))
    return best[1]


def _window_motion(run: RunLog, lag: float, window_s: float) -> tuple[Array, Array]:
    """(commanded, true) (|distance|, heading change) per window, each (K, 2)."""
    t, v, w = run.controls.t, run.controls.values[:, 0], run.controls.values[:, 2]
    gt = run.groundtruth
    start = max(t[0], gt.t[0]) + 1.0
    a = np.arange(start, min(t[-1], gt.t[-1]) - window_s - 1.0, window_s)
    b = a + window_s
    cum_v = np.concatenate([[0.0], np.cumsum(v[:-1] * np.diff(t))])
    cum_w = np.concatenate([[0.0], np.cumsum(w[:-1] * np.diff(t))])

    def integral(cum: Array, rate: Array, at: Array) -> Array:
        i = np.clip(np.searchsorted(t, at, side="right") - 1, 0, len(t) - 1)
        return cum[i] + rate[i] * (at - t[i])

    cmd = np.column_stack(
        [
            np.abs(integral(cum_v, v, b - lag) - integral(cum_v, v, a - lag)),
            integral(cum_w, w, b - lag) - integral(cum_w, w, a - lag),
        ]
    )
    heading = np.unwrap(gt.pose[:, 2])
    dist = np.hypot(
        np.interp(b, gt.t, gt.pose[:, 0]) - np.interp(a, gt.t, gt.pose[:, 0]),
        np.interp(b, gt.t, gt.pose[:, 1]) - np.interp(a, gt.t, gt.pose[:, 1]),
    )
    turn = np.interp(b, gt.t, heading) - np.interp(a, gt.t, heading)
    return cmd, np.column_stack([dist, turn])
