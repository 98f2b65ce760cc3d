"""An adversarial corpus for the lab's checks: answers to exercises 1a-9 written apart from the
solutions, each as a student would type it into the exercise's cell.

Each entry is (exercise, kind, label, source, expected): `kind` is "right" (another form of a
correct answer: float32, lists, other formulas; must score 1 on the notebook's and on the graded
cases), "wrong" (must score less than 1, and the notebook's line must hold `expected`) or "cheat"
(calls the package's implementation, by any name: must score 0 and say "you called the
package's"). The sources run in a namespace holding `np`, `sp` and the derivations' symbols, as
the notebooks' cells do; anything else they import themselves.
"""

from __future__ import annotations

RIGHT, WRONG, CHEAT = "right", "wrong", "cheat"

TWIST = """
def twist_from_wheels(wheels, geometry):
    w1, w2, w3, w4 = wheels
    r, k = geometry.wheel_radius, geometry.lx + geometry.ly
    return {ret}
"""
J = "np.array([[1, 1, 1, 1], [-1, 1, 1, -1], [-1 / k, 1 / k, -1 / k, 1 / k]]) * r / 4"

COV = """
def twist_covariance(wheel_sigma, geometry):
    r, k = geometry.wheel_radius, geometry.lx + geometry.ly
    J = np.array([[1, 1, 1, 1], [-1, 1, 1, -1], [-1 / k, 1 / k, -1 / k, 1 / k]]) * r / 4
    s = np.asarray(wheel_sigma, dtype=float)
    return {ret}
"""

MOTION_F = """f = sp.Matrix([x + du_x * sp.cos(theta) - du_y * sp.sin(theta),
                    y + du_x * sp.sin(theta) + du_y * sp.cos(theta), theta + dtheta])"""

R_FN = """
def motion_noise_R(pose, M):
    c, s = np.cos(pose[2]), np.sin(pose[2])
    V = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    {body}
"""

PREDICT = """
def predict(mu, Sigma, u, R):
    x, y, th = mu[:3]
    c, s = np.cos(th), np.sin(th)
    G = np.array([[1.0, 0.0, -u[0] * s - u[1] * c], [0.0, 1.0, u[0] * c - u[1] * s], [0, 0, 1.0]])
    new = np.array(mu, dtype=float)
    new[0], new[1] = x + u[0] * c - u[1] * s, y + u[0] * s + u[1] * c
    new[2] = (th + u[2] + np.pi) % (2 * np.pi) - np.pi
    S = np.array(Sigma, dtype=float)
    {body}
    return new, S
"""
PREDICT_RIGHT = """S[:3, :3] = G @ S[:3, :3] @ G.T + R
    S[:3, 3:] = G @ S[:3, 3:]
    S[3:, :3] = S[:3, 3:].T"""

OBS = """
def derive_observation():
    {delta}
    z = sp.Matrix([sp.sqrt(dx**2 + dy**2), {bearing}])
    return z, z.jacobian([x, y, theta]), z.jacobian([m_x, m_y])
"""

ZHAT = """
def predict_z(pose, landmark):
    dx, dy = {delta}
    phi = {bearing}
    return {ret}
"""
WRAP = "(a + np.pi) % (2 * np.pi) - np.pi"

NEW = """
def add_landmark(mu, Sigma, z, Q):
    d = len(mu)
    x, y, th = mu[:3]
    r, phi = z
    c, s = np.cos(th + phi), np.sin(th + phi)
    Gp = np.array([[1.0, 0.0, -r * s], [0.0, 1.0, r * c]])
    Gz = np.array([[c, -r * s], [s, r * c]])
    out = np.zeros((d + 2, d + 2))
    out[:d, :d] = Sigma
    {body}
    return np.concatenate([mu, [x + r * c, y + r * s]]), out
"""
NEW_RIGHT = """out[d:, :d] = Gp @ Sigma[:3, :]
    out[:d, d:] = out[d:, :d].T
    out[d:, d:] = Gp @ Sigma[:3, :3] @ Gp.T + Gz @ Q @ Gz.T"""

