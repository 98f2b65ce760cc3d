"""The loop `EKFSLAM.feed` stands for, step by step: the tests' oracle for a run fed in one call."""

from __future__ import annotations

from ekfslam.core.filter.ekf import EKFSLAM, Detections, Pieces


def one_by_one(
    ekf: EKFSLAM, pieces: Pieces, detections: Detections, *, validate: bool = False
) -> None:
    """`predict_many` through the pieces that end by each detection, `update` with it, and
    `predict_many` through the pieces after the last (each call checking its arguments when
    `validate`)."""
    u, dt, t, M, R = pieces
    done = 0
    for i, p in enumerate([*detections.upto.tolist(), len(u)]):
        if p > done:
            ekf.predict_many(u[done:p], dt[done:p], t[done:p], M, R, validate=validate)
            done = p
        if i < len(detections.upto):
            z, Q, when = detections.z[i], detections.Q[i], float(detections.t[i])
            ekf.update(int(detections.landmark_id[i]), z, Q, when, validate=validate)
