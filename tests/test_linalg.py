"""The linear algebra of the Newton steps (linalg.py): inertia and solves of
the direct methods, the two factor slots, the Steihaug-Toint conjugate
gradients, the free rigid motions, AMG, method names."""

import types

import numpy as np
import pytest
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from shellritz import NeoHookean, Shell, shapes
from shellritz.linalg import (METHODS, REGULARIZATION, CGPath, DirectSolver, LinearSolverError, free_rigid_modes,
                              lower_matvec, make_linear_solver, pardiso_available, projector,
                              resolve_method, steihaug_cg, symmetric_from_lower)

DIRECT = ["superlu"] + (["pardiso"] if pardiso_available() else [])


def lower(A):
    return sp.tril(sp.csr_matrix(A)).tocsr()


def random_symmetric(n, eigenvalues, seed=0, density=None):
    rng = np.random.default_rng(seed)
    Q, _ = np.linalg.qr(rng.standard_normal((n, n)))
    return Q @ np.diag(eigenvalues) @ Q.T


def direct(method, A, singular=False):
    K = lower(A)
    return DirectSolver(method, K.shape[0], K.indptr, K.indices, regularize=singular), K


@pytest.mark.parametrize("method", DIRECT)
@pytest.mark.parametrize("n_negative", [0, 1, 3])
def test_inertia_counts_negative_eigenvalues(method, n_negative):
    ev = np.linspace(0.5, 4.0, 12)
    ev[:n_negative] *= -1
    A = random_symmetric(12, ev)
    solver, K = direct(method, A)
    assert solver.factorize(K) == n_negative
    assert solver.current_is_positive_definite() == (n_negative == 0)
    b = np.arange(12.0)
    # indefinite or not, solves are exact (Bunch-Kaufman / diagonal pivots)
    assert np.linalg.norm(A @ solver.solve(b) - b) <= 1e-10 * np.linalg.norm(b)


@pytest.mark.parametrize("method", DIRECT)
def test_lagged_factor_preconditions_an_indefinite_hessian(method):
    """After a positive definite Hessian, an indefinite one with the same
    pattern is factorized into the other slot: its inertia is reported, and
    the preconditioner stays the positive definite factor."""
    A = random_symmetric(10, np.linspace(1.0, 3.0, 10), seed=3)
    B = random_symmetric(10, np.r_[-1.0, np.linspace(1.0, 3.0, 9)], seed=4)
    solver, KA = direct(method, A)
    KB = lower(B)
    assert solver.factorize(KA) == 0
    assert solver.factorize(KB) == 1
    assert not solver.current_is_positive_definite()
    r = np.ones(10)
    np.testing.assert_allclose(solver.preconditioner()(r), np.linalg.solve(A, r), rtol=1e-10)
    np.testing.assert_allclose(solver.solve(r), np.linalg.solve(B, r), rtol=1e-9)
    assert solver.factorize(KA) == 0 and solver.current_is_positive_definite()


@pytest.mark.parametrize("method", DIRECT)
def test_singular_hessian_factorizes_and_counts_no_negative(method):
    """A free chain of springs (exact null mode): the regularized
    factorization of K + 1e-10 max|diag| I exists and is positive definite;
    CG with it solves consistent right-hand sides."""
    w = np.arange(1.0, 10.0)
    A = np.zeros((10, 10))
    for i, wi in enumerate(w):
        A[np.ix_([i, i + 1], [i, i + 1])] += wi * np.array([[1.0, -1.0], [-1.0, 1.0]])
    solver, K = direct(method, A, singular=True)
    assert solver.factorize(K) == 0
    b = np.random.default_rng(4).standard_normal(10)
    b -= b.mean()
    null = np.ones((10, 1)) / np.sqrt(10)
    p, info = steihaug_cg(lower_matvec(K), -b, solver.preconditioner(), rtol=1e-12,
                          project=projector(null))
    assert np.linalg.norm(A @ p - b) <= 1e-9 * np.linalg.norm(b)
    # the factor is that of K + d I (up to the round-off amplified along the null mode)
    Areg = A + REGULARIZATION * np.abs(np.diag(A)).max() * np.eye(10)
    P = projector(null)
    np.testing.assert_allclose(P(solver.preconditioner()(b)), P(np.linalg.solve(Areg, b)), rtol=1e-8)


needs_pardiso = pytest.mark.skipif(not pardiso_available(), reason="pypardiso not installed")


@needs_pardiso
def test_pardiso_slots_share_one_analysis(monkeypatch):
    """Both PARDISO slots are factors of one handle: the ordering and
    symbolic analysis (phase 11) run once for the pattern, each Hessian is a
    numeric factorization (phase 22) of its slot's matrix number, and a
    slot's factor survives the other slot's factorizations."""
    from shellritz import linalg
    phases = []
    call = linalg._PardisoHandle.call
    monkeypatch.setattr(linalg._PardisoHandle, "call",
                        lambda self, phase, mnum, data, b: (phases.append((phase, mnum)),
                                                            call(self, phase, mnum, data, b))[1])
    A = random_symmetric(10, np.linspace(1.0, 3.0, 10), seed=3)
    B = random_symmetric(10, np.r_[-2.0, -1.0, np.linspace(1.0, 3.0, 8)], seed=5)
    solver, KA = direct("pardiso", A)
    assert solver.factorize(KA) == 0 and solver.factorize(lower(B)) == 2
    assert solver.factorize(lower(B)) == 2
    assert [p for p in phases if p[0] != 33] == [(11, 1), (22, 1), (22, 2), (22, 2)]
    r = np.ones(10)
    np.testing.assert_allclose(solver.preconditioner()(r), np.linalg.solve(A, r), rtol=1e-10)
    np.testing.assert_allclose(solver.solve(r), np.linalg.solve(B, r), rtol=1e-9)
    solver.release()
    assert phases[-1] == (-1, 1) and not solver._slots[0].handle.analysed


