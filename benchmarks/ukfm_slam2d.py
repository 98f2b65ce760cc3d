"""ukfm's 2D SLAM benchmark world and its EKF, reimplemented here because ukfm is not on PyPI.

The source is CAOR-MINES-ParisTech/ukfm (BSD-3): ``python/ukfm/model/slam2d.py`` (the model
``SLAM2D``: `simulate` is its ``simu_f`` and ``simu_h``; `UkfmEKF` its ``EKF`` class with
``ekf_FG_ana``, ``ekf_jacobian_update``, ``ekf_augment`` and the retraction ``phi``) and
``python/benchmarks/slam2d.py`` (the loop, `run_ukfm_ekf`). The state, the Jacobians and the
numpy calls of every step are ukfm's, in its order: the covariance propagated as a full
``F P Fᵀ + G Q Gᵀ``, every sighting of a step stacked into one ``H`` (``np.vstack``,
``block_diag``) and one ``solve``, a new landmark appended by building a larger ``P``. Two
things differ and neither changes the per-step work: the random numbers come from a seeded
``numpy.random.Generator`` (ukfm calls the global ``np.random.randn``), and the noisy inputs
are floats (ukfm's are 1-element arrays, which numpy 2 refuses to write into a scalar slot).

The world: a robot turning at v = 0.25 m/s, ω = 1.5°/s for `STEPS` seconds of 1 Hz odometry,
20 landmarks on a circle 3 m outside its path, seen between 1 and 5 m (2 to 3 a step) as
their position in the robot's frame with 0.1 m noise.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.linalg import block_diag

Array = NDArray[np.float64]

STEPS = 2500  # ukfm's T = 2500 s at odo_freq = 1 Hz
N_LANDMARKS = 20
MAX_RANGE, MIN_RANGE = 5.0, 1.0
V, GYRO = 0.25, 1.5 / 180 * np.pi
ODO_STD = np.array([0.05 * V / np.sqrt(2), 0.05 * V * np.sqrt(2) * 2])  # speed, angular speed
OBS_STD = 0.1
DT = 1.0
J = np.array([[0, -1], [1, 0]])


@dataclass(frozen=True)
class World:
    """One run of ukfm's benchmark: the true poses (N, 3) as (x, y, θ), the noisy inputs (N-1,
    2) as (v, ω), the landmarks (L, 2), and the sightings ys (N, L, 3): (y_x, y_y, id) with id
    -1 where landmark i is not seen at step n."""

    poses: Array
    omegas: Array
    landmarks: Array
    ys: Array


def so2_exp(phi: float) -> Array:
    """ukfm's ``SO2.exp``."""
    Rot = np.empty((2, 2))
    Rot[0, 0] = np.cos(phi)
    Rot[1, 1] = np.cos(phi)
    Rot[0, 1] = -np.sin(phi)
    Rot[1, 0] = np.sin(phi)
    return Rot


def simulate(seed: int, steps: int = STEPS) -> World:
    """ukfm's ``simu_f`` then ``simu_h``: the trajectory, the noisy odometry, the sightings."""
    rng = np.random.default_rng(seed)
    r = V / GYRO
    ldks = np.zeros((N_LANDMARKS, 2))
    for i in range(N_LANDMARKS):
        rho, th = r + MIN_RANGE + 2, 2 * np.pi * i / N_LANDMARKS
        ldks[i] = np.array([rho * np.cos(th), rho * np.sin(th) + r])
    Rots, ps = [np.eye(2)], [np.zeros(2)]
    omegas = np.zeros((steps - 1, 2))
    for n in range(1, steps):
        Rot, p = Rots[-1], ps[-1]
        Rots.append(Rot.dot(so2_exp(GYRO * DT)))
        ps.append(p + Rot.dot(np.hstack([V, 0])) * DT)
        omegas[n - 1] = (
            V + ODO_STD[0] * rng.standard_normal(),
            GYRO + ODO_STD[1] * rng.standard_normal(),
        )
    ys = np.zeros((steps, N_LANDMARKS, 3))
    ys[:, :, 2] = -1
    for n in range(steps):
        for i in range(N_LANDMARKS):
            d = np.linalg.norm(ldks[i] - ps[n])
            if MAX_RANGE > d > MIN_RANGE:
                ys[n, i, :2] = Rots[n].T.dot(ldks[i] - ps[n]) + OBS_STD * rng.standard_normal(2)
                ys[n, i, 2] = i
    poses = np.array(
        [(p[0], p[1], np.arctan2(R[1, 0], R[0, 0])) for R, p in zip(Rots, ps, strict=True)]
    )
    return World(poses, omegas, ldks, ys)


