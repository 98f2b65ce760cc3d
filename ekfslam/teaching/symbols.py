"""The sympy symbols of the seed's models, in the notebooks' names: the pose (x, y, theta), the
control increment (du_x, du_y, dtheta), a landmark (m_x, m_y), a measurement (r, phi).

Apart from `ekfslam.teaching.derivations` (which derives with them) so that an exercise's cell can
import the symbols while that exercise is graded without the derivations, which are its answer.
Real symbols: sympy then simplifies sqrt(q)^2 to q and takes conjugates as the identity.
"""

from __future__ import annotations

import sympy as sp

x, y, theta = sp.symbols("x y theta", real=True)
du_x, du_y, dtheta = sp.symbols("du_x du_y dtheta", real=True)
m_x, m_y = sp.symbols("m_x m_y", real=True)
r, phi = sp.symbols("r phi", real=True)
delta_x, delta_y = sp.symbols("delta_x delta_y", real=True)
q = sp.Symbol("q", positive=True)
sigma_r, sigma_phi = sp.symbols("sigma_r sigma_phi", positive=True)

POSE = (x, y, theta)
CONTROL = (du_x, du_y, dtheta)
x_b, y_b, theta_b = sp.symbols("x_b y_b theta_b", real=True)  # a robot another robot sees
LANDMARK = (m_x, m_y)
TARGET = (x_b, y_b, theta_b)
MEASUREMENT = (r, phi)
