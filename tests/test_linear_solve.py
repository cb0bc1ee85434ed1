"""The sparse LDL^T solve of the Newton driver (solve.py): positive
definiteness and inertia from the pivot signs, shifted solves."""

import numpy as np
import pytest
import scipy.sparse as sp

from shellritz.solve import (MIN_SHIFT, EvaluationError, factorize_if_positive_definite,
                             shifted_solve, symmetric_from_lower)


def lower(A):
    return sp.tril(sp.csr_matrix(A)).tocsr()


def random_symmetric(n, eigenvalues, seed=0):
    rng = np.random.default_rng(seed)
    Q, _ = np.linalg.qr(rng.standard_normal((n, n)))
    return Q @ np.diag(eigenvalues) @ Q.T


@pytest.mark.parametrize("n_negative", [0, 1, 3])
def test_inertia_counts_negative_eigenvalues(n_negative):
    ev = np.linspace(0.5, 4.0, 12)
    ev[:n_negative] *= -1
    A = random_symmetric(12, ev)
    assert np.array_equal(symmetric_from_lower(lower(A)).toarray(), np.tril(A) + np.tril(A, -1).T)
    lu, negative = factorize_if_positive_definite(sp.csc_matrix(A))
    assert negative == n_negative
    assert (lu is not None) == (n_negative == 0)


def test_positive_definite_solve_is_exact():
    A = random_symmetric(30, np.linspace(0.1, 10, 30), seed=1)
    b = np.arange(30.0)
    lu, negative = factorize_if_positive_definite(sp.csc_matrix(A))
    assert negative == 0
    assert np.linalg.norm(A @ lu.solve(b) - b) <= 1e-12 * np.linalg.norm(b)


def test_singular_matrix_is_not_positive_definite():
    A = np.diag([1.0, 0.0, 2.0])
    lu, _ = factorize_if_positive_definite(sp.csc_matrix(A))
    assert lu is None


def test_shift_makes_indefinite_matrix_solvable():
    ev = np.linspace(-1.0, 3.0, 9)             # smallest eigenvalue -1
    A = random_symmetric(9, ev, seed=2)
    b = np.ones(9)
    x, shift = shifted_solve(lower(A), b)
    assert shift > 1.0                          # just above -lambda_min, by factors of 10
    assert shift <= 10.0 * 1.0 + 1e-12
    assert np.linalg.norm(A @ x + shift * x - b) <= 1e-10 * np.linalg.norm(b)
    x0, shift0 = shifted_solve(lower(A + 2 * np.eye(9)), b)
    assert shift0 == 0.0


def test_hopeless_matrix_raises():
    # eigenvalues +-1e6 with a zero diagonal: no shift up to 1e3 x the diagonal helps
    A = np.array([[0.0, 1e6], [1e6, 0.0]])
    with pytest.raises(EvaluationError, match="positive definite"):
        shifted_solve(lower(A), np.ones(2))


def test_tiny_shift_regularizes_an_exact_null_mode():
    """A free rigid translation makes the Hessian singular; Newton's shift,
    lowered 100x per iteration, ends far below MIN_SHIFT and then only
    regularizes the null mode: the solve is that of the consistent singular
    system (and counts as an undamped Newton step)."""
    # a free chain of springs: exact null mode (translation), exactly zero last pivot
    w = np.arange(1.0, 10.0)
    A = np.zeros((10, 10))
    for i, wi in enumerate(w):
        A[np.ix_([i, i + 1], [i, i + 1])] += wi * np.array([[1.0, -1.0], [-1.0, 1.0]])
    b = np.random.default_rng(4).standard_normal(10)
    b -= b.mean()                                        # consistent right-hand side
    scale = np.abs(np.diag(A)).max()
    assert factorize_if_positive_definite(sp.csc_matrix(A))[0] is None
    x, shift = shifted_solve(lower(A), b, 1e-6 * MIN_SHIFT * scale)
    assert 0 < shift < MIN_SHIFT * scale
    assert np.linalg.norm(A @ x - b) <= 1e-6 * np.linalg.norm(b)