JOSEPH = """
def joseph(Sigma, K, H, Q):
    A = np.eye(len(Sigma)) - K @ H
    return {ret}
"""

UPDATE = """
def joseph(Sigma, K, H, Q):
    A = np.eye(len(Sigma)) - K @ H
    return A @ Sigma @ A.T + K @ Q @ K.T


def wrap(a):
    return (a + np.pi) % (2 * np.pi) - np.pi


def update(mu, Sigma, j, z, Q):
    d = len(mu)
    l = {slot}
    dx, dy = mu[l] - mu[0], mu[l + 1] - mu[1]
    q = dx * dx + dy * dy
    r = np.sqrt(q)
    z_hat = np.array([r, wrap(np.arctan2(dy, dx) - mu[2])])
    H = np.zeros((2, d))
    H[:, :3] = [[-dx / r, -dy / r, 0.0], [dy / q, -dx / q, -1.0]]
    H[:, l : l + 2] = [[dx / r, dy / r], [-dy / q, dx / q]]
    S = H @ Sigma @ H.T + {noise}
    K = np.linalg.solve(S, H @ Sigma).T
    nu = z - z_hat
    {wrap_nu}
    {post}
    return post, joseph(Sigma, K, H, Q)
"""
UPDATE_RIGHT = {
    "slot": "3 + 2 * j",
    "noise": "Q",
    "wrap_nu": "nu[1] = wrap(nu[1])",
    "post": "post = mu + K @ nu\n    post[2] = wrap(post[2])",
}

GATE = """
def nis_gate(z, z_hat, S, p):
    {body}
"""

ALIGN = """
from scipy.optimize import minimize


def align_map(X, Y):
    def cost(p):
        c, s = np.cos(p[2]), np.sin(p[2])
        moved = X @ np.array([[c, -s], [s, c]]).T + p[:2]
        return np.mean(np.linalg.norm(moved - Y, axis=1))

    {body}
"""
ALIGN_START = """c0 = Y.mean(0) - X.mean(0)
    best = minimize(cost, [*c0, 0.0], method="Powell", options={"xtol": 1e-12, "ftol": 1e-15})
    best = minimize(cost, best.x, method="Nelder-Mead",
                    options={"xatol": 1e-11, "fatol": 1e-16, "maxiter": 40000})"""

INVERSE = """
from scipy.optimize import minimize


def align_map(X, Y):
    def cost(p):  # lays the true map Y onto the estimate X
        c, s = np.cos(p[2]), np.sin(p[2])
        return np.mean(np.linalg.norm(Y @ np.array([[c, -s], [s, c]]).T + p[:2] - X, axis=1))

    best = minimize(cost, [*(X.mean(0) - Y.mean(0)), 0.0], method="Powell",
                    options={"xtol": 1e-12, "ftol": 1e-15})
    best = minimize(cost, best.x, method="Nelder-Mead",
                    options={"xatol": 1e-11, "fatol": 1e-16, "maxiter": 40000})
    return best.x
"""

LOOP = """
from itertools import pairwise

from ekfslam.core import models


def replay_loop(run, ekf, noise):
    twist, tc, det = run.control_twist(), run.controls.t, run.detections
    M, Q = noise.motion_density(), noise.Q
    {body}
"""
LOOP_EVENTS = """# one merged, sorted list of events: a control row starts, or a tag is seen
    events = sorted([(t, 1, i) for i, t in enumerate(tc)] + [(t, 0, k) for k, t in enumerate(det.t)])
    now, row = None, -1
    for t, kind, i in events:
        if row >= 0 and t > now:
            dt = t - now
            ekf.predict(twist[row] * dt, models.motion_noise(ekf.mu[:3], M * dt), t)
        now = t
        if kind == 1:
            row = i
        else:
            ekf.update(int(det.tag_id[i]), (det.range[i], det.bearing[i]), Q, t)"""
