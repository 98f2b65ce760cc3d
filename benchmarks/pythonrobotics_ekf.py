"""PythonRobotics' EKF SLAM on its own world, reimplemented for the loop benchmark
(`benchmarks.loop`) so that the comparison runs without a checkout of it.

The source is AtsushiSakai/PythonRobotics (MIT), ``SLAM/EKFSLAM/ekf_slam.py``: `simulate` is its
``main`` loop's ``observation`` (four RFID tags, v = 1 m/s, ω = 0.1 rad/s, DT = 0.1 s, 50 s,
range-bearing sightings within 20 m, noisy inputs), and `run_pythonrobotics` its ``ekf_slam``
step with ``jacob_motion``, ``search_correspond_landmark_id`` (its association by Mahalanobis
distance: it is given no ids), ``calc_innovation``, ``jacob_h`` (the lift matrices built in full)
and the landmark appended without cross-covariance, each with its numpy calls; as written there,
``Cx`` is both the motion and the observation noise. Only the random numbers differ: a seeded
``numpy.random.Generator`` instead of the global ``np.random.randn``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

Array = NDArray[np.float64]

Cx = np.diag([0.5, 0.5, np.deg2rad(30.0)]) ** 2
Q_sim = np.diag([0.2, np.deg2rad(1.0)]) ** 2
R_sim = np.diag([1.0, np.deg2rad(10.0)]) ** 2
DT = 0.1
SIM_TIME = 50.0
MAX_RANGE = 20.0
M_DIST_TH = 2.0
STATE_SIZE = 3
LM_SIZE = 2
RFID = np.array([[10.0, -2.0], [15.0, 10.0], [3.0, 15.0], [-5.0, 20.0]])


@dataclass(frozen=True)
class World:
    """One run of PythonRobotics' example: the true poses (N, 3), the noisy inputs (N, 2) as
    (v, ω), and each step's sightings, (k, 3) rows of (range, bearing, id)."""

    poses: Array
    inputs: Array
    sightings: list[Array]


def pi_2_pi(angle: float) -> float:
    return (angle + math.pi) % (2 * math.pi) - math.pi


def motion_model(x: Array, u: Array) -> Array:
    F = np.array([[1.0, 0, 0], [0, 1.0, 0], [0, 0, 1.0]])
    B = np.array([[DT * math.cos(x[2, 0]), 0], [DT * math.sin(x[2, 0]), 0], [0.0, DT]])
    return (F @ x) + (B @ u)


def simulate(seed: int) -> World:
    """PythonRobotics' ``main`` loop without the filter: truth, noisy inputs, sightings."""
    rng = np.random.default_rng(seed)
    xTrue = np.zeros((STATE_SIZE, 1))
    u = np.array([[1.0, 0.1]]).T
    poses, inputs, sightings = [xTrue.ravel().copy()], [], []
    time = 0.0
    while SIM_TIME >= time:
        time += DT
        xTrue = motion_model(xTrue, u)
        z = np.zeros((0, 3))
        for i in range(len(RFID[:, 0])):
            dx, dy = RFID[i, 0] - xTrue[0, 0], RFID[i, 1] - xTrue[1, 0]
            d = math.hypot(dx, dy)
            angle = pi_2_pi(math.atan2(dy, dx) - xTrue[2, 0])
            if d <= MAX_RANGE:
                dn = d + rng.standard_normal() * Q_sim[0, 0] ** 0.5
                angle_n = angle + rng.standard_normal() * Q_sim[1, 1] ** 0.5
                z = np.vstack((z, np.array([dn, angle_n, i])))
        ud = (
            u[0, 0] + rng.standard_normal() * R_sim[0, 0] ** 0.5,
            u[1, 0] + rng.standard_normal() * R_sim[1, 1] ** 0.5,
        )
        poses.append(xTrue.ravel().copy())
        inputs.append(ud)
        sightings.append(z)
    return World(np.array(poses), np.array(inputs), sightings)


def calc_n_lm(x: Array) -> int:
    return int((len(x) - STATE_SIZE) / LM_SIZE)


def jacob_motion(x: Array, u: Array) -> tuple[Array, Array]:
    Fx = np.hstack((np.eye(STATE_SIZE), np.zeros((STATE_SIZE, LM_SIZE * calc_n_lm(x)))))
    jF = np.array(
        [
            [0.0, 0.0, -DT * u[0, 0] * math.sin(x[2, 0])],
            [0.0, 0.0, DT * u[0, 0] * math.cos(x[2, 0])],
            [0.0, 0.0, 0.0],
        ],
        dtype=np.float64,
    )
    G = np.eye(STATE_SIZE) + Fx.T @ jF @ Fx
    return G, Fx


