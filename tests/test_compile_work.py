"""Compile-cost changes keep the numbers: the Levenberg–Marquardt kernel's linear solve calls LAPACK dgesv
directly (imunoise.fitting.kernels._solve) and must give np.linalg.solve's bits and errors."""

from __future__ import annotations

import numpy as np
import pytest

from imunoise.fitting.kernels import _solve


@pytest.mark.parametrize("n", [1, 3, 7])
def test_solve_is_numpy_solve_to_the_bit(n):
    rng = np.random.default_rng(n)
    for _ in range(20):
        J = rng.standard_normal((n + 4, n))
        M = J.T @ J + np.diag(rng.uniform(1e-6, 1.0, n))  # the damped normal matrix of the LM step
        b = rng.standard_normal(n)
        assert np.array_equal(_solve(M, b), np.linalg.solve(M, b))
    A = rng.standard_normal((n, n)) + n * np.eye(n)  # not symmetric: the column-major copy matters
    assert np.array_equal(_solve(A, b), np.linalg.solve(A, b))


def test_solve_raises_what_numpy_solve_raises():
    with pytest.raises(np.linalg.LinAlgError, match="singular"):
        _solve(np.zeros((2, 2)), np.ones(2))
    with pytest.raises(np.linalg.LinAlgError, match="infs or NaNs"):
        _solve(np.array([[1.0, np.nan], [0.0, 1.0]]), np.ones(2))
    with pytest.raises(np.linalg.LinAlgError, match="infs or NaNs"):
        _solve(np.eye(2), np.array([1.0, np.inf]))
