"""In-place operations on the filter's pre-allocated covariance storage.

The update of eq. (16) is, for the optimal gain, Σ -= K S Kᵀ = Wᵀ W with W = L⁻¹ (H Σ) (2 x n):
the only O(n²) step of the filter. It must touch Σ once, where it lies, with no n x n temporary.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

Array = NDArray[np.float64]


#: Bytes of Σ's rows per BLAS call in `subtract_gram`.
_BLOCK_BYTES = 1 << 19
#: Up to this state size (about 20 landmarks) numpy's Σ -= Wᵀ W is as fast as BLAS in place,
#: and scipy.linalg need not be imported.
_NUMPY_MAX_DIM = 40


def subtract_gram(S: Array, W: Array, d: int) -> None:
    """Σ -= Wᵀ W in place: S is the (capacity, capacity) storage, W (2, capacity), zero beyond d.

    A small map takes one numpy expression. A larger one takes BLAS dgemm with β = 1, which
    updates Σ where it lies, in one pass over memory with no n x n temporary (the memory-bound
    floor of an O(n²) update). It gets whole rows of the storage, S[i0:i1, :], as the
    Fortran-ordered matrix S[i0:i1, :]ᵀ, a block of rows per call; each call then stays small
    enough for BLAS to run it on one thread, and a memory-bound pass gains nothing from more.
    (``a.dot(b)`` rather than ``a @ b`` in the hot paths: the same product, less overhead on
    small arrays.)
    """
    capacity = S.shape[1]
    if d <= _NUMPY_MAX_DIM and 8 * d * capacity <= _BLOCK_BYTES:
        S[:d] -= W[:, :d].T.dot(W)  # whole rows: contiguous, hence faster than S[:d, :d]
        return
    from scipy.linalg.blas import dgemm  # here, not at the top: scipy.linalg is slow to import

    rows = max(1, _BLOCK_BYTES // (8 * capacity))
    for i0 in range(0, d, rows):
        i1 = min(d, i0 + rows)
        out = dgemm(-1.0, W.T, W[:, i0:i1], beta=1.0, c=S[i0:i1].T, overwrite_c=True)
        assert out.base is S, "dgemm worked on a copy"  # S must be C-ordered, as allocated