class State:
    """ukfm's ``SLAM2D.STATE``: the rotation, the position and the landmarks (k, 2)."""

    def __init__(self, Rot: Array, p: Array, p_l: Array | None = None) -> None:
        self.Rot, self.p = Rot, p
        self.p_l = np.zeros((2, 0)) if p_l is None else p_l


def f(state: State, omega: Array, w: Array, dt: float) -> State:
    """ukfm's ``SLAM2D.f``."""
    return State(
        Rot=state.Rot.dot(so2_exp((omega[1] + w[1]) * dt)),
        p=state.p + state.Rot.dot(np.hstack([omega[0] + w[0], 0])) * dt,
        p_l=state.p_l,
    )


def h(state: State) -> Array:
    """ukfm's ``SLAM2D.h`` for one landmark (``state.p_l`` holds just it)."""
    return state.Rot.T.dot(state.p_l - state.p)


def aug_z(state: State, y: Array) -> State:
    """ukfm's ``SLAM2D.aug_z``."""
    return State(Rot=state.Rot, p=state.p, p_l=state.Rot.dot(y) + state.p)


def phi(state: State, xi: Array) -> State:
    """ukfm's ``SLAM2D.phi``: SO(2) x R^(2(1+L))."""
    k = int(xi[3:].shape[0] / 2)
    p_ls = state.p_l + np.reshape(xi[3:], (k, 2))
    return State(Rot=state.Rot.dot(so2_exp(xi[0])), p=state.p + xi[1:3], p_l=p_ls)


class UkfmEKF:
    """ukfm's ``slam2d.EKF`` with ``ekf_FG_ana``, ``ekf_jacobian_update`` and ``ekf_augment``."""

    def __init__(self, state0: State, P0: Array, Q: Array) -> None:
        self.state, self.P, self.Q = state0, P0, Q
        self.new_state = self.state
        self.F = np.eye(self.P.shape[0])
        self.G = np.zeros((self.P.shape[0], self.Q.shape[0]))
        self.H = np.zeros((0, self.P.shape[0]))
        self.r = np.zeros(0)
        self.R = np.zeros((0, 0))
        self.q = Q.shape[0]

    def propagation(self, omega: Array, dt: float) -> None:
        self.new_state = f(self.state, omega, np.zeros(self.q), dt)
        self.F, self.G = self.jacobian_propagation(omega, dt)
        P = self.F.dot(self.P).dot(self.F.T) + self.G.dot(self.Q).dot(self.G.T)
        self.P = (P + P.T) / 2
        self.state = self.new_state

    def jacobian_propagation(self, omega: Array, dt: float) -> tuple[Array, Array]:
        F = np.eye(self.P.shape[0])
        F[1:3, 0] = self.state.Rot.dot(J).dot(np.hstack([omega[0], 0])) * dt
        G = np.zeros((self.P.shape[0], 2))
        G[1:3, 0] = self.state.Rot.dot(np.array([1, 0])) * dt
        G[0, 1] = dt
        return F, G

    def state_update(self) -> None:
        S = self.H.dot(self.P).dot(self.H.T) + self.R
        K = np.linalg.solve(S, self.P.dot(self.H.T).T).T
        xi = K.dot(self.r)
        self.state = phi(self.state, xi)
        P = (np.eye(self.P.shape[0]) - K.dot(self.H)).dot(self.P)
        self.P = (P + P.T) / 2
        self.H = np.zeros((0, self.P.shape[0]))
        self.r = np.zeros(0)
        self.R = np.zeros((0, 0))

    def H_num(self, y: Array, idxs: Array, R: Array) -> None:
        H_idx = np.zeros((2, 5))
        H_idx[:, 0] = -self.state.Rot.T.dot(J.dot(self.state.p_l - self.state.p))
        H_idx[:, 1:3] = -self.state.Rot.T
        H_idx[:, 3:] = self.state.Rot.T
        H = np.zeros((y.shape[0], self.P.shape[0]))
        H[:, idxs] = H_idx
        r = y - h(self.state)
        self.H = np.vstack((self.H, H))
        self.r = np.hstack((self.r, r))
        self.R = block_diag(self.R, R)

    def aug(self, y: Array, aug_idxs: Array, R: Array) -> None:
        self.state.p_l = np.squeeze(self.state.p_l)
        HR = np.zeros((2, 3))
        HR[:2, 0] = -self.state.Rot.T.dot(J.dot(self.state.p_l - self.state.p))
        HR[:2, 1:3] = -self.state.Rot.T
        H = np.zeros((2, self.P.shape[0]))
        H[:, aug_idxs] = HR
        HL = self.state.Rot.T
        iHL = np.linalg.inv(HL)
        P_sz = -iHL.dot(H.dot(self.P))
        P_ss = iHL.dot(H.dot(self.P).dot(H.T) + R).dot(iHL.T)
        d = self.P.shape[0]
        Pa = np.zeros((d + 2, d + 2))
        Pa[:d, :d] = self.P
        Pa[:d, d:] = P_sz.T
        Pa[d:, :d] = P_sz
        Pa[d:, d:] = P_ss
        self.P = Pa
        self.state = aug_z(self.state, y)
        self.H = np.zeros((0, self.P.shape[0]))
        self.r = np.zeros(0)
        self.R = np.zeros((0, 0))