def calc_landmark_position(x: Array, z: Array) -> Array:
    zp = np.zeros((2, 1))
    zp[0, 0] = x[0, 0] + z[0] * math.cos(x[2, 0] + z[1])
    zp[1, 0] = x[1, 0] + z[0] * math.sin(x[2, 0] + z[1])
    return zp


def get_landmark_position_from_state(x: Array, ind: int) -> Array:
    return x[STATE_SIZE + LM_SIZE * ind : STATE_SIZE + LM_SIZE * (ind + 1), :]


def search_correspond_landmark_id(xAug: Array, PAug: Array, zi: Array) -> int:
    nLM = calc_n_lm(xAug)
    min_dist = []
    for i in range(nLM):
        lm = get_landmark_position_from_state(xAug, i)
        y, S, _ = calc_innovation(lm, xAug, PAug, zi, i)
        min_dist.append((y.T @ np.linalg.inv(S) @ y)[0, 0])
    min_dist.append(M_DIST_TH)
    return min_dist.index(min(min_dist))


def calc_innovation(lm: Array, xEst: Array, PEst: Array, z: Array, LMid: int):
    delta = lm - xEst[0:2]
    q = (delta.T @ delta)[0, 0]
    z_angle = math.atan2(delta[1, 0], delta[0, 0]) - xEst[2, 0]
    zp = np.array([[math.sqrt(q), pi_2_pi(z_angle)]])
    y = (z - zp).T
    y[1] = pi_2_pi(y[1, 0])
    H = jacob_h(q, delta, xEst, LMid + 1)
    S = H @ PEst @ H.T + Cx[0:2, 0:2]
    return y, S, H


def jacob_h(q: float, delta: Array, x: Array, i: int) -> Array:
    sq = math.sqrt(q)
    G = np.array(
        [
            [-sq * delta[0, 0], -sq * delta[1, 0], 0, sq * delta[0, 0], sq * delta[1, 0]],
            [delta[1, 0], -delta[0, 0], -q, -delta[1, 0], delta[0, 0]],
        ]
    )
    G = G / q
    nLM = calc_n_lm(x)
    F1 = np.hstack((np.eye(3), np.zeros((3, 2 * nLM))))
    F2 = np.hstack(
        (np.zeros((2, 3)), np.zeros((2, 2 * (i - 1))), np.eye(2), np.zeros((2, 2 * nLM - 2 * i)))
    )
    F = np.vstack((F1, F2))
    return G @ F


def ekf_slam(xEst: Array, PEst: Array, u: Array, z: Array) -> tuple[Array, Array]:
    """PythonRobotics' ``ekf_slam`` (its ``print("New LM")`` left out)."""
    S = STATE_SIZE
    G, Fx = jacob_motion(xEst[0:S], u)
    xEst[0:S] = motion_model(xEst[0:S], u)
    PEst[0:S, 0:S] = G.T @ PEst[0:S, 0:S] @ G + Fx.T @ Cx @ Fx
    initP = np.eye(2)
    for iz in range(len(z[:, 0])):
        min_id = search_correspond_landmark_id(xEst, PEst, z[iz, 0:2])
        nLM = calc_n_lm(xEst)
        if min_id == nLM:
            xAug = np.vstack((xEst, calc_landmark_position(xEst, z[iz, :])))
            PAug = np.vstack(
                (
                    np.hstack((PEst, np.zeros((len(xEst), LM_SIZE)))),
                    np.hstack((np.zeros((LM_SIZE, len(xEst))), initP)),
                )
            )
            xEst, PEst = xAug, PAug
        lm = get_landmark_position_from_state(xEst, min_id)
        y, S_, H = calc_innovation(lm, xEst, PEst, z[iz, 0:2], min_id)
        K = (PEst @ H.T) @ np.linalg.inv(S_)
        xEst = xEst + (K @ y)
        PEst = (np.eye(len(xEst)) - (K @ H)) @ PEst
    xEst[2] = pi_2_pi(xEst[2, 0])
    return xEst, PEst


def run_pythonrobotics(world: World) -> Array:
    """PythonRobotics' loop on one world (as its ``main``, PEst starting at I); poses (N, 3)."""
    xEst, PEst = np.zeros((STATE_SIZE, 1)), np.eye(STATE_SIZE)
    out = np.zeros((len(world.poses), 3))
    for n, (ud, z) in enumerate(zip(world.inputs, world.sightings, strict=True)):
        xEst, PEst = ekf_slam(xEst, PEst, np.array([ud]).T, z)
        out[n + 1] = xEst[0:STATE_SIZE, 0]
    return out
