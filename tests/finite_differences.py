"""∂f/∂x by central differences: the one helper the Jacobian tests check their models with."""

from __future__ import annotations

import numpy as np


def central(fn, x, eps: float = 1e-6) -> np.ndarray:
    """∂fn/∂x at x (a vector) by central differences, one column per entry of x."""
    x = np.asarray(x, dtype=float)
    cols = []
    for k in range(len(x)):
        e = np.zeros(len(x))
        e[k] = eps
        cols.append((fn(x + e) - fn(x - e)) / (2 * eps))
    return np.column_stack(cols)