@needs_pardiso
@pytest.mark.parametrize("n_negative", [0, 2])
def test_single_precision_factor_refined_solves_and_double_inertia(n_negative):
    """factor_precision 'single': the factor is single precision (one
    triangular solve leaves a residual far above double round-off: 1e-9 to
    1e-6 here, condition number 1e3), its inertia is right where the
    eigenvalues are well away from zero, the refined solves reach 1e-12, CG
    preconditioned by it reaches 1e-10 in a few iterations, and the inertia
    asked for exactly comes from a double factorization (a third slot)."""
    ev = np.geomspace(1e-3, 1.0, 40)
    ev[:n_negative] *= -1
    A = random_symmetric(40, ev, seed=7)
    K = lower(A)
    solver = DirectSolver("pardiso", 40, K.indptr, K.indices, single=True)
    assert solver.factorize(K) == n_negative
    b = np.random.default_rng(1).standard_normal(40)
    once = solver._slots[solver._current].solve(b)
    assert np.linalg.norm(A @ once - b) > 1e-9 * np.linalg.norm(b)
    assert np.linalg.norm(A @ solver.solve(b) - b) <= 1e-12 * np.linalg.norm(b)
    if n_negative == 0:
        p, info = steihaug_cg(lower_matvec(K), -b, solver.preconditioner(), rtol=1e-10)
        assert info["reason"] == "converged" and info["iterations"] <= 4
    assert solver.factorize(K, exact_inertia=True) == n_negative
    assert len(solver._slots) == 3 and solver._current == 2
    assert np.linalg.norm(A @ solver._slots[2].solve(b) - b) <= 1e-12 * np.linalg.norm(b)
    solver.release()


def test_factor_precision_choice_and_errors():
    A = random_symmetric(12, np.linspace(1.0, 2.0, 12))
    K = lower(A)
    make = lambda method, precision: make_linear_solver(method, 12, K.indptr, K.indices,
                                                        precision=precision)
    assert not make("superlu", "double").single
    with pytest.raises(LinearSolverError, match="single-precision factorization needs 'pardiso'"):
        make("superlu", "single")
    with pytest.raises(ValueError, match="choose one of double, single"):
        make("superlu", "half")
    if pardiso_available():
        assert make("pardiso", "single").single and not make("pardiso", "double").single


def test_symmetric_from_lower():
    A = random_symmetric(7, np.arange(1.0, 8.0))
    np.testing.assert_array_equal(symmetric_from_lower(lower(A)).toarray(), np.tril(A) + np.tril(A, -1).T)
    P = np.random.default_rng(0).standard_normal((7, 3))
    np.testing.assert_allclose(lower_matvec(lower(A))(P), A @ P, rtol=1e-13, atol=1e-13)


def test_cg_with_the_exact_factor_is_newton_in_one_iteration():
    A = random_symmetric(30, np.linspace(0.1, 10, 30), seed=1)
    g = np.arange(30.0)
    p, info = steihaug_cg(lambda v: A @ v, g, lambda r: np.linalg.solve(A, r))
    assert info["iterations"] == 1 and info["reason"] == "converged"
    np.testing.assert_allclose(p, -np.linalg.solve(A, g), rtol=1e-12)
    assert info["norm_M"] == pytest.approx(np.sqrt(p @ A @ p), rel=1e-12)


def test_cg_respects_the_trust_region_in_the_preconditioner_norm():
    A = random_symmetric(40, np.linspace(0.01, 10, 40), seed=2)
    D = np.diag(np.linspace(1.0, 3.0, 40))                # M = D
    g = np.ones(40)
    full, _ = steihaug_cg(lambda v: A @ v, g, lambda r: np.linalg.solve(D, r), rtol=1e-12, maxiter=200)
    radius = 0.3 * np.sqrt(full @ D @ full)
    p, info = steihaug_cg(lambda v: A @ v, g, lambda r: np.linalg.solve(D, r), radius)
    assert info["reason"] == "boundary"
    assert np.sqrt(p @ D @ p) == pytest.approx(radius, rel=1e-10)
    assert info["norm_M"] == pytest.approx(radius, rel=1e-12)
    # the model decreases at least as much as at the Cauchy point
    model = lambda q: g @ q + 0.5 * q @ A @ q
    Mg = np.linalg.solve(D, g)
    tc = min(radius / np.sqrt(Mg @ D @ Mg), (g @ Mg) / (Mg @ A @ Mg))
    assert model(p) <= model(-tc * Mg) + 1e-14


def test_cg_follows_negative_curvature_to_the_boundary():
    ev = np.r_[-2.0, np.linspace(1.0, 4.0, 19)]
    A = random_symmetric(20, ev, seed=5)
    w, V = np.linalg.eigh(A)
    g = V[:, 0] + 0.1 * np.random.default_rng(6).standard_normal(20)   # mostly along the negative mode
    p, info = steihaug_cg(lambda v: A @ v, g, lambda r: r, radius=1.5)
    assert info["reason"] == "negative curvature" and info["curvature"] < 0
    assert np.linalg.norm(p) == pytest.approx(1.5, rel=1e-10)
    assert g @ p + 0.5 * p @ A @ p < 0                    # the model decreases
    # without a region (line search) the direction is still a descent direction
    q, info = steihaug_cg(lambda v: A @ v, g, lambda r: r)
    assert g @ q < 0


@pytest.mark.parametrize("negative", [0, 2])
def test_recorded_cg_path_gives_the_step_at_a_smaller_radius(negative):
    """After a rejected trust-region step the model is the same: the steps
    at smaller radii come from the recorded CG path without iterations and
    equal those of new CG solves, on positive definite and indefinite K."""
    ev = np.r_[-np.linspace(1.0, 2.0, negative), np.linspace(0.01, 10, 40 - negative)]
    A = random_symmetric(40, ev, seed=7)
    D = np.diag(np.linspace(1.0, 3.0, 40))
    g = np.random.default_rng(8).standard_normal(40)
    solve = lambda r: np.linalg.solve(D, r)
    path = CGPath()
    p0, info0 = steihaug_cg(lambda v: A @ v, g, solve, 5.0, 1e-12, 200, None, path)
    assert info0["iterations"] == len(path.entries) >= 2
    radius = info0["norm_M"]
    for _ in range(4):                          # successive rejections: half the step each time
        radius *= 0.5
        p, info = path.step(radius)
        q, ref = steihaug_cg(lambda v: A @ v, g, solve, radius, 1e-12, 200)
        assert info["iterations"] == 0 and info["reason"] == ref["reason"]
        np.testing.assert_allclose(p, q, rtol=1e-12, atol=1e-14 * np.abs(q).max())
        assert np.sqrt(p @ D @ p) == pytest.approx(radius, rel=1e-10)
    # positive definite K solved inside the region: the whole path is inside
    # any radius that contains the Newton step, nothing to replay
    if negative == 0:
        path = CGPath()
        p0, info0 = steihaug_cg(lambda v: A @ v, g, solve, 1e6, 1e-12, 200, None, path)
        assert info0["reason"] == "converged"
        assert path.step(2 * info0["norm_M"]) is None


def test_indefinite_preconditioner_is_refused():
    A = np.eye(3)
    with pytest.raises(LinearSolverError, match="not positive definite"):
        steihaug_cg(lambda v: A @ v, np.ones(3), lambda r: -r)


