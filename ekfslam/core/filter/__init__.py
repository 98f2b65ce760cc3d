"""The EKF-SLAM filter (eqs. 1-16): `ekf` (the class), `config`, `history`, `kernels` (numba).

Nothing is re-exported here: importing the package must not compile the kernels."""