def run_ukfm_ekf(world: World) -> Array:
    """ukfm's benchmark loop (``python/benchmarks/slam2d.py``) for its EKF alone; returns the
    estimated poses (N, 3) as (x, y, θ)."""
    Q = np.diag(ODO_STD**2)
    R = OBS_STD**2 * np.eye(2)
    aug_idxs = np.array([0, 1, 2])
    ekf = UkfmEKF(State(Rot=np.eye(2), p=np.zeros(2), p_l=np.zeros((0, 2))), np.zeros((3, 3)), Q)
    lmk = np.array([])
    ys = world.ys
    out = np.zeros((len(ys), 3))
    for n in range(1, len(ys)):
        ekf.propagation(world.omegas[n - 1], DT)
        y_n = ys[n]
        idxs = np.where(y_n[:, 2] >= 0)[0]
        p_ls = ekf.state.p_l
        for idx0 in idxs:
            idx = np.where(lmk == y_n[idx0, 2])[0]
            if idx.shape[0] == 0:
                continue
            up_idxs = np.hstack([0, 1, 2, 3 + 2 * idx, 4 + 2 * idx])
            ekf.state.p_l = np.squeeze(p_ls[idx])
            ekf.H_num(np.squeeze(y_n[idx0, :2]), up_idxs, R)
        ekf.state.p_l = p_ls
        if ekf.H.shape[0] > 0:
            ekf.state_update()
        for idx0 in idxs:
            idx = np.where(lmk == y_n[idx0, 2])[0]
            if not idx.shape[0] == 0:
                continue
            lmk = np.hstack([lmk, int(y_n[idx0, 2])])
            p_l = np.expand_dims(ekf.state.p + ekf.state.Rot.dot(y_n[idx0, :2]), 0)
            p_ls = np.vstack([ekf.state.p_l, p_l])
            ekf.state.p_l = p_l
            ekf.aug(y_n[idx0, :2], aug_idxs, R)
            ekf.state.p_l = p_ls
        Rot = ekf.state.Rot
        out[n] = (ekf.state.p[0], ekf.state.p[1], np.arctan2(Rot[1, 0], Rot[0, 0]))
    return out