def test_method_names_and_availability():
    assert resolve_method("superlu", 10) == "superlu"
    assert resolve_method("auto", 10) in ("pardiso", "superlu")
    with pytest.raises(ValueError, match="unknown linear solver 'mumps': choose one of " + ", ".join(METHODS)):
        resolve_method("mumps", 10)
    with pytest.raises(LinearSolverError, match="needs the nodal block structure"):
        resolve_method("amg", 10, has_blocks=False)


def _plate(n=8):
    mesh = shapes.rectangle(n, n)
    s = Shell(mesh, 0.05, NeoHookean(1.0, nu=0.3))
    s.clamp(mesh.nodes_where(lambda X: X[:, 0] < 1e-9))
    s._setup()
    s.set_parameter(0.0)
    return s


def test_rigid_modes_free_only_where_no_support():
    """A clamped plate has no free rigid motion; a free one has six, and
    they are null vectors of its Hessian (positions and tangent derivatives
    rotate together)."""
    s = _plate()
    assert free_rigid_modes(s.block_layout()) is None
    mesh = shapes.rectangle(6, 6)
    f = Shell(mesh, 0.05, NeoHookean(1.0, nu=0.3))
    f._setup()
    f.set_parameter(0.0)
    Q = free_rigid_modes(f.block_layout())
    assert Q.shape == (9 * mesh.n_nodes, 6)
    _, _, K = f.evaluate(f.free_state(), 2)
    KQ = lower_matvec(K)(Q)
    assert np.abs(KQ).max() <= 1e-12 * np.abs(K.diagonal()).max()
    v = np.random.default_rng(0).standard_normal(Q.shape[0])
    assert np.abs(Q.T @ projector(Q)(v)).max() <= 1e-12


def test_near_null_space_has_the_strain_gradient_terms_zero_modes():
    """Where the strain-gradient term is on (elements shorter than h) the
    AMG near null space adds homogeneous strains S c and quadratic
    displacements to the rigid and bending modes: on a flat free plate
    they are null vectors of the term's Hessian (R = C |grad grad eps|^2
    vanishes for linear strain), while a cubic in-plane displacement is
    not; without the term they are not added.  On the plate the bending
    modes and strains that involve its normal coordinate are zero or rigid
    rotations and are left out: 9 vectors without the term (6 rigid, 3
    bending), 18 with it (6 rigid, 3 bending, 3 strains, 6 in-plane
    quadratic displacements), all independent."""
    from shellritz import StVenantKirchhoff
    from shellritz.shell import _near_null_candidates
    mesh = shapes.rectangle(8, 8)
    plain = Shell(mesh, 0.05, NeoHookean(1.0, nu=0.3))
    thick = Shell(mesh, 0.3, StVenantKirchhoff.from_young(1.0, 0.3))
    assert plain.strain_gradient is None and thick.strain_gradient is not None
    for s in (plain, thick):
        s._setup()
        s.set_parameter(0.0)
    assert plain.block_layout()[4]().shape[1] == 9
    B = thick.block_layout()[4]()
    assert B.shape[1] == 18 and np.linalg.matrix_rank(B) == 18
    # the candidates kept: c_x^2, c_y^2, c_x c_y (bending, strains), and those of
    # the quadratic displacements along e_x, e_y
    kept = [0, 1, 2, 3, 4, 5, 6, 7, 9, 12, 13, 15, 18, 19, 21, 22, 27, 28]
    assert np.array_equal(B, _near_null_candidates(thick.U, kept).reshape(B.shape))
    x = thick.free_state()
    U = thick.U.copy()
    data = np.zeros(thick._nnz)              # the term's Hessian alone, in K's pattern
    thick.strain_gradient.add(2, thick, U, np.zeros_like(thick._Le), np.zeros_like(thick._G), data)
    K = sp.csr_matrix((data, thick._indices, thick._indptr), shape=(len(x), len(x)))
    KB = lower_matvec(K)(B)
    scale = np.abs(K).max() * np.linalg.norm(B, axis=0)
    assert np.all(np.linalg.norm(KB[:, 6:], axis=0) <= 1e-10 * scale[6:])
    # a strain curving in the plane is seen: u = c_x^3 e_x (c: the nodes / size)
    r, a1, a2 = thick.U[:, 0], thick.U[:, 1], thick.U[:, 2]
    size = np.abs(r - r.mean(axis=0)).max()
    cx = (r[:, 0] - r[:, 0].mean()) / size
    V = np.zeros((mesh.n_nodes, 3, 3))
    V[:, 0, 0] = cx ** 3
    V[:, 1, 0] = 3 * cx ** 2 * a1[:, 0] / size
    V[:, 2, 0] = 3 * cx ** 2 * a2[:, 0] / size
    v = V.reshape(-1)
    assert np.linalg.norm(lower_matvec(K)(v)) > 1e-5 * np.abs(K).max() * np.linalg.norm(v)     # observed 3e-4


def test_independent_near_null_columns():
    """_independent_columns keeps a column only where its part orthogonal
    to the kept ones is above NEAR_NULL_DEPENDENT of the largest column:
    a multiple of a kept column, a zero column, one at round-off scale and
    a non-finite one are left out."""
    from shellritz.shell import _independent_columns
    rng = np.random.default_rng(0)
    M = rng.standard_normal((60, 7))
    M[:, 2] = np.nan
    M[:, 3] = 2 * M[:, 0] - M[:, 1]
    M[:, 4] = 0.0
    M[:, 5] = 1e-12 * rng.standard_normal(60)
    assert _independent_columns(M).tolist() == [0, 1, 6]


def test_near_null_space_on_a_curved_shell_keeps_the_strains(monkeypatch):
    """On a curved shell (a cylinder with elements shorter than h) no
    candidate depends on the others: the near null space is the rigid
    modes, the six bending modes and the six homogeneous strains, as
    before the quadratic displacements were candidates.  The dependencies
    are found on a sample of nodes (NEAR_NULL_SAMPLE): on a plate a sample
    of 40 of its 81 nodes finds the same nine vectors as all of them."""
    import shellritz.shell as shell_module
    from shellritz.shell import _near_null_candidates
    mesh = shapes.cylinder(32, 10, radius=1.0, length=1.0)
    s = Shell(mesh, 0.3, NeoHookean(1.0, nu=0.3))
    assert s.strain_gradient is not None
    s._setup()
    s.set_parameter(0.0)
    B = s.block_layout()[4]()
    assert np.array_equal(B, _near_null_candidates(s.U, np.arange(18)).reshape(B.shape))
    plate = Shell(shapes.rectangle(8, 8), 0.05, NeoHookean(1.0, nu=0.3))
    plate._setup()
    plate.set_parameter(0.0)
    whole = plate.block_layout()[4]()
    monkeypatch.setattr(shell_module, "NEAR_NULL_SAMPLE", 40)
    assert np.array_equal(plate.block_layout()[4](), whole) and whole.shape[1] == 9