LOOP_WHOLE = """k = 0
    for i in range(len(tc) - 1):
        dt = tc[i + 1] - tc[i]
        ekf.predict(twist[i] * dt, models.motion_noise(ekf.mu[:3], M * dt), tc[i + 1])
        while k < len(det.t) and det.t[k] <= tc[i + 1]:
            ekf.update(int(det.tag_id[k]), (det.range[k], det.bearing[k]), Q, det.t[k])
            k += 1
    while k < len(det.t):
        ekf.update(int(det.tag_id[k]), (det.range[k], det.bearing[k]), Q, det.t[k])
        k += 1"""

CORPUS: list[tuple[str, str, str, str, str]] = [
    # --- 1a ---
    (
        "1a",
        RIGHT,
        "float32",
        TWIST.format(ret=f"({J} @ np.asarray(wheels)).astype(np.float32)"),
        "",
    ),
    ("1a", RIGHT, "a list", TWIST.format(ret=f"list({J} @ np.asarray(wheels))"), ""),
    (
        "1a",
        RIGHT,
        "a tuple, term by term",
        TWIST.format(
            ret="(r / 4 * (w1 + w2 + w3 + w4), r / 4 * (w2 + w3 - w1 - w4), "
            "r * (w2 + w4 - w1 - w3) / (4 * k))"
        ),
        "",
    ),
    ("1a", RIGHT, "J from einsum", TWIST.format(ret=f"np.einsum('ij,j->i', {J}, wheels)"), ""),
    (
        "1a",
        WRONG,
        "vy negated",
        TWIST.format(ret=f"{J} @ np.asarray(wheels) * [1, -1, 1]"),
        "vy has the wrong sign",
    ),
    (
        "1a",
        WRONG,
        "ωz without 1/(lx+ly)",
        TWIST.format(ret=f"{J} @ np.asarray(wheels) * [1, 1, k]"),
        "wrong factor",
    ),
    ("1a", WRONG, "zeros", TWIST.format(ret="np.zeros(3)"), "returns zeros"),
    (
        "1a",
        WRONG,
        "numbers typed in",
        TWIST.format(
            ret=J.replace("k", "0.122").replace("r /", "0.03 /") + " @ np.asarray(wheels)"
        ),
        "right for the default robot only",
    ),
    (
        "1a",
        WRONG,
        "ω3 negated",
        TWIST.format(ret=f"{J} @ (np.asarray(wheels) * [1, 1, -1, 1])"),
        "J[0, 2]",
    ),
    (
        "1a",
        WRONG,
        "a constant",
        TWIST.format(ret="np.array([0.0375, 0.0, 0.0])"),
        "same answer whatever",
    ),
    (
        "1a",
        CHEAT,
        "the geometry's matrix",
        TWIST.format(ret="geometry.wheels_to_twist_matrix @ np.asarray(wheels)"),
        "wheels_to_twist_matrix",
    ),
    (
        "1a",
        CHEAT,
        "ekfslam.wheels_to_twist under another name",
        "import ekfslam\nconvert = ekfslam.wheels_to_twist\n"
        "def twist_from_wheels(wheels, geometry):\n    return convert(wheels, geometry)\n",
        "wheels_to_twist",
    ),
    # --- 1b ---
    ("1b", RIGHT, "float32", COV.format(ret="(J @ np.diag(s**2) @ J.T).astype(np.float32)"), ""),
    (
        "1b",
        RIGHT,
        "sum of outer products",
        COV.format(ret="sum(s[i] ** 2 * np.outer(J[:, i], J[:, i]) for i in range(4))"),
        "",
    ),
    ("1b", RIGHT, "J scaled by σ", COV.format(ret="(J * s) @ (J * s).T"), ""),
    ("1b", WRONG, "σ for σ²", COV.format(ret="J @ np.diag(s) @ J.T"), "needs variances"),
    (
        "1b",
        CHEAT,
        "the package's covariance",
        "from ekfslam.core.kinematics import wheel_noise_to_twist_covariance as cov\n"
        "def twist_covariance(wheel_sigma, geometry):\n    return cov(wheel_sigma, geometry)\n",
        "wheel_noise_to_twist_covariance",
    ),
    # --- 2a ---
    (
        "2a",
        RIGHT,
        "sp.diff entry by entry, own symbols",
        "def derive_motion_jacobians():\n"
        "    x, y, theta, du_x, du_y, dtheta = sp.symbols('x y theta du_x du_y dtheta')\n"
        f"    {MOTION_F}\n"
        "    G = sp.Matrix(3, 3, lambda i, j: sp.diff(f[i], [x, y, theta][j]))\n"
        "    V = sp.Matrix(3, 3, lambda i, j: sp.diff(f[i], [du_x, du_y, dtheta][j]))\n"
        "    return G, V\n",
        "",
    ),
    (
        "2a",
        WRONG,
        "G typed in by hand",
        "def derive_motion_jacobians():\n"
        "    G = sp.Matrix([[1, 0, -du_x * sp.sin(theta) - du_y * sp.cos(theta)],\n"
        "                   [0, 1, du_x * sp.cos(theta) - du_y * sp.sin(theta)], [0, 0, 1]])\n"
        "    V = sp.Matrix([[sp.cos(theta), -sp.sin(theta), 0], [sp.sin(theta), sp.cos(theta), 0],\n"
        "                   [0, 0, 1]])\n"
        "    return G, V\n",
        "typed in, not derived",
    ),
    (
        "2a",
        WRONG,
        "(V, G)",
        f"def derive_motion_jacobians():\n    {MOTION_F}\n"
        "    return f.jacobian([du_x, du_y, dtheta]), f.jacobian([x, y, theta])\n",
        "G and V are swapped",
    ),
    (
        "2a",
        WRONG,
        "+Δuy sin θ in x",
        "def derive_motion_jacobians():\n"
        f"    {MOTION_F.replace('- du_y * sp.sin(theta),', '+ du_y * sp.sin(theta),')}\n"
        "    return f.jacobian([x, y, theta]), f.jacobian([du_x, du_y, dtheta])\n",
        "G[0, 2]",
    ),
    (
        "2a",
        CHEAT,
        "the package's derivation",
        "from ekfslam.teaching import derivations\n"
        "def derive_motion_jacobians():\n"
        "    m = derivations.motion_model()\n    return m.jacobian_pose, m.jacobian_input\n",
        "you called the package's",
    ),
    # --- 2b ---
    ("2b", RIGHT, "float32", R_FN.format(body="return (V @ M @ V.T).astype(np.float32)"), ""),
    (
        "2b",
        RIGHT,
        "nested lists",
        R_FN.format(body="return (V @ np.asarray(M) @ V.T).tolist()"),
        "",
    ),
    ("2b", RIGHT, "einsum", R_FN.format(body="return np.einsum('ij,jk,lk->il', V, M, V)"), ""),
    ("2b", WRONG, "R = M", R_FN.format(body="return np.array(M)"), "R equals M"),
    ("2b", WRONG, "Vᵀ M V", R_FN.format(body="return V.T @ M @ V"), "Vᵀ M V instead of V M Vᵀ"),
    (
        "2b",
        WRONG,
        "M changed in place",
        R_FN.format(body="M[:] = V @ M @ V.T\n    return M"),
        "changed the M it was given",
    ),
    (
        "2b",
        CHEAT,
        "motion_noise in a lambda",
        "from ekfslam.core import models\nmotion_noise_R = lambda pose, M: models.motion_noise(pose, M)\n",
        "motion_noise",
    ),
    # --- 3 ---
    ("3", RIGHT, "own f and G, block form", PREDICT.format(body=PREDICT_RIGHT), ""),
    (
        "3",
        RIGHT,
        "the lifted G, full products",
        PREDICT.format(
            body="Gt = np.eye(len(S))\n    Gt[:3, :3] = G\n    F = np.zeros((3, len(S)))\n"
            "    F[:, :3] = np.eye(3)\n    S = Gt @ S @ Gt.T + F.T @ R @ F"
        ),
        "",
    ),
    (
        "3",
        RIGHT,
        "float32",
        PREDICT.format(
            body=PREDICT_RIGHT + "\n    new, S = new.astype(np.float32), S.astype(np.float32)"
        ),
        "",
    ),
    (
        "3",
        WRONG,
        "heading not wrapped",
        PREDICT.format(body=PREDICT_RIGHT + "\n    new[2] = th + u[2]"),
        "heading is not wrapped",
    ),
    (
        "3",
        WRONG,
        "G[0, 2] sign",
        PREDICT.format(body="G[0, 2] = -G[0, 2]\n    " + PREDICT_RIGHT),
        "G[0, 2] (row x, column θ) has the wrong sign",
    ),
    (
        "3",
        WRONG,
        "Σ[r, m] left alone",
        PREDICT.format(body="S[:3, :3] = G @ S[:3, :3] @ G.T + R"),
        "Σ[r, m] is not updated",
    ),
    (
        "3",
        WRONG,
        "R left out",
        PREDICT.format(body=PREDICT_RIGHT.replace(" + R", "")),
        "R is missing",
    ),
    (
        "3",
        WRONG,
        "Σ changed in place",
        PREDICT.format(body="S = Sigma\n    " + PREDICT_RIGHT),
        "changed the Σ it was given",
    ),
    (
        "3",
        CHEAT,
        "predict_step",
        "from ekfslam.core.steps import predict_step\n"
        "def predict(mu, Sigma, u, R):\n    return predict_step(mu, Sigma, u, R)\n",
        "predict_step",
    ),
    (
        "3",
        CHEAT,
        "the module under another name",
        "import ekfslam.core.steps as helpers\n"
        "def predict(mu, Sigma, u, R):\n    return getattr(helpers, 'predict' + '_step')(mu, Sigma, u, R)\n",
        "predict_step",
    ),
    (
        "3",
        CHEAT,
        "the filter object",
        "import ekfslam\n"
        "def predict(mu, Sigma, u, R):\n"
        "    f = ekfslam.EKFSLAM(mu[:3], Sigma[:3, :3])\n"
        "    f.predict(u, R)\n    return f.mu, f.Sigma\n",
        "you called the package's",
    ),
    (
        "3",
        CHEAT,
        "the literal F_x reference",
        "from ekfslam.teaching.reference import LiteralEKFSLAM\n"
        "def predict(mu, Sigma, u, R):\n"
        "    f = LiteralEKFSLAM(mu[:3], Sigma[:3, :3])\n    f.predict(u, R)\n    return f.mu, f.Sigma\n",
        "you called the package's",
    ),
    # --- 4a ---
    (
        "4a",
        RIGHT,
        "atan2, the norm squared written out",
        OBS.format(delta="dx, dy = -(x - m_x), -(y - m_y)", bearing="sp.atan2(dy, dx) - theta"),
        "",
    ),
    (
        "4a",
        WRONG,
        "δ = robot − landmark",
        OBS.format(delta="dx, dy = x - m_x, y - m_y", bearing="sp.atan2(dy, dx) - theta"),
        "δ is landmark − robot",
    ),
    (
        "4a",
        WRONG,
        "the seed's arctan",
        OBS.format(delta="dx, dy = m_x - x, m_y - y", bearing="sp.atan(dy / dx) - theta"),
        "use atan2",
    ),
    (
        "4a",
        WRONG,
        "+θ",
        OBS.format(delta="dx, dy = m_x - x, m_y - y", bearing="sp.atan2(dy, dx) + theta"),
        "adds the heading",
    ),
    (
        "4a",
        CHEAT,
        "the package's derivation",
        "from ekfslam.teaching import derivations as d\n"
        "def derive_observation():\n    o = d.observation_model()\n"
        "    return o.value, o.jacobian_pose, o.jacobian_input\n",
        "you called the package's",
    ),
    # --- 4b ---
    (
        "4b",
        RIGHT,
        "math.atan2, own wrap",
        "import math\n"
        + ZHAT.format(
            delta="landmark[0] - pose[0], landmark[1] - pose[1]",
            bearing="(math.atan2(dy, dx) - pose[2] + math.pi) % (2 * math.pi) - math.pi",
            ret="np.array([math.hypot(dx, dy), phi])",
        ),
        "",
    ),
    (
        "4b",
        RIGHT,
        "complex numbers, a tuple",
        ZHAT.format(
            delta="landmark[0] - pose[0], landmark[1] - pose[1]",
            bearing="np.angle((dx + 1j * dy) * np.exp(-1j * pose[2]))",
            ret="(abs(dx + 1j * dy), phi)",
        ),
        "",
    ),
    (
        "4b",
        RIGHT,
        "float32",
        ZHAT.format(
            delta="np.float32(landmark[0] - pose[0]), np.float32(landmark[1] - pose[1])",
            bearing="np.arctan2(np.sin(np.arctan2(dy, dx) - pose[2]), np.cos(np.arctan2(dy, dx) - pose[2]))",
            ret="np.array([np.hypot(dx, dy), phi], dtype=np.float32)",
        ),
        "",
    ),
    (
        "4b",
        WRONG,
        "no wrap",
        ZHAT.format(
            delta="landmark[0] - pose[0], landmark[1] - pose[1]",
            bearing="np.arctan2(dy, dx) - pose[2]",
            ret="np.array([np.hypot(dx, dy), phi])",
        ),
        "not wrapped",
    ),
    (
        "4b",
        WRONG,
        "δ reversed",
        ZHAT.format(
            delta="pose[0] - landmark[0], pose[1] - landmark[1]",
            bearing="(np.arctan2(dy, dx) - pose[2] + np.pi) % (2 * np.pi) - np.pi",
            ret="np.array([np.hypot(dx, dy), phi])",
        ),
        "δ is landmark − robot",
    ),
    (
        "4b",
        WRONG,
        "range squared",
        ZHAT.format(
            delta="landmark[0] - pose[0], landmark[1] - pose[1]",
            bearing="(np.arctan2(dy, dx) - pose[2] + np.pi) % (2 * np.pi) - np.pi",
            ret="np.array([dx**2 + dy**2, phi])",
        ),
        "squared distance",
    ),
    (
        "4b",
        CHEAT,
        "observation found by name",
        "import importlib\nobs = getattr(importlib.import_module('ekfslam.core.models'), 'observa' + 'tion')\n"
        "def predict_z(pose, landmark):\n    return obs(pose, landmark)\n",
        "observation",
    ),
    (
        "4b",
        CHEAT,
        "the package's observation model, compiled by the package (numba)",
        "from ekfslam.core import models\nfrom ekfslam.core.filter import compile as cc\n"
        "h = cc.compiled({'h': models.observation}, {}).h\n"
        "def predict_z(pose, landmark):\n"
        "    return h(np.asarray(pose, float), np.asarray(landmark, float))\n",
        "observation",
    ),
    # --- 5 ---
    ("5", RIGHT, "own Jacobians, block form", NEW.format(body=NEW_RIGHT), ""),
    (
        "5",
        RIGHT,
        "the grown Σ as A Σ Aᵀ + B Q Bᵀ",
        NEW.format(
            body="A = np.zeros((d + 2, d))\n    A[:d, :d] = np.eye(d)\n    A[d:, :3] = Gp\n"
            "    B = np.zeros((d + 2, 2))\n    B[d:] = Gz\n    out = A @ Sigma @ A.T + B @ Q @ B.T"
        ),
        "",
    ),
    (
        "5",
        WRONG,
        "no cross-covariance",
        NEW.format(body="out[d:, d:] = Gp @ Sigma[:3, :3] @ Gp.T + Gz @ Q @ Gz.T"),
        "cross-covariance of the new landmark is missing",
    ),
    (
        "5",
        WRONG,
        "the robot block only",
        NEW.format(body=NEW_RIGHT + "\n    out[d:, 3:d] = 0.0\n    out[3:d, d:] = 0.0"),
        "older landmarks",
    ),
    (
        "5",
        CHEAT,
        "new_landmark_step through functools.partial",
        "import functools\nfrom ekfslam.core import steps\n"
        "add_landmark = functools.partial(steps.new_landmark_step)\n",
        "new_landmark_step",
    ),
    # --- 6a ---
    (
        "6a",
        RIGHT,
        "expanded",
        JOSEPH.format(
            ret="Sigma - K @ H @ Sigma - Sigma @ H.T @ K.T + K @ (H @ Sigma @ H.T + Q) @ K.T"
        ),
        "",
    ),
    (
        "6a",
        RIGHT,
        "float32",
        JOSEPH.format(ret="(A @ Sigma @ A.T + K @ Q @ K.T).astype(np.float32)"),
        "",
    ),
    (
        "6a",
        RIGHT,
        "nested lists",
        JOSEPH.format(ret="(A @ Sigma @ A.T + K @ Q @ K.T).tolist()"),
        "",
    ),
    ("6a", WRONG, "(I - KH)Σ", JOSEPH.format(ret="A @ Sigma"), "seed's (I - KH)Σ"),
    ("6a", WRONG, "K Q Kᵀ left out", JOSEPH.format(ret="A @ Sigma @ A.T"), "K Q Kᵀ is missing"),
    (
        "6a",
        WRONG,
        "transposes swapped",
        JOSEPH.format(ret="A.T @ Sigma @ A + K @ Q @ K.T"),
        "wrong side",
    ),
    # --- 6b ---
    ("6b", RIGHT, "own ẑ and H, solve for K", UPDATE.format(**UPDATE_RIGHT), ""),
    (
        "6b",
        RIGHT,
        "float32",
        UPDATE.format(
            **{
                **UPDATE_RIGHT,
                "post": "post = (mu + K @ nu).astype(np.float32)\n    post[2] = wrap(post[2])",
            }
        ),
        "",
    ),
    (
        "6b",
        WRONG,
        "ν not wrapped",
        UPDATE.format(**{**UPDATE_RIGHT, "wrap_nu": "pass"}),
        "innovation z - ẑ is not wrapped",
    ),
    (
        "6b",
        WRONG,
        "slot off by one",
        UPDATE.format(**{**UPDATE_RIGHT, "slot": "5 + 2 * j"}),
        "reads the landmark from rows",
    ),
    (
        "6b",
        WRONG,
        "slot without ×2",
        UPDATE.format(**{**UPDATE_RIGHT, "slot": "3 + j"}),
        "reads the landmark from rows",
    ),
    (
        "6b",
        WRONG,
        "posterior heading not wrapped",
        UPDATE.format(**{**UPDATE_RIGHT, "post": "post = mu + K @ nu"}),
        "posterior heading is not wrapped",
    ),
    (
        "6b",
        WRONG,
        "S without Q",
        UPDATE.format(**{**UPDATE_RIGHT, "noise": "0.0"}),
        "Q is missing from S",
    ),
    (
        "6b",
        WRONG,
        "μ changed in place",
        UPDATE.format(
            **{**UPDATE_RIGHT, "post": "mu += K @ nu\n    mu[2] = wrap(mu[2])\n    post = mu"}
        ),
        "changed the μ it was given",
    ),
    (
        "6b",
        CHEAT,
        "update_steps",
        "from ekfslam.core.steps import update_steps\n\n"
        "def joseph(Sigma, K, H, Q):\n    A = np.eye(len(Sigma)) - K @ H\n    return A @ Sigma @ A.T + K @ Q @ K.T\n\n"
        "def update(mu, Sigma, j, z, Q):\n    s = update_steps(mu, Sigma, j, z, Q)\n"
        "    return s.mu_post, joseph(Sigma, s.K, s.H, Q)\n",
        "update_steps",
    ),
    # --- 7 ---
    (
        "7",
        RIGHT,
        "scipy's chi2, inv",
        "from scipy.stats import chi2\n"
        + GATE.format(
            body="nu = np.array(z, dtype=float) - z_hat\n    nu[1] = np.arctan2(np.sin(nu[1]), np.cos(nu[1]))\n"
            "    return float(nu @ np.linalg.inv(S) @ nu), float(chi2.ppf(p, 2))"
        ),
        "",
    ),
    (
        "7",
        RIGHT,
        "a list",
        GATE.format(
            body="nu = np.subtract(z, z_hat)\n    nu[1] = (nu[1] + np.pi) % (2 * np.pi) - np.pi\n"
            "    return [nu @ np.linalg.solve(S, nu), -2 * np.log1p(-p)]"
        ),
        "",
    ),
    (
        "7",
        WRONG,
        "ν not wrapped",
        GATE.format(
            body="nu = np.subtract(z, z_hat)\n    return nu @ np.linalg.solve(S, nu), -2 * np.log(1 - p)"
        ),
        "not wrapped",
    ),
    (
        "7",
        WRONG,
        "νᵀ S ν",
        GATE.format(
            body="nu = np.subtract(z, z_hat)\n    nu[1] = (nu[1] + np.pi) % (2 * np.pi) - np.pi\n"
            "    return nu @ S @ nu, -2 * np.log(1 - p)"
        ),
        "multiplies by S",
    ),
    (
        "7",
        WRONG,
        "-2 ln p",
        GATE.format(
            body="nu = np.subtract(z, z_hat)\n    nu[1] = (nu[1] + np.pi) % (2 * np.pi) - np.pi\n"
            "    return nu @ np.linalg.solve(S, nu), -2 * np.log(p)"
        ),
        "uses ln p",
    ),
    (
        "7",
        WRONG,
        "z changed in place",
        GATE.format(
            body="z -= z_hat\n    z[1] = (z[1] + np.pi) % (2 * np.pi) - np.pi\n"
            "    return z @ np.linalg.solve(S, z), -2 * np.log(1 - p)"
        ),
        "changed the z it was given",
    ),
    (
        "7",
        CHEAT,
        "the filter's quantile",
        "from ekfslam.core.filter.config import chi2_2dof_quantile as q\n"
        + GATE.format(
            body="nu = np.subtract(z, z_hat)\n    nu[1] = (nu[1] + np.pi) % (2 * np.pi) - np.pi\n"
            "    return nu @ np.linalg.solve(S, nu), q(p)"
        ),
        "chi2_2dof_quantile",
    ),
    # --- 8 ---
    ("8", RIGHT, "a merged event list", LOOP.format(body=LOOP_EVENTS), ""),
    (
        "8",
        WRONG,
        "whole intervals",
        LOOP.format(body=LOOP_WHOLE),
        "split the interval at each detection",
    ),
    (
        "8",
        WRONG,
        "R from M, not M dt",
        LOOP.format(body=LOOP_EVENTS.replace("M * dt), t)", "M), t)")),
        "builds each piece's R from M itself",
    ),
    (
        "8",
        CHEAT,
        "the package's replay",
        "import ekfslam\n\ndef replay_loop(run, ekf, noise):\n    done = ekfslam.replay(run, noise)\n",
        "replay",
    ),
    (
        "8",
        CHEAT,
        "the check's own loop",
        "from ekfslam.analysis import replay_mistakes as rm\n\n"
        "def replay_loop(run, ekf, noise):\n    rm.mistaken_loop(run, ekf, noise, None)\n",
        "mistaken_loop",
    ),
    # --- 9 ---
    (
        "9",
        RIGHT,
        "Powell then Nelder-Mead",
        ALIGN.format(body=ALIGN_START + "\n    return best.x"),
        "",
    ),
    ("9", RIGHT, "a list", ALIGN.format(body=ALIGN_START + "\n    return list(best.x)"), ""),
    (
        "9",
        WRONG,
        "least squares (Kabsch)",
        ALIGN.format(
            body="mx, my = X.mean(0), Y.mean(0)\n    U, _, Vt = np.linalg.svd((X - mx).T @ (Y - my))\n"
            "    R = Vt.T @ U.T\n    t = my - R @ mx\n    return t[0], t[1], np.arctan2(R[1, 0], R[0, 0])"
        ),
        "least squares",
    ),
    ("9", WRONG, "the inverse transform", INVERSE, "lays the true map onto the estimate"),
    (
        "9",
        WRONG,
        "θ0 negated",
        ALIGN.format(body=ALIGN_START + "\n    return best.x * [1, 1, -1]"),
        "wrong sign",
    ),
    (
        "9",
        CHEAT,
        "ekfslam.align_mean_distance",
        "import ekfslam\n\ndef align_map(X, Y):\n    a = ekfslam.align_mean_distance(X, Y)\n"
        "    return a.x0, a.y0, a.theta0\n",
        "align_mean_distance",
    ),
]
