"""The straight-line code the compiled filter runs for `advance` does what `advance`'s lines do."""

import math

import numpy as np
import pytest

from ekfslam.core.filter import generate, steps
from ekfslam.core.models import ODOMETRY, RANGE_BEARING
from ekfslam.geometry import wrap_angle

MODELS = {"motion": ODOMETRY, "sensor": RANGE_BEARING}


@pytest.fixture(scope="module")
def generated():
    source = generate.straight_line(
        steps.advance, steps.STRAIGHT_LINE["advance"], MODELS, "advance"
    )
    env = {"math": math, "wrap_angle": wrap_angle}
    exec(compile(source, "<generated advance>", "exec"), env)
    return env["advance"], source


def _block(rng):
    block = np.zeros(steps.BLOCK)
    block[steps.POSE : steps.COV] = rng.uniform(-2, 2, 3) * (1, 1, 1.5)
    A = rng.normal(size=(3, 3))
    block[steps.COV : steps.PRODUCT] = (A @ A.T + np.eye(3)).ravel() * 1e-2
    block[steps.PRODUCT : steps.BEFORE] = (np.eye(3) + 0.1 * rng.normal(size=(3, 3))).ravel()
    block[steps.BEFORE : steps.OWED] = block[steps.POSE : steps.COV] + rng.normal(size=3) * 0.01
    block[steps.OWED :] = rng.normal(size=3) * 1e-3
    return block


@pytest.mark.parametrize("per_second", [False, True])
@pytest.mark.parametrize("lin", list(steps.Linearization))
def test_generated_advance_writes_what_advance_writes(generated, per_second, lin):
    fn, _ = generated
    rng = np.random.default_rng(int(lin) * 2 + per_second)
    for _ in range(50):
        block = _block(rng)
        u = rng.normal(size=3) * (0.05, 0.05, 0.3)
        B = rng.normal(size=(3, 3))
        N = B @ B.T * 1e-3
        dt = float(rng.uniform(0.001, 0.5))
        a, b = block.copy(), block.copy()
        steps.advance(a, u, N, dt, per_second, int(lin))  # its lines, interpreted
        fn(b, u, N, dt, per_second, int(lin))
        np.testing.assert_allclose(b, a, rtol=1e-12, atol=1e-15)
        assert not np.array_equal(a, block)  # the step did write


def test_generated_advance_is_straight_line_code(generated):
    _, source = generated
    assert "np." not in source and "@" not in source  # no arrays made: scalars only
    assert source.count("if ") == 2 * len(steps.Linearization)  # one branch per flag combination