@pytest.mark.parametrize("levels", ["one", "several"])
def test_amg_preconditions_a_plate_hessian(levels, monkeypatch):
    """pyamg smoothed aggregation (9x9 blocks, rigid near null space) as the
    CG preconditioner of a clamped plate Hessian: converges to 1e-8 in far
    fewer iterations than Jacobi (observed at 16 x 16: 1 with one level, the
    default at this size, where the coarse solver factorizes the Hessian;
    16 with the coarsening forced to three levels; Jacobi 400+)."""
    import shellritz.linalg as linalg
    if levels == "several":
        monkeypatch.setattr(linalg, "AMG_ONE_LEVEL_BLOCKS", 0)
        monkeypatch.setattr(linalg, "AMG_COARSE_BLOCKS", 10)
    s = _plate(16)
    _, g, K = s.evaluate(s.free_state(), 2)
    b = np.random.default_rng(1).standard_normal(K.shape[0])
    amg = make_linear_solver("amg", K.shape[0], K.indptr, K.indices, s.block_layout())
    amg.factorize(K)
    assert (len(amg._ml.levels) == 1) == (levels == "one")
    A = symmetric_from_lower(K)
    p, info = steihaug_cg(lower_matvec(K), -b, amg.preconditioner(), rtol=1e-8, maxiter=200)
    assert info["reason"] == "converged"
    assert np.linalg.norm(A @ p - b) <= 1e-7 * np.linalg.norm(b)
    _, jac = steihaug_cg(lower_matvec(K), -b, lambda r: r / np.abs(A.diagonal()), rtol=1e-8, maxiter=400)
    assert info["iterations"] < 40 < jac["iterations"]


def test_amg_hierarchy_stops_at_the_level_cap(monkeypatch):
    """The coarsening stops at AMG_MAX_LEVELS even where AMG_COARSE_BLOCKS
    is not reached (a fourth level made the W-cycle much weaker: 269 against
    75 CG iterations on the 100k-triangle thin leaf, bench/amg_growth.py),
    and the capped hierarchy still preconditions CG to 1e-8.  The 24 x 24
    plate coarsened to 2 blocks would have more levels without the cap."""
    import shellritz.linalg as linalg
    monkeypatch.setattr(linalg, "AMG_ONE_LEVEL_BLOCKS", 0)
    monkeypatch.setattr(linalg, "AMG_COARSE_BLOCKS", 2)
    s = _plate(24)
    K = s.evaluate(s.free_state(), 2)[2]
    cap = linalg.AMG_MAX_LEVELS
    levels = {}
    for limit in (10, cap):                        # the capped (default) hierarchy last
        monkeypatch.setattr(linalg, "AMG_MAX_LEVELS", limit)
        amg = make_linear_solver("amg", K.shape[0], K.indptr, K.indices, s.block_layout())
        amg.factorize(K)
        levels[limit] = len(amg._ml.levels)
    assert levels[10] > cap and levels[cap] == cap
    b = np.random.default_rng(1).standard_normal(K.shape[0])
    p, info = steihaug_cg(lower_matvec(K), -b, amg.preconditioner(), rtol=1e-8, maxiter=200)
    assert info["reason"] == "converged"


def test_amg_embedding_is_the_symmetric_hessian_in_nodal_blocks():
    """AMGSolver._embed writes the full symmetric matrix of the lower
    triangle straight into 9 x 9 nodal blocks of the full numbering, the
    fixed DOFs with the median |diagonal| as an identity row; equal to the
    dense construction entry by entry."""
    from shellritz.linalg import AMGSolver, BlockLayout
    rng = np.random.default_rng(3)
    nodes, b = 7, 9
    n_full = nodes * b
    fixed = np.zeros(n_full, bool)
    fixed[[0, 1, 2, 20, 40, 41]] = True           # some DOFs of nodes 0, 2 and 4
    free = np.flatnonzero(~fixed)
    links = {(i, i) for i in range(nodes)} | {(1, 0), (3, 1), (4, 2), (6, 0), (6, 5), (5, 3)}
    D = np.zeros((n_full, n_full))
    for i, j in links:
        D[i * b:(i + 1) * b, j * b:(j + 1) * b] = rng.standard_normal((b, b))
    D = D + D.T
    F = D[np.ix_(free, free)]
    K = sp.csr_matrix(np.tril(F))
    solver = AMGSolver(len(free), BlockLayout(b, free, n_full, None, None))
    A = solver._embed(K)
    assert A.blocksize == (b, b)
    d = np.abs(np.diag(F))
    expected = np.zeros((n_full, n_full))
    expected[np.ix_(free, free)] = F
    expected[fixed, fixed] = np.median(d[d > 0])
    assert np.array_equal(A.toarray(), expected)


@pytest.mark.parametrize("room", [True, False])
def test_amg_rebuild_keeps_one_previous_hierarchy_where_two_fit(room, monkeypatch):
    """A rebuild of the AMG hierarchy keeps the one it replaces as the
    fallback (restore_previous) -- and only that one -- where memory holds
    both; where it does not (the 1M-triangle leaf: 8.5 GB per hierarchy) the
    current one is released before the new one is built, said in
    ``released_previous``, and there is nothing to restore."""
    import shellritz.linalg as linalg
    monkeypatch.setattr(linalg, "_available_memory", lambda: float("inf") if room else 0)
    s = _plate(8)
    _, _, K = s.evaluate(s.free_state(), 2)
    amg = make_linear_solver("amg", K.shape[0], K.indptr, K.indices, s.block_layout())
    amg.factorize(K)
    first = amg._ml
    assert linalg._hierarchy_bytes(first) >= K.data.nbytes      # holds at least the Hessian
    amg.note_iterations(5, "converged")
    assert amg.note_iterations(5 * amg.rebuild_growth + 6, "converged") > 0     # slowed down: rebuilt
    assert amg.builds == 2 and amg._ml is not first
    assert amg.released_previous == (not room)
    assert (amg._previous is first) == room
    amg.note_iterations(5, "converged")
    amg.note_iterations(5 * amg.rebuild_growth + 6, "converged")       # a third build drops the first
    assert amg._previous is not first
    assert amg.restore_previous() == room


def test_amg_rebuild_counts_iterations_per_decade_of_the_forcing_tolerance():
    """The rebuild test compares CG iterations per decade of residual
    reduction: a solve to 1e-3 taking three times the iterations of the
    first to 0.1 keeps the hierarchy, the same count to 0.1 rebuilds it; a
    solve stopped on the trust-region boundary counts as one decade."""
    s = _plate(8)
    _, _, K = s.evaluate(s.free_state(), 2)
    amg = make_linear_solver("amg", K.shape[0], K.indptr, K.indices, s.block_layout())
    amg.factorize(K)
    slow = int(5 * amg.rebuild_growth + 6)
    amg.note_iterations(5, "converged", 0.1)
    assert amg.note_iterations(slow, "converged", 1e-3) == 0.0 and amg.builds == 1
    assert amg.note_iterations(slow, "boundary", 1e-3) > 0 and amg.builds == 2
    amg.note_iterations(5, "converged", 0.1)
    assert amg.note_iterations(slow, "converged", 0.1) > 0 and amg.builds == 3
    amg.release()


@pytest.mark.parametrize("room", [True, False])
def test_amg_keeps_the_rigid_and_bending_vectors_where_memory_is_short(room, monkeypatch):
    """With the strain-gradient term on (elements shorter than h) the near
    null space has 18 vectors, rigid and bending modes first (the same as
    without the term), then strains and quadratic displacements; where the
    hierarchy would not leave room for the Newton iteration
    (_hierarchy_need) AMG builds on the first twelve: coarse blocks of 12
    instead of 18, said in its note and in the solve's history."""
    import shellritz.linalg as linalg
    from shellritz.solve import _Linear
    monkeypatch.setattr(linalg, "AMG_ONE_LEVEL_BLOCKS", 0)
    monkeypatch.setattr(linalg, "AMG_COARSE_BLOCKS", 10)
    monkeypatch.setattr(linalg, "_available_memory", lambda: float("inf") if room else 0)
    mesh = shapes.rectangle(12, 12)
    layouts = []
    for h in (0.3, 0.001):
        s = Shell(mesh, h, NeoHookean(1.0, nu=0.3))
        s.clamp(mesh.nodes_where(lambda X: X[:, 0] < 1e-9))
        s._setup()
        s.set_parameter(0.0)
        layouts.append(s.block_layout()[4]())
        if h == 0.3:
            assert s.strain_gradient is not None
            shell = s
    assert layouts[0].shape[1] == 18 and layouts[1].shape[1] == 9     # on the plate: 3 bending modes
    assert np.array_equal(layouts[0][:, :9], layouts[1])
    K = shell.evaluate(shell.free_state(), 2)[2]
    amg = make_linear_solver("amg", K.shape[0], K.indptr, K.indices, shell.block_layout())
    amg.factorize(K)
    assert (amg.note is not None) == (not room)
    assert amg._ml.levels[0].P.blocksize == (9, 18 if room else 12)
    amg.release()
    history = types.SimpleNamespace(notes=[], factorizations=0, linear=None)
    opts = types.SimpleNamespace(linear="amg", factor_precision="double", verbose=False)
    lin = _Linear(shell, opts, history)
    lin.factorize(K)
    assert any("near-null vectors only" in n for n in history.notes) == (not room)
    lin.release()


def test_amg_restriction_is_p_transposed_without_a_copy_and_coarse_solve_is_direct(monkeypatch):
    """The hierarchy's restrictions are P^T applied on P's own storage (no
    second copy of P: 0.75 GB at the 199k-triangle leaf), equal to SciPy's
    P^T x; the coarsest level is solved by one factorization of the direct
    solver (PARDISO where present), made at the first cycle, equal to a
    dense solve, with zero rows (a dependent near-null vector) on a unit
    diagonal; release frees it."""
    import shellritz.linalg as linalg
    monkeypatch.setattr(linalg, "AMG_ONE_LEVEL_BLOCKS", 0)
    monkeypatch.setattr(linalg, "AMG_COARSE_BLOCKS", 10)
    s = _plate(16)
    K = s.evaluate(s.free_state(), 2)[2]
    # a near null space with a dependent vector (the plate's own has none),
    # whose zero columns of P make zero rows of the coarse levels
    layout = s.block_layout()
    dependent = lambda: np.hstack([layout.near_null(), layout.near_null()[:, -1:]])
    amg = make_linear_solver("amg", K.shape[0], K.indptr, K.indices, layout._replace(near_null=dependent))
    amg.factorize(K)
    ml = amg._ml
    assert len(ml.levels) == 3
    rng = np.random.default_rng(4)
    for level in ml.levels[:-1]:
        assert not sp.issparse(level.R)
        x = rng.standard_normal(level.P.shape[0])
        P = level.P.tobsr()
        assert np.allclose(level.R @ x, P.T @ x, rtol=1e-14, atol=1e-14 * np.abs(x).sum())
        y = rng.standard_normal(level.P.shape[1])
        assert np.allclose(level.P @ y, P @ y, rtol=1e-14, atol=1e-14 * np.abs(y).sum())
    amg.preconditioner()(rng.standard_normal(K.shape[0]))
    coarse = ml.coarse_direct
    A = ml.levels[-1].A
    assert coarse._A is A and coarse._solver.name == resolve_method("auto", 0)
    # the coarsest level has zero rows (the dependent vector): solved on a
    # unit diagonal
    D = A.toarray()
    empty = ~D.any(axis=1)
    assert 0 < empty.sum() < len(D) // 2
    b = rng.standard_normal(A.shape[0])
    x = coarse(A, b)
    assert np.array_equal(x[empty], b[empty])
    b[empty] = 0.0
    exact = np.zeros_like(b)
    exact[~empty] = np.linalg.solve(D[np.ix_(~empty, ~empty)], b[~empty])
    # relative error: the regularization (1e-10 of the largest pivot) times
    # the condition number (4e4 here), one refinement step: observed 1.9e-7
    assert np.linalg.norm(coarse(A, b) - exact) <= 1e-5 * np.linalg.norm(exact)
    amg.release()
    assert coarse._solver is None


def test_prolongation_smoothing_is_block_jacobi_with_the_spectral_radius_of_its_operator():
    """The prolongation smoother P = T - (omega / rho) D^-1 A T with D the
    nodal block diagonal of A: S = D^-1/2 by blocks (S D S = I), rho the
    spectral radius of D^-1 A (Lanczos on S A S) within 1e-2 of the dense
    eigenvalues' on a plate's AMG operator (a Ritz value: from below), and
    P equal to the dense formula; a block with a zero and a negative
    eigenvalue is inverted on its positive part only."""
    import shellritz.linalg as linalg
    s = _plate(16)
    K = s.evaluate(s.free_state(), 2)[2]
    amg = make_linear_solver("amg", K.shape[0], K.indptr, K.indices, s.block_layout())
    A = amg._embed(K)
    S = linalg._block_inverse_sqrt(A)
    dense_A = A.toarray()
    blocks = [dense_A[9 * i:9 * i + 9, 9 * i:9 * i + 9] for i in range(A.shape[0] // 9)]
    for Si, Di in zip(S, blocks):
        assert np.allclose(Si @ Di @ Si, np.eye(9), atol=1e-10)
    Dinv = sp.block_diag([Si @ Si for Si in S]).toarray()
    exact = np.abs(np.linalg.eigvals(Dinv @ dense_A)).max()
    rho = linalg._spectral_radius(A, S)
    assert exact * (1 - 1e-2) <= rho <= exact * (1 + 1e-12)
    T = sp.bsr_matrix(np.kron(np.eye(A.shape[0] // 9), np.ones((9, 1))), blocksize=(9, 1))
    P = linalg._smoothed_prolongator(A, T.copy(), 4 / 3)
    dense = T.toarray() - (4 / 3 / rho) * Dinv @ dense_A @ T.toarray()
    assert np.allclose(P.toarray(), dense, atol=1e-12 * np.abs(dense).max())
    # positive part only: diag(2, 0, -1) in a rotated basis -> 2^-1/2 on the first direction
    Q = np.linalg.qr(np.random.default_rng(0).standard_normal((3, 3)))[0]
    B = sp.bsr_matrix(Q @ np.diag([2.0, 0.0, -1.0]) @ Q.T, blocksize=(3, 3))
    assert np.allclose(linalg._block_inverse_sqrt(B)[0], np.outer(Q[:, 0], Q[:, 0]) / np.sqrt(2))
    # nothing to smooth with (a zero operator): rho = 0 and P = T, no NaN
    Z = A.copy()
    Z.data[:] = 0.0
    P = linalg._smoothed_prolongator(Z, T.copy(), 4 / 3)
    assert np.array_equal(P.toarray(), T.toarray())


def test_amg_setup_is_pyamgs_smoothed_aggregation_without_its_temporaries(monkeypatch):
    """linalg._smoothed_aggregation (own set-up loop: prolongation smoothing
    in place, the Galerkin product summed into its block pattern, P and the
    finest operator kept in single precision, smoothed by our block
    Gauss-Seidel) builds pyamg's hierarchy for the same settings: the
    stored prolongators and finest operator equal to their float32 rounding
    (relative 2^-24 per entry), each coarse operator the exact Galerkin
    product of the stored prolongator and the double operator (observed
    1.4e-15) and pyamg's to the rounding of P (observed 4e-8 of the largest
    entry, P of level 1 5e-8); as a preconditioner the same CG iterations."""
    import pyamg
    import pyamg.aggregation.smooth
    import shellritz.linalg as linalg
    # both with the exact spectral radius of D^-1 A (each estimates it its own way)
    monkeypatch.setattr(pyamg.aggregation.smooth, "approximate_spectral_radius",
                        lambda M: np.abs(np.linalg.eigvals(M.toarray())).max())
    monkeypatch.setattr(linalg, "_spectral_radius",
                        lambda M, S: np.abs(np.linalg.eigvals(
                            sp.block_diag([Si @ Si for Si in S]).toarray() @ M.toarray())).max())
    s = _plate(16)
    K = s.evaluate(s.free_state(), 2)[2]
    amg = make_linear_solver("amg", K.shape[0], K.indptr, K.indices, s.block_layout())
    A, B = amg._embed(K), amg.near_null()
    smoother = ("block_gauss_seidel", {"sweep": "symmetric", "iterations": linalg.AMG_SMOOTHER_SWEEPS})
    ref = pyamg.smoothed_aggregation_solver(
        A, B=B, symmetry="symmetric", strength=("symmetric", {"theta": linalg.AMG_STRENGTH_THETA}),
        improve_candidates=None, smooth=("jacobi", {"omega": 4 / 3, "weighting": "block"}),
        presmoother=smoother, postsmoother=smoother, max_coarse=10, max_levels=3, coarse_solver="splu")
    ours = linalg._smoothed_aggregation(A.copy(), B, "splu", linalg.AMG_STRENGTH_THETA, 4 / 3, 3, 10)
    assert len(ours.levels) == len(ref.levels) == 3

    def rounded(mine, theirs):
        return np.all(np.abs(mine - theirs) <= 2.0**-24 * np.abs(theirs) + 1e-13 * np.abs(theirs).max())
    assert ours.levels[0].A.data.dtype == np.float32 and ours.levels[1].A.dtype == np.float64
    assert rounded(ours.levels[0].A.tobsr().toarray(), ref.levels[0].A.toarray())
    # P before its rounding: our block inverses (eigh) and pyamg's (pinv)
    # agree to round-off times the blocks' condition (observed 8e-12 of the
    # largest entry), which the rounding to single precision may carry over
    # a rounding boundary: one unit more than the rounding alone
    P0, ref_P0 = ours.levels[0].P.tobsr().toarray(), ref.levels[0].P.toarray()
    assert np.all(np.abs(P0 - ref_P0) <= 2.0**-23 * np.abs(ref_P0) + 1e-10 * np.abs(ref_P0).max())
    A_fine = A.toarray()
    for k in range(2):
        P, theirs = ours.levels[k].P.tobsr().toarray(), ref.levels[k].P.toarray()
        # the rounding of P on level 0 reaches level 1's P through A_1
        assert np.abs(P - theirs).max() <= 5e-7 * np.abs(theirs).max()
        A_coarse = ours.levels[k + 1].A.toarray()
        galerkin = P.T @ A_fine @ P
        assert np.abs(A_coarse - galerkin).max() <= 1e-13 * np.abs(galerkin).max()
        assert np.abs(A_coarse - ref.levels[k + 1].A.toarray()).max() <= 5e-7 * np.abs(galerkin).max()
        A_fine = A_coarse
    # one W-cycle: the rounding of the finest operator reaches the lowest
    # modes (condition number 4e6 here), in the energy norm observed
    # 2.8e-5; as CG's preconditioner (to 1e-10) the same iteration count (19)
    r = np.random.default_rng(0).standard_normal(A.shape[0])

    def cycle(ml):
        return lambda v: ml.solve(v, x0=np.zeros_like(v), maxiter=1, cycle="W", tol=1e-30)
    w = [cycle(ml)(r) for ml in (ours, ref)]
    d = w[0] - w[1]
    assert np.sqrt(d @ (A @ d)) <= 1e-4 * np.sqrt(w[1] @ (A @ w[1]))
    its = []
    for ml in (ours, ref):
        count = []
        M = spla.LinearOperator(A.shape, matvec=cycle(ml))
        assert spla.cg(A, r, M=M, rtol=1e-10, maxiter=500, callback=lambda _: count.append(1))[1] == 0
        its.append(len(count))
    assert abs(its[0] - its[1]) <= 1


def test_amg_preconditioner_of_a_free_body_is_positive_definite(monkeypatch):
    """A free plate's Hessian is singular (six rigid modes); its hierarchy's
    coarsest factor is regularized, so a W-cycle is 1e10 times the
    identity on the rigid modes and positive definite only if every level
    a W-cycle visits twice holds the exact (double) operator its coarser
    levels were made from: r.M r > 0 for the rigid modes and random r
    (observed 5.2e9 and 1.3e10 to 3.7e10 here; with level 1 rounded to
    single precision -3.6e11 on a rigid mode)."""
    import shellritz.linalg as linalg
    monkeypatch.setattr(linalg, "AMG_ONE_LEVEL_BLOCKS", 0)
    monkeypatch.setattr(linalg, "AMG_COARSE_BLOCKS", 10)
    mesh = shapes.rectangle(24, 24)
    s = Shell(mesh, 0.3, NeoHookean(1.0, nu=0.3))      # strain-gradient term on: 18 near-null vectors
    s._setup()
    s.set_parameter(0.0)
    K = s.evaluate(s.free_state(), 2)[2]
    layout = s.block_layout()
    amg = make_linear_solver("amg", K.shape[0], K.indptr, K.indices, layout)
    amg.factorize(K)
    assert len(amg._ml.levels) == 3 and amg._ml.levels[0].P.blocksize == (9, 18)
    M = amg.preconditioner()
    Q = free_rigid_modes(layout)
    R = np.random.default_rng(0).standard_normal((5, K.shape[0]))
    assert Q.shape[1] == 6
    assert all(v @ M(v) > 0 for v in [*Q.T, *R])
    amg.release()


def test_multigrid_over_nested_meshes_where_elements_are_shorter_than_the_thickness(monkeypatch):
    """The leaf's reference stiffness on 16 rings at h/l = 7.3 (its
    strain-gradient term on: sixth order at the mesh scale), CG to 1e-8:
    the hierarchy over the discs of 8 and 4 rings (the prolongators of
    nested iteration, transfer.interpolation_jacobian, the finest one
    smoothed) takes at most 0.6 of the iterations of smoothed aggregation
    (observed 26 against 48 with its "VW" cycle, which on three levels is a
    V-cycle; 23 with W-cycles; on 45 rings 25 against 62, and 30 against
    107 at h/l = 14.6 with W-cycles: bench/amg_geometric.py); its levels
    are the meshes, the finest prolongator moves no fixed DOF, and the
    cycle is positive definite."""
    import shellritz.linalg as linalg
    from shellritz.scenes import leaf
    from shellritz.transfer import interpolation_jacobian
    monkeypatch.setattr(linalg, "AMG_ONE_LEVEL_BLOCKS", 0)
    monkeypatch.setattr(linalg, "AMG_COARSE_BLOCKS", 30)
    shells = [leaf(rings, thickness=7.3 / 16, membrane="dkt") for rings in (16, 8, 4)]
    for s in shells:
        s._setup()
        s.set_parameter(0.0)
    fine = shells[0]
    K = fine.evaluate(fine.free_state(), 2)[2]
    layout = fine.block_layout()
    nested = layout._replace(prolongators=tuple(interpolation_jacobian(c, c.U, f)
                                                for f, c in zip(shells, shells[1:])))
    b = np.random.default_rng(0).standard_normal(K.shape[0])
    its = {}
    for name, lay in (("aggregation", layout), ("nested", nested)):
        amg = make_linear_solver("amg", K.shape[0], K.indptr, K.indices, lay)
        amg.factorize(K)
        _, info = steihaug_cg(lower_matvec(K), -b, amg.preconditioner(), rtol=1e-8, maxiter=300)
        assert info["reason"] == "converged"
        its[name] = info["iterations"]
    levels = amg._ml.levels
    assert [lv.A.shape[0] for lv in levels] == [9 * s.mesh.n_nodes for s in shells]
    assert amg.note.startswith("multigrid over the 2 coarser meshes")
    fixed = np.ones(layout.n_full, bool)
    fixed[layout.free] = False
    assert fixed.any() and not np.any(levels[0].P @ np.ones(levels[0].P.shape[1]) * fixed)
    M = amg.preconditioner()
    assert all(v @ M(v) > 0 for v in np.random.default_rng(1).standard_normal((5, K.shape[0])))
    assert its["nested"] <= 0.6 * its["aggregation"]


def _four_level_plate(monkeypatch):
    """The 24 x 24 plate's Hessian and an AMG solver whose smoothed
    aggregation has four levels (at most 2 blocks on the coarsest)."""
    import shellritz.linalg as linalg
    monkeypatch.setattr(linalg, "AMG_ONE_LEVEL_BLOCKS", 0)
    monkeypatch.setattr(linalg, "AMG_COARSE_BLOCKS", 2)
    monkeypatch.setattr(linalg, "AMG_MAX_LEVELS", 4)
    s = _plate(24)
    K = s.evaluate(s.free_state(), 2)[2]
    amg = make_linear_solver("amg", K.shape[0], K.indptr, K.indices, s.block_layout())
    amg.factorize(K)
    assert len(amg._ml.levels) == 4
    return K, amg


def test_cycle_is_pyamgs_w_and_v_cycle(monkeypatch):
    """linalg._cycle visiting every coarser level twice (once) is one of
    pyamg's W-cycles (V-cycles) from zero, to rounding (observed 1e-16
    relative), on a four-level hierarchy; "VW" (the second level once, the
    third twice) is neither."""
    import shellritz.linalg as linalg
    K, amg = _four_level_plate(monkeypatch)
    ml = amg._ml
    b = np.random.default_rng(2).standard_normal(ml.levels[0].A.shape[0])
    ours = {}
    for name, visits in linalg.CYCLES.items():
        ml.visits = visits
        x = np.zeros_like(b)
        linalg._cycle(ml, 0, x, b)
        ours[name] = x
        if name in ("W", "V"):
            theirs = ml.solve(b, x0=np.zeros_like(b), tol=1e-30, maxiter=1, cycle=name)
            assert np.linalg.norm(x - theirs) <= 1e-12 * np.linalg.norm(theirs)
    for other in ("W", "V"):
        assert np.linalg.norm(ours["VW"] - ours[other]) > 1e-3 * np.linalg.norm(ours[other])
    amg.release()


@pytest.mark.parametrize("cycle", ["W", "V", "VW"])
def test_every_cycle_is_a_symmetric_positive_definite_preconditioner(cycle, monkeypatch):
    """For each cycle (AMG option ``cycle``) on a four-level hierarchy:
    v.M v > 0, CG with M converges to 1e-8, and u.M v = v.M u -- to 1e-10
    relative with the finest operator in double precision (observed 1e-12),
    to 1e-5 as built, the finest operator rounded to single precision while
    its smoother divides by the double diagonal blocks (observed 1e-6)."""
    import shellritz.linalg as linalg
    K, amg = _four_level_plate(monkeypatch)
    U = np.random.default_rng(3).standard_normal((4, K.shape[0]))
    smooth = linalg._smooth
    for in_double, tol in ((False, 1e-5), (True, 1e-10)):
        if in_double:            # no level rounded to single precision
            monkeypatch.setattr(linalg, "_smooth", lambda level, A, _: smooth(level, A, False))
        amg.release()
        amg.options = dict(cycle=cycle)
        amg.factorize(K)
        assert amg._ml.visits == {"W": (2, 2), "V": (1, 1), "VW": (1, 2)}[cycle]
        M = amg.preconditioner()
        for u, v in zip(U, U[1:]):
            assert abs(u @ M(v) - v @ M(u)) <= tol * abs(u @ M(v))
            assert v @ M(v) > 0
        _, info = steihaug_cg(lower_matvec(K), -U[0], M, rtol=1e-8, maxiter=300)
        assert info["reason"] == "converged"
    amg.release()


def test_block_gauss_seidel_is_pyamgs():
    """The smoother of every level but the coarsest (_block_gauss_seidel) does
    pyamg's symmetric block Gauss-Seidel sweeps: on a double-precision
    operator the same iterate to rounding (observed 1e-16 relative)."""
    import shellritz.linalg as linalg
    from pyamg.relaxation.relaxation import block_gauss_seidel
    from pyamg.util.utils import get_block_diag
    s = _plate(6)
    K = s.evaluate(s.free_state(), 2)[2]
    amg = make_linear_solver("amg", K.shape[0], K.indptr, K.indices, s.block_layout())
    A = amg._embed(K)
    rng = np.random.default_rng(1)
    b, x0 = rng.standard_normal(A.shape[0]), rng.standard_normal(A.shape[0])
    theirs, ours = x0.copy(), x0.copy()
    block_gauss_seidel(A, theirs, b, iterations=2, sweep="symmetric", blocksize=9)
    linalg._block_gauss_seidel(A.indptr, A.indices, A.data, get_block_diag(A, 9, inv_flag=True), ours, b, 2)
    assert not np.allclose(ours, x0)
    assert np.linalg.norm(ours - theirs) <= 1e-12 * np.linalg.norm(theirs)


def test_amg_options_are_checked():
    """An unknown AMG option is an error naming the known ones."""
    s = _plate(6)
    K = s.evaluate(s.free_state(), 2)[2]
    amg = make_linear_solver("amg", K.shape[0], K.indptr, K.indices, s.block_layout())
    with pytest.raises(ValueError, match="AMG options"):
        amg.options = dict(strength="classical")
        amg.factorize(K)
    with pytest.raises(ValueError, match="cycle='X'"):
        amg.options = dict(cycle="X")
        amg.factorize(K)


def test_cg_solves_the_model_projected_off_the_free_rigid_motions():
    """Away from equilibrium a free body's Hessian K is not zero along its
    rigid rotations Q (K Q != 0), so K p has a part along Q that no step
    orthogonal to Q can reduce: CG must take the residual of the projected
    model, P(-g - K p).  With the unprojected one it ran to maxiter (and
    then found r.M^-1 r at round-off, "not positive definite") on a buckled
    free disc.  Here K = A + (c q^T + q c^T), A SPD, q a unit vector."""
    rng = np.random.default_rng(1)
    n = 40
    B = rng.standard_normal((n, n))
    A = B @ B.T / n + np.eye(n)
    q = np.zeros(n)
    q[0] = 1.0
    c = rng.standard_normal(n)
    K = A + np.outer(c, q) + np.outer(q, c)
    Q = q[:, None]
    project = lambda v: v - Q @ (Q.T @ v)
    g = project(rng.standard_normal(n))
    p, info = steihaug_cg(lambda v: K @ v, g, lambda r: np.linalg.solve(A, r), rtol=1e-10,
                          maxiter=100, project=project)
    assert info["reason"] == "converged" and info["iterations"] < 40
    assert abs(q @ p) < 1e-14
    assert np.linalg.norm(project(K @ p + g)) <= 1e-10 * np.linalg.norm(g)
    # the projected model's minimizer (K restricted to the complement of q)
    exact = np.zeros(n)
    exact[1:] = np.linalg.solve(K[1:, 1:], -g[1:])
    assert np.allclose(p, exact, rtol=1e-8, atol=1e-12)


def test_upper_pattern_is_the_transpose_of_the_lower_one():
    """DirectSolver's PARDISO input (the upper triangle by rows, 1-based,
    each entry's position in the lower data, the diagonal's positions) equals
    SciPy's transpose of the lower pattern, rows sorted; a pattern without a
    diagonal entry is refused with its row."""
    from shellritz.linalg import _upper_of_lower
    n = 300
    A = sp.random(n, n, density=0.03, random_state=2, format="csr")
    L = sp.tril(A + A.T + sp.eye(n), format="csr")
    L.sort_indices()
    ia, ja, to_upper, diag = _upper_of_lower(L.indptr, L.indices, n)
    U = sp.csr_matrix((np.arange(L.nnz, dtype=np.float64), L.indices, L.indptr), shape=(n, n)).T.tocsr()
    U.sort_indices()
    assert np.array_equal(ia, U.indptr + 1) and np.array_equal(ja, U.indices + 1)
    assert np.array_equal(to_upper, U.data.astype(np.int64))
    rows = np.repeat(np.arange(n), np.diff(L.indptr))
    assert np.array_equal(diag, np.flatnonzero(rows == L.indices))
    M = L.tolil()
    M[17, 17] = 0.0
    M = sp.csr_matrix(M)
    M.eliminate_zeros()
    with pytest.raises(LinearSolverError, match="lacks the diagonal entry of 1 rows .first: row 17"):
        DirectSolver("superlu", n, M.indptr, M.indices)


def test_pardiso_values_are_the_shifted_upper_triangle():
    """The values handed to PARDISO (``_shifted_upper``, in place) are those
    of the upper triangle by rows of L + shift I, in double and, rounded
    once from the shifted double value, in single precision."""
    from shellritz.linalg import _shifted_upper, _upper_of_lower
    n = 200
    A = sp.random(n, n, density=0.05, random_state=3, format="csr")
    L = sp.tril(A + A.T + sp.eye(n), format="csr")
    L.sort_indices()
    ia, ja, to_upper, _ = _upper_of_lower(L.indptr, L.indices, n)
    shift = 0.3183098861837907
    U = (L + shift * sp.eye(n)).T.tocsr()
    U.sort_indices()
    for dtype in (np.float64, np.float32):
        out = np.full(L.nnz, np.nan, dtype)
        _shifted_upper(L.data, to_upper, ia, shift, out)
        assert np.array_equal(out, U.data.astype(dtype))
