"""Linear algebra of the Newton steps: one interface, several methods.

A Newton step of solve.py needs, for the Hessian K of the free DOFs (given as
its lower triangle, CSR, with a sparsity pattern fixed per mesh):

* a preconditioner ``M^-1`` that is symmetric positive definite, for the
  Steihaug-Toint conjugate gradients of the trust-region step and the
  truncated Newton-CG direction of the line search (:func:`steihaug_cg`);
  for a direct method and a positive definite K it is ``K^-1`` itself (one
  CG iteration gives the exact Newton step);
* the inertia of K (its number of negative eigenvalues) where the method can
  tell: that decides stability, and whether K itself can precondition;
* solves with K itself (indefinite allowed) for the bordered systems of arc
  length continuation and the tangent predictor.

Methods (``method=`` of :func:`make_linear_solver`):

``"pardiso"``  Intel MKL PARDISO (package pypardiso, x86-64): symmetric
    indefinite LDL^T with Bunch-Kaufman pivoting, METIS ordering and symbolic
    analysis once per sparsity pattern, only the numeric factorization per
    Newton step; the inertia is reported by the factorization.  With
    ``precision="single"`` the factors are single precision (half the
    factor memory; preconditioners of CG and refined solves, see
    :class:`DirectSolver`).
``"superlu"``  SciPy's SuperLU in symmetric mode (diagonal pivots, minimum
    degree ordering of A^T + A redone at every factorization); inertia from the
    pivot signs.  Slower (no reuse of the analysis), always available.
``"amg"``  pyamg smoothed aggregation on the 9 x 9 nodal blocks with the six
    rigid-body modes (positions and tangent derivatives) and six quadratic
    bending modes as near null space,
    as the preconditioner of the conjugate gradients; the hierarchy is kept
    across Newton steps and rebuilt when the Krylov iterations grow.  No
    inertia (stability by LOBPCG on request).
``"auto"``  ``"pardiso"`` where installed, else ``"superlu"``, up to
    :data:`AUTO_DIRECT_MAX_DOFS` free DOFs, ``"amg"`` above (measured
    crossover: bench/scaling.py, README "Solver").
"""

import os
import time
from typing import Callable, NamedTuple

import numba as nb
import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from .kernels.parallel import run_chunks

METHODS = ("auto", "pardiso", "superlu", "amg")

# Above this many free DOFs "auto" prefers AMG to a factorization (memory:
# PARDISO's analysis and one factor of the leaf Hessian take 3.8 KB per DOF
# at 56k DOFs and 8.8 at 226k (analysis 2.9, factor 5.9), and the solver
# keeps two factors; see README "Solver").
AUTO_DIRECT_MAX_DOFS = 600_000

# AMG: coarsening stops at this many block rows (pyamg counts blocks: the
# coarse levels have one 12 x 12 block per aggregate, the near-null space
# size), where the direct solver factorizes (_CoarseDirect; SuperLU when
# measured here); at most 3,000 DOFs.  Measured on the 50k leaf
# Hessian (226k DOFs, one CG solve to 1e-8, 2 threads): 3,000 blocks stopped
# at a dense 23,000-DOF level 1 whose SuperLU factor took 50 s and 0.6 GB
# (20 CG iterations); 250 blocks: three levels, a 576-DOF coarse solve, 77
# CG iterations with V-cycles, 56 with W-cycles (0.43 s each).  Prolongation
# smoothing: energy minimization of degree 2 (pyamg's choice for shells)
# 56 iterations, set-up 23 s; of degree 1: 43, 15.7 s; Jacobi: 71, 5.5 s,
# and the least memory: the set-up's temporaries beyond the Hessian peak at
# 0.46 GB against 0.95 (degree 1), which decides at 1M triangles (24 GB).
AMG_COARSE_BLOCKS = 250
# ... or after three levels, whichever comes first: a fourth level (from
# about 100k triangles on) made the W-cycle much weaker.  Measured on the
# leaf with h = 0.005, whose elements stay longer than h (bench/amg_growth.py,
# CG to 1e-8 on the Hessian at the solution): 80 / 78 iterations at 12k /
# 50k triangles (three levels each), 269 at 100k with four levels (163 s of
# CG), 75 with three (47.5 s; set-up 8.8 against 7.8 s).  The coarsest level
# grows with the mesh (about 10 % of the DOFs of the second: 26k at 199k
# triangles: the first W-cycle, which factorizes it, took 6.2 s with
# PARDISO against 33.6 s with SuperLU; a cycle 3 s).
AMG_MAX_LEVELS = 3
# memory: where the hierarchy with the whole near null space (18 vectors on
# the triangle engine with its strain-gradient term) would not leave room
# for the Newton iteration, only its first AMG_LEAN_NEAR_NULL vectors (rigid
# and bending modes) are used: the levels below the finest scale with the
# square of their number (18 -> 12: the first coarse operator 2.25 times
# smaller), at more CG iterations (100k leaf: 59 instead of 38 to 1e-8).
# The hierarchy beyond the finest operator A_0 (as embedded, in double) takes
# about AMG_P_SHARE (k/18) + AMG_COARSE_SHARE (k/18)^2 - 1/2 times A_0's
# bytes for k vectors (P_0 grows with k, the coarse levels with k^2; A_0
# is rounded to single precision: half of it comes back), the shares
# measured on the 1M-triangle leaf with 18 (2026-12-04: P_0 in single
# precision 0.33 A_0; the coarse operators -- A_1 0.88, P_1 0.10, A_2
# 0.14 -- and the coarsest factor 0.50: 1.62 A_0); the
# Newton iteration needs room for AMG_NEWTON_HESSIANS Hessians' values
# besides (the 1M leaf ran out of memory at its first Newton step with 18
# vectors and the levels in double: resident 12.4 GB after A_0, killed at
# 24.9 GB, at least 4.3 GB = 2 Hessians' values beyond the hierarchy; one
# more for margin).  Two are not enough: with them the 1M leaf (finest
# level in single precision) chose all 18 vectors and was killed at 22.8 GB
# resident in its first Newton step (2026-12-05), where with three it
# chose 12 and peaked at 17.6 GB (2026-12-04).
AMG_LEAN_NEAR_NULL = 12
AMG_P_SHARE = 0.33
AMG_COARSE_SHARE = 1.62
AMG_NEWTON_HESSIANS = 3
# strength of connection: a coupling between two nodes whose block is below
# this fraction of their diagonal blocks' (Frobenius norms) is weak and not
# aggregated along.  theta = 0 (every coupling strong) aggregated across the
# weak couplings of the strain-gradient term's edge jumps and of the
# tangent DOFs.  Measured on the leaf at the solution (bench/amg_growth.py,
# CG to 1e-8, three levels, 2026-12-04): h = 0.02 at 12k / 50k / 100k
# triangles 55 / 94 / 136 iterations with theta = 0, 32 / 40 / 59 with
# 0.05 (CG at 100k 70 s against 106 s: fewer but dearer iterations, the
# coarse levels being larger); h = 0.005 78 -> 42 at 50k.  On the same
# Hessians measured apart: 0.1 gave 29 / 30 / 54, and 0.2 did not converge
# in 1,000 iterations (50k, h = 0.02: too many nodes left out of every
# aggregate); 0.05 keeps away from that edge.
AMG_STRENGTH_THETA = 0.05
# pre- and post-smoother of every level but the coarsest: this many
# symmetric block Gauss-Seidel sweeps (forward, then backward; pyamg's
# "block_gauss_seidel", sweep "symmetric", iterations 2) with the level's
# nodal blocks (_smooth, _block_gauss_seidel; the finest level's operator
# in single precision)
AMG_SMOOTHER_SWEEPS = 2
# ... except that a Hessian of at most this many nodal blocks (27,000 DOFs
# of the triangle engine: sparse, cheap to factorize) is one level: the
# coarse solver's factor of the Hessian the hierarchy was built on, kept as
# the preconditioner until CG slows down (10-ring leaf of the stability map,
# trust region: 29 Newton and 227 CG iterations, 2.1 s; coarsened to three
# levels 560 Newton iterations: hierarchies rebuilt on its indefinite
# Hessians keep turning out not SPD).
AMG_ONE_LEVEL_BLOCKS = 3000
# multigrid over the nested meshes a solve started from (_geometric_hierarchy):
# the finest prolongator smoothed by one block Jacobi step, the coarser ones
# the plain interpolation; on the leaf's reference stiffness (CG to 1e-8,
# 12k triangles, bench/amg_geometric.py) 17 / 25 / 30 iterations at
# h/l = 3.6 / 7.3 / 14.6 (smoothed aggregation 25 / 62 / 107, the plain
# interpolation 32 / 78 / 122); every prolongator smoothed: the same
# iterations, but at 50k triangles and h/l = 14.6 31 against 47, for
# 1.2-1.35 times the operators' memory and 4-13 times the set-up
GEOMETRIC_SMOOTHED_LEVELS = 1
# the multigrid cycle (_cycle; AMG option ``cycle``): "W", every coarser
# level visited twice by its parent; "V", once; "VW", the second level once
# from the finest and the coarser ones twice.  Smoothed aggregation uses
# "W" (its coarser levels are small: V-cycles took 77 CG iterations where
# W-cycles took 56, above); multigrid over nested meshes "VW": its second
# operator has as many blocks as the finest (the smoothed finest
# prolongator has about 10 blocks per row; 50k leaf 328k against 323k), so
# that visiting it twice makes a cycle 1.5-1.7 times as dear.  Measured on
# the leaf's reference stiffness (bench/amg_cycle.py, CG to 1e-8, 2 threads;
# iterations W / V / VW): 50k triangles, h/l = 3.6: 18 / 19 / 19, 7.3:
# 26 / 35 / 30; 100k, 3.6: 19 / 20 / 19, 7.3: 27 / 36 / 31; CG time of VW
# 0.65-0.75 of W's, of V 0.62-0.83 (V loses where h/l is large).
CYCLES = {"W": (2, 2), "V": (1, 1), "VW": (1, 2)}   # visits of the second level, of the coarser ones
NESTED_CYCLE = "VW"
SA_CYCLE = "W"
# the CG iterations a rebuild of the hierarchy is measured against are at
# least these (AMGSolver.note_iterations: a first solve cut on the
# trust-region boundary after one iteration would make any later one of 8
# rebuild; not counting boundary solves at all made the thin panel of the
# stability map take 461 instead of 365 Newton iterations).  A rebuild with
# Jacobi prolongation smoothing costs about 13 CG iterations (50k leaf).
REBUILD_MIN_ITS = 5


class LinearSolverError(RuntimeError):
    """A linear solve could not be done (message says which method and why)."""


def _locate_mkl():
    """Tell pypardiso where MKL's runtime library is, if it is where pip puts
    it: pypardiso otherwise globs the whole environment recursively when it
    is imported (2 s, on every run)."""
    import glob
    import os
    import sys
    if "PYPARDISO_MKL_RT" in os.environ:
        return
    for pattern in ("lib/libmkl_rt.so*", "lib/libmkl_rt*.dylib", "Library/bin/mkl_rt*.dll"):
        found = sorted(glob.glob(os.path.join(sys.prefix, pattern)), key=len)
        if found:
            os.environ["PYPARDISO_MKL_RT"] = found[0]
            return


def pardiso_available():
    _locate_mkl()
    try:
        import pypardiso  # noqa: F401
    except (ImportError, OSError):
        return False
    return True


def resolve_method(method, n_dofs, has_blocks=True):
    """The concrete method for ``method`` (checks the name and availability)."""
    if method not in METHODS:
        raise ValueError(f"unknown linear solver {method!r}: choose one of {', '.join(METHODS)}")
    if method == "auto":
        if n_dofs > AUTO_DIRECT_MAX_DOFS and has_blocks:
            return "amg"
        return "pardiso" if pardiso_available() else "superlu"
    if method == "pardiso" and not pardiso_available():
        raise LinearSolverError("linear solver 'pardiso' needs the package pypardiso (Intel MKL, "
                                "x86-64 only: pip install pypardiso); available here: superlu, amg")
    if method == "amg" and not has_blocks:
        raise LinearSolverError("linear solver 'amg' needs the nodal block structure of the triangle "
                                "engine; use 'pardiso' or 'superlu' for this problem")
    return method


def symmetric_from_lower(K):
    """The full symmetric matrix (CSR) of its lower triangle K (CSR)."""
    return (K + sp.tril(K, -1).T).tocsr()


# --------------------------------------------------------------------- direct


class _PardisoHandle:
    """One PARDISO handle for matrices of one sparsity pattern: the METIS
    ordering and symbolic analysis once, then up to ``factors`` numeric
    factorizations kept side by side (PARDISO's ``maxfct`` / ``mnum``), each
    slot of :class:`DirectSolver` one of them.  A handle per slot would
    repeat the analysis and keep its symbolic data twice: on the 50k leaf
    Hessian (226k DOFs) 2.4 s and 0.65 GB each, next to 1.33 GB per factor.
    The 1-based row pointers and column indices PARDISO reads are made once
    (pypardiso's ``_call_pardiso``, which fixes maxfct = mnum = 1, converts
    them at every call); the call itself is pypardiso's ctypes binding of
    ``pardiso``."""

    def __init__(self, n, ia, ja, factors, single=False):
        import os
        _locate_mkl()
        import pypardiso
        self._ps = ps = pypardiso.PyPardisoSolver(mtype=-2)     # real symmetric indefinite
        os.environ.setdefault("PYPARDISO_MKL_RT", ps.libmkl._name)   # found elsewhere: keep it
        ps.set_iparm(1, 1)         # use the iparm values below, not the defaults
        ps.set_iparm(2, 2)         # METIS nested dissection ordering
        ps.set_iparm(10, 13)       # pivot perturbation 1e-13 (1e-8 by default: inaccurate solves
        #                            of indefinite leaf Hessians, 7e-2 residuals measured)
        ps.set_iparm(21, 1)        # Bunch-Kaufman 1x1 and 2x2 pivots
        ps.set_iparm(24, 1)        # two-level parallel factorization
        # single: the matrices, the factors and the solves in single precision
        # (the values handed to PARDISO are then float32)
        ps.set_iparm(28, 1 if single else 0)
        self.dtype = np.float32 if single else np.float64
        self.n = n
        self.nnz = len(ja)
        self._ia, self._ja = ia, ja        # the upper triangle by rows, 1-based (_upper_of_lower)
        self.factors = factors
        self.analysed = False

    def call(self, phase, mnum, data, b):
        """PARDISO ``phase`` on matrix number ``mnum`` (1-based) with values
        ``data`` and right-hand sides b (n, nrhs), Fortran order; returns x."""
        import ctypes
        from pypardiso.pardiso_wrapper import PyPardisoError
        ps = self._ps
        x = np.zeros_like(b)
        error = ctypes.c_int32(0)
        int_p = ctypes.POINTER(ctypes.c_int32)
        ps._mkl_pardiso(ps.pt.ctypes.data_as(ctypes.POINTER(ps._pt_type[0])),
                        ctypes.byref(ctypes.c_int32(self.factors)), ctypes.byref(ctypes.c_int32(mnum)),
                        ctypes.byref(ctypes.c_int32(-2)), ctypes.byref(ctypes.c_int32(phase)),
                        ctypes.byref(ctypes.c_int32(self.n)), data.ctypes.data_as(ctypes.c_void_p),
                        self._ia.ctypes.data_as(int_p), self._ja.ctypes.data_as(int_p),
                        ps.perm.ctypes.data_as(int_p), ctypes.byref(ctypes.c_int32(b.shape[1])),
                        ps.iparm.ctypes.data_as(int_p), ctypes.byref(ctypes.c_int32(0)),
                        b.ctypes.data_as(ctypes.c_void_p), x.ctypes.data_as(ctypes.c_void_p),
                        ctypes.byref(error))
        if error.value != 0:
            raise LinearSolverError(f"PARDISO phase {phase} failed ({PyPardisoError(error.value)})")
        return x

    def iparm(self, i):
        return int(self._ps.get_iparm(i))

    def release(self):
        """Free the analysis and every factor (PARDISO refuses to free a
        handle it never analysed)."""
        if self.analysed:
            self.call(-1, 1, np.zeros(1, self.dtype), np.zeros((self.n, 1), self.dtype))
            self.analysed = False


class _PardisoFactor:
    """One factor slot: matrix number ``mnum`` of a shared :class:`_PardisoHandle`."""

    def __init__(self, handle, mnum):
        self.handle, self._mnum = handle, mnum
        self._data = np.zeros(handle.nnz, handle.dtype)   # PARDISO refines solves against these
        self.negative = None
        self.perturbed = 0

    def factorize(self, lower, to_upper, shift):
        """Factorize the matrix with lower-triangle values ``lower`` (its
        upper ones: ``lower[to_upper]``) plus ``shift`` on the diagonal."""
        h = self.handle
        _shifted_upper(lower, to_upper, h._ia, shift, self._data)
        zero = np.zeros((h.n, 1), h.dtype)
        try:
            if not h.analysed:
                h.call(11, self._mnum, self._data, zero)
                h.analysed = True
            h.call(22, self._mnum, self._data, zero)
        except LinearSolverError:
            self.negative = None
            raise
        self.negative = h.iparm(23)
        self.perturbed = h.iparm(14)

    def solve(self, b):
        h = self.handle
        b = np.asarray(b, dtype=h.dtype)
        # perturbed pivots: two steps of iterative refinement
        h._ps.set_iparm(8, 2 if self.perturbed else 0)
        x = h.call(33, self._mnum, self._data, b.reshape(-1, 1) if b.ndim == 1 else np.asfortranarray(b))
        return x.reshape(b.shape).astype(np.float64, copy=False)

    def release(self):
        self.handle.release()


class _SuperLUFactor:
    def __init__(self):
        self._lu = None
        self.negative = None
        self.perturbed = 0

    def factorize(self, A):
        """A: full symmetric CSC.  SuperLU in symmetric mode with diagonal
        pivots computes A = P^T L U P with U = D L^T, so the signs of diag(U)
        are the inertia (Sylvester)."""
        try:
            lu = spla.splu(A, permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0,
                           options=dict(SymmetricMode=True))
        except RuntimeError as exc:            # an exactly zero pivot: singular
            self._lu, self.negative = None, None
            raise LinearSolverError(f"SuperLU: singular matrix ({exc})") from exc
        if not np.array_equal(lu.perm_r, lu.perm_c):
            self._lu, self.negative = None, None
            raise LinearSolverError("SuperLU left the diagonal while pivoting: no inertia")
        self._lu = lu
        self.negative = int(np.count_nonzero(~(lu.U.diagonal() > 0.0)))

    def solve(self, b):
        return self._lu.solve(np.asarray(b, dtype=np.float64))

    def release(self):
        self._lu = None


# Where the problem has free rigid motions (an exactly singular Hessian), the
# factorized matrix is K + REGULARIZATION * max|diag K| * I: the null modes
# would otherwise be amplified without bound by the preconditioner (the
# conjugate gradients, which run on K itself in the complement of the rigid
# motions, remove the effect of the shift in a few iterations).
REGULARIZATION = 1e-10
# ... and 1e-6 for a single-precision factorization, whose pivots carry
# rounding errors of about 6e-8 times the matrix's scale: a shift below that
# leaves the pivots of the rigid motions with a random sign
REGULARIZATION_SINGLE = 1e-6
# iterative refinement of solves with a single-precision factor (DirectSolver.solve)
REFINE_RTOL, REFINE_MAX = 1e-12, 10


@nb.njit(cache=True)
def _upper_of_lower(indptr, indices, n):
    """The upper triangle by rows (PARDISO's input: 1-based int32 row
    pointers ia and columns ja) of a symmetric matrix given by its lower
    triangle in CSR, the position in the lower data of each upper entry, and
    of each diagonal entry (-1: missing).  A counting sort by column: the
    rows are visited in order, so each upper row comes out sorted.  (SciPy's
    transpose and conversion took 8 s, with their float and index copies, on
    the 100k leaf's 26.5M entries.)"""
    nnz = indptr[n]
    start = np.zeros(n + 1, np.int64)
    for k in range(nnz):
        start[indices[k] + 1] += 1
    for j in range(n):
        start[j + 1] += start[j]
    ia = np.empty(n + 1, np.int32)
    for j in range(n + 1):
        ia[j] = start[j] + 1
    ja = np.empty(nnz, np.int32)
    to_upper = np.empty(nnz, np.int64)
    diag = np.full(n, -1, np.int64)
    for i in range(n):
        for k in range(indptr[i], indptr[i + 1]):
            j = indices[k]
            p = start[j]
            start[j] = p + 1
            ja[p] = i + 1
            to_upper[p] = k
            if j == i:
                diag[i] = k
    return ia, ja, to_upper, diag


@nb.njit(cache=True)
def _shifted_upper(lower, to_upper, ia, shift, out):
    """PARDISO's values, written into ``out`` (its dtype): the upper
    triangle by rows, ``lower[to_upper]``, with ``shift`` added to the
    diagonal, the first entry of each upper row (1-based row pointers ia).
    In place: on the 100k leaf the gather and the shifted copy were three
    arrays of 212 MB per factorization, whose first touch alone took 2-4 s
    on a VM that hands freed memory back to its host (README, Scaling)."""
    for p in range(len(to_upper)):
        out[p] = lower[to_upper[p]]
    if shift != 0.0:
        for j in range(len(ia) - 1):
            d = ia[j] - 1
            out[d] = lower[to_upper[d]] + shift     # rounded once, also into float32


class DirectSolver:
    """Sparse LDL^T factorizations of the Hessians of one sparsity pattern.

    Two factor slots: the current Hessian's, and the last positive definite
    one, which preconditions the conjugate gradients when the current Hessian
    is indefinite (a nearby positive definite Hessian: CG then needs few
    iterations to find the negative curvature and the trust-region step,
    with one factorization per Newton step).  With PARDISO both are factors
    of one handle (:class:`_PardisoHandle`: one analysis).

    single: the factorizations in single precision (PARDISO), as
    preconditioners and with iterative refinement in the solves; the inertia
    that decides stability comes from a double-precision factorization
    (factorize(exact_inertia=True), a third slot).
    """

    direct = True

    def __init__(self, method, n, indptr, indices, regularize=False, single=False):
        if single and method != "pardiso":
            raise LinearSolverError(f"a single-precision factorization needs 'pardiso', not {method!r}")
        self.name = method
        self.regularize = regularize
        self.single = single
        self.n = n
        # PARDISO takes the upper triangle by rows = the lower triangle by
        # columns: one fixed permutation of the entries, found once
        ia, ja, self._to_upper, self._diag = _upper_of_lower(np.asarray(indptr), np.asarray(indices), n)
        missing = np.flatnonzero(self._diag < 0)
        if len(missing):
            raise LinearSolverError(f"the Hessian pattern lacks the diagonal entry of {len(missing)} "
                                    f"rows (first: row {missing[0]})")
        if method == "pardiso":
            # both slots are factors of one handle (one analysis); single
            # precision: a third slot, a double-precision handle of its own,
            # for the inertia where it decides (factorize(exact_inertia=True);
            # analysed at its first use)
            shared = _PardisoHandle(n, ia, ja, 2, single)
            self._slots = ([_PardisoFactor(shared, 1), _PardisoFactor(shared, 2)]
                           + ([_PardisoFactor(_PardisoHandle(n, ia, ja, 1), 1)] if single else []))
        else:
            self._slots = [_SuperLUFactor(), _SuperLUFactor()]
        self._current = None      # slot of the current Hessian
        self._pd = None           # slot of the last positive definite Hessian
        self.K = None

    def factorize(self, K, exact_inertia=False):
        """Numeric factorization of K (lower CSR, this pattern).  Returns the
        number of negative eigenvalues (None: singular / unknown).
        exact_inertia: in double precision also where the factorizations
        are single (the inertia of a single-precision factor is that of K
        up to perturbations of about 1e-6 of its largest entries)."""
        self.K = K
        slot = 2 if self.single and exact_inertia else [i for i in (0, 1) if i != self._pd][0]
        f = self._slots[slot]
        shift = 0.0
        if self.regularize:
            relative = REGULARIZATION_SINGLE if self._single(slot) else REGULARIZATION
            shift = relative * np.abs(K.data[self._diag]).max(initial=0.0)
        if self.name == "pardiso":
            f.factorize(K.data, self._to_upper, shift)
        else:
            data = K.data.copy()
            data[self._diag] += shift
            Kr = sp.csr_matrix((data, K.indices, K.indptr), shape=K.shape)
            f.factorize(symmetric_from_lower(Kr).tocsc())
        self._current = slot
        if f.negative == 0:
            self._pd = slot
        return f.negative

    def _single(self, slot):
        """The factor in ``slot`` is single precision (slot 2 is the double one)."""
        return self.single and slot != 2

    def solve(self, b):
        """K^-1 b with the current (possibly indefinite) factorization,
        refined against K: if regularized one step (the error falls from the
        regularization to its square), if single precision until the
        residual is REFINE_RTOL of b (each step multiplies it by about 1e-4
        on the leaf), at most REFINE_MAX steps."""
        if self._current is None:
            raise LinearSolverError("no factorization of the current Hessian")
        f = self._slots[self._current]
        x = f.solve(b)
        Kx = lower_matvec(self.K)
        for _ in range(REFINE_MAX if self._single(self._current) else int(self.regularize)):
            r = b - Kx(x)
            if np.linalg.norm(r) <= REFINE_RTOL * np.linalg.norm(b):
                break
            x = x + f.solve(r)
        return x

    def preconditioner(self):
        """M^-1 (SPD): the current factorization if K is positive definite,
        else the last positive definite one, else None (no SPD factor yet)."""
        if self._pd is None:
            return None
        return self._slots[self._pd].solve

    def current_is_positive_definite(self):
        """The preconditioner is the factorization of the current Hessian."""
        return self._pd is not None and self._pd == self._current

    def release(self):
        for s in self._slots:
            s.release()


# ------------------------------------------------------------------------ AMG
class BlockLayout(NamedTuple):
    """An engine's nodal structure for AMG and the rigid-motion projection
    (``problem.block_layout()``): DOFs per node, the free DOFs in the full
    numbering (node-major), the number of full DOFs, callables -> the
    rigid-body modes (n_full, 6) and the near null space (n_full, k) of the
    current state, and the prolongators of the coarser nested meshes the
    solve started from (finest first; transfer.interpolation_jacobian), for
    multigrid over those meshes instead of smoothed aggregation."""
    block: int
    free: np.ndarray
    n_full: int
    rigid_modes: Callable
    near_null: Callable
    prolongators: tuple = ()


class AMGSolver:
    """Algebraic multigrid as the CG preconditioner: pyamg smoothed
    aggregation, or, where the solve started from coarser meshes
    (``layout.prolongators``), multigrid over those meshes
    (_geometric_hierarchy).

    The free-DOF Hessian is embedded in the full nodal numbering (fixed DOFs
    get an identity row scaled to the diagonal), so that it has 9 x 9 nodal
    blocks; the near null space is the engine's (``block_layout``: the six
    rigid-body modes of the current state -- translations, and rotations
    acting on positions and tangent derivatives -- and for triangles six
    bending modes).  The hierarchy is built on the first Hessian (the
    reference state) and rebuilt on the current one when CG slows down
    (``note_iterations``); if a rebuilt one turns out not SPD, the previous
    hierarchy comes back (kept where memory holds two hierarchies).
    """

    direct = False
    single = False
    name = "amg"

    def __init__(self, n, layout, rebuild_growth=2.0, options=None):
        self.n = n
        self.block, self.free_full, self.n_full = layout.block, layout.free, layout.n_full
        self.near_null, self.prolongators = layout.near_null, layout.prolongators
        self.rebuild_growth = rebuild_growth
        self.options = dict(options or {})
        self._ml = self._previous = None
        self._its_at_build = None
        self.K = None
        self.builds = 0
        self.released_previous = False
        self.note = None                # what the last build was, where not smoothed aggregation in full

    def _embed(self, K):
        """The symmetric Hessian in the full nodal numbering as a BSR matrix
        of nodal blocks, fixed DOFs with an identity row scaled to the median
        diagonal, written straight from the lower triangle K
        (``_lower_to_full_bsr``: the BSR is the only copy; the route through
        SciPy's transpose, sum, selection products and conversion held about
        six times K at its peak: 0.9 GB for the 50k leaf, about 18 GB for
        the 1M-triangle one)."""
        d = np.abs(K.diagonal())
        scale = np.median(d[d > 0]) if np.any(d > 0) else 1.0
        indptr, indices, data = _lower_to_full_bsr(K.indptr, K.indices, K.data, self.free_full,
                                                   self.n_full, self.block, scale)
        index_type = np.int32 if len(indices) < 2**31 else np.int64
        return sp.bsr_matrix((data, indices.astype(index_type), indptr.astype(index_type)),
                             shape=(self.n_full, self.n_full))

    @property
    def one_level(self):
        """The hierarchy stays one level (AMG_ONE_LEVEL_BLOCKS)."""
        return self.n_full <= AMG_ONE_LEVEL_BLOCKS * self.block

    def factorize(self, K, exact_inertia=False):
        """Keep K (the hierarchy is built on the first one); no inertia
        (exact_inertia: the direct solvers' interface, nothing to do here)."""
        self.K = K
        if self._ml is None:
            self._build(K)
        return None

    def _build(self, K):
        # a rebuild replaces the previous hierarchy: only the current one is
        # kept as a fallback, and not even that where two would not fit in
        # memory (1M-triangle leaf: 8.5 GB each, set-up peak 5 GB more)
        self._release(self._previous)
        self._previous = None
        self.released_previous = (self._ml is not None
                                  and 2 * _hierarchy_bytes(self._ml) > _available_memory())
        if self.released_previous:
            self._release(self._ml)
            self._ml = None
        A = self._embed(K)
        coarse = _CoarseDirect()
        opts = dict(theta=AMG_STRENGTH_THETA, omega=4.0 / 3.0, max_levels=AMG_MAX_LEVELS,
                    max_coarse=AMG_ONE_LEVEL_BLOCKS if self.one_level else AMG_COARSE_BLOCKS,
                    smoothed_levels=GEOMETRIC_SMOOTHED_LEVELS, cycle=None)
        unknown = set(self.options) - set(opts)
        if unknown:
            raise ValueError(f"AMG options {sorted(unknown)}: choose from {sorted(opts)}")
        opts.update(self.options)
        smoothed_levels = opts.pop("smoothed_levels")
        self.note = None
        nested = bool(self.prolongators) and not self.one_level
        cycle = opts.pop("cycle") or (NESTED_CYCLE if nested else SA_CYCLE)
        if cycle not in CYCLES:
            raise ValueError(f"AMG option cycle={cycle!r}: choose from {sorted(CYCLES)}")
        if nested:
            fixed = np.ones(self.n_full, bool)
            fixed[self.free_full] = False
            ml = _geometric_hierarchy(A, self.prolongators, fixed, coarse, opts["omega"], smoothed_levels)
            self.note = f"multigrid over the {len(self.prolongators)} coarser meshes of the start (nested iteration)"
        else:
            B = self.near_null()
            if (B.shape[1] > AMG_LEAN_NEAR_NULL
                    and _hierarchy_need(A, K, B.shape[1]) > _available_memory()):
                B = np.ascontiguousarray(B[:, :AMG_LEAN_NEAR_NULL])
                self.note = (f"hierarchy on the first {AMG_LEAN_NEAR_NULL} near-null vectors only "
                             "(not enough memory for all; more CG iterations)")
            ml = _smoothed_aggregation(A, B, coarse, **opts)
        ml.coarse_direct = coarse
        ml.visits = CYCLES[cycle]
        self._previous, self._ml = self._ml, ml
        self._its_at_build = None
        self.builds += 1

    def note_iterations(self, its, reason, rtol=0.1):
        """After a CG solve to the relative residual ``rtol``: rebuild the
        hierarchy on the current Hessian if CG slowed down -- more than
        ``rebuild_growth`` times the iterations per decade of residual
        reduction of the first solve after the last build (counted as at
        least REBUILD_MIN_ITS: a first solve cut after an iteration or two
        on the trust-region boundary says nothing) plus 5 -- without meeting
        negative curvature (a cycle of an indefinite Hessian is no SPD
        preconditioner).  Per decade (log10(1/rtol), at least one; a solve
        stopped on the boundary counts one): the inexact Newton tightens
        rtol as it converges, and more iterations for more decades are no
        sign of a stale hierarchy (199k-triangle leaf from its 50k solution:
        5 then 19 CG iterations at rtol 0.1 and about 1e-3 rebuilt it for
        nothing, 25 s and a second hierarchy).  Returns the seconds spent
        rebuilding (0: kept)."""
        decades = max(np.log10(1.0 / rtol), 1.0) if reason == "converged" else 1.0
        per_decade = its / decades
        if self._its_at_build is None:
            self._its_at_build = max(per_decade, REBUILD_MIN_ITS)
            return 0.0
        if per_decade > self.rebuild_growth * self._its_at_build + 5 and reason != "negative curvature":
            t0 = time.perf_counter()
            self._build(self.K)
            return time.perf_counter() - t0
        return 0.0

    def restore_previous(self):
        """Back to the previous hierarchy (the rebuilt one was not SPD: this
        can happen in any later solve, so the previous one is kept -- the
        stability map's thin panel took 693 instead of 365 Newton iterations
        when it was released after the new one's first solve); False if
        there is none."""
        if self._previous is None:
            return False
        self._release(self._ml)
        self._ml, self._previous = self._previous, None
        self._its_at_build = None
        return True

    def preconditioner(self):
        ml, free, nf = self._ml, self.free_full, self.n_full

        def cycle(r):
            full = np.zeros(nf)
            full[free] = r
            if len(ml.levels) == 1:
                return ml.coarse_solver(ml.levels[0].A, full)[free]
            x = np.zeros(nf)
            _cycle(ml, 0, x, full)
            return x[free]

        def apply(r):                       # one cycle per vector
            return cycle(r) if r.ndim == 1 else np.column_stack([cycle(c) for c in r.T])
        return apply

    def current_is_positive_definite(self):
        return False

    def release(self):
        self._release(self._ml)
        self._release(self._previous)
        self._ml = self._previous = None

    @staticmethod
    def _release(ml):
        """Free a hierarchy's coarse factor (PARDISO keeps it until told)."""
        if ml is not None and hasattr(ml, "coarse_direct"):
            ml.coarse_direct.release()


def _cycle(ml, level, x, b):
    """One multigrid cycle on A_level x = b, x in place: presmoothing, the
    restricted residual corrected from zero on the next level (visited
    ``ml.visits`` times: CYCLES; solved directly on the coarsest),
    prolongation, postsmoothing.  With visits (2, 2) it is pyamg's
    MultilevelSolver.solve(cycle="W", maxiter=1) without that one's two
    residual norms on the finest level (tested); pyamg has no cycle that
    visits the levels unequally.  The pre- and postsmoothers are the same
    symmetric sweeps, so every such cycle is a symmetric positive definite
    preconditioner (symmetric to the single-precision rounding of the
    finest operator, whose smoother divides by the double diagonal blocks:
    1e-6 relative, tested)."""
    lv = ml.levels[level]
    lv.presmoother(lv.A, x, b)
    coarse_b = lv.R @ (b - lv.A @ x)
    coarse_x = np.zeros_like(coarse_b)
    if level == len(ml.levels) - 2:
        coarse_x[:] = ml.coarse_solver(ml.levels[-1].A, coarse_b)
    else:
        for _ in range(ml.visits[level > 0]):
            _cycle(ml, level + 1, coarse_x, coarse_b)
    x += lv.P @ coarse_x
    lv.postsmoother(lv.A, x, b)


def _smoothed_aggregation(A, B, coarse_solver, theta, omega, max_levels, max_coarse):
    """The smoothed-aggregation hierarchy of the BSR matrix A (symmetric)
    with near-null space B: pyamg's (``smoothed_aggregation_solver`` with
    symmetric strength ``theta``, standard aggregation, no relaxation of B,
    Jacobi prolongation smoothing with 'block' weighting ``omega``, block
    Gauss-Seidel smoothers, coarsening while a level has more than
    ``max_coarse`` blocks and there are fewer than ``max_levels`` levels),
    built from pyamg's parts, with the steps that hold memory done
    without pyamg's temporaries: the prolongation smoothing scales and
    corrects A T in place (pyamg copies A for D^-1 A), and
    the Galerkin product P^T (A P) is summed into its block pattern
    (_galerkin) with the restriction as a view of P (pyamg: a copy of P,
    R A, R A P); P is kept in single precision (_SingleBSR), rounded
    before the Galerkin product (its double-precision version is gone
    before the coarse operator is allocated), and so is the finest
    operator, after it (in place); the smoothers are our block Gauss-Seidel
    (_smooth).  The same hierarchy up to that rounding (tested)."""
    from pyamg.aggregation import fit_candidates, standard_aggregation
    from pyamg.multilevel import MultilevelSolver
    from pyamg.strength import symmetric_strength_of_connection
    levels = []
    while True:
        level = MultilevelSolver.Level()
        level.A = A
        levels.append(level)
        if len(levels) >= max_levels or A.shape[0] // A.blocksize[0] <= max_coarse:
            break
        C = symmetric_strength_of_connection(A, theta=theta)
        T, B = fit_candidates(standard_aggregation(C)[0], B)
        del C
        A = _coarsen(level, A, _smoothed_prolongator(A, T, omega), single=len(levels) == 1)
    return MultilevelSolver(levels, coarse_solver=coarse_solver)


def _geometric_hierarchy(A, prolongators, fixed, coarse_solver, omega, smoothed_levels):
    """The multigrid hierarchy of the BSR matrix A over nested meshes:
    ``prolongators`` (finest first) interpolate a coarser mesh's nodal
    increments onto the next finer one's (transfer.interpolation_jacobian;
    the finest one's rows of ``fixed`` DOFs zeroed), the first
    ``smoothed_levels`` of them smoothed by one block Jacobi step on their
    level's operator (_smoothed_prolongator), each coarse operator the
    Galerkin product P^T A P, block Gauss-Seidel smoothers and the coarsest
    level solved directly, as in _smoothed_aggregation."""
    from pyamg.multilevel import MultilevelSolver
    levels = []
    for k, P in enumerate(prolongators):
        level = MultilevelSolver.Level()
        level.A = A
        levels.append(level)
        P = P.copy()
        if k == 0:           # the block rows' rows of fixed DOFs, each block row repeated per block
            P.data[fixed.reshape(-1, P.blocksize[0]).repeat(np.diff(P.indptr), axis=0)] = 0.0
        if k < smoothed_levels:
            P = _smoothed_prolongator(A, P, omega)
        A = _coarsen(level, A, P, single=k == 0)
    level = MultilevelSolver.Level()
    level.A = A
    levels.append(level)
    return MultilevelSolver(levels, coarse_solver=coarse_solver)


def _coarsen(level, A, P, single):
    """The next coarser operator P^T A P (_galerkin), with P kept on
    ``level`` in single precision (_SingleBSR; rounded before the product),
    R a view of its transpose, and the level's smoothers (_smooth, A
    rounded after the product where ``single``)."""
    level.P = _SingleBSR(P)
    level.R = _TransposeOf(level.P)
    coarse = _galerkin(A, level.P)
    _smooth(level, A, single)
    return coarse


def _smooth(level, A, single):
    """The level's pre- and post-smoother: AMG_SMOOTHER_SWEEPS symmetric
    block Gauss-Seidel sweeps (_block_gauss_seidel) with the pseudo-inverses
    of the diagonal blocks of A (BSR; pyamg's get_block_diag); ``single``:
    A is rounded to single precision in place (_SingleBSR), after the
    Galerkin product that made the next level from it.
    Only the finest level is rounded (1M-triangle leaf: A_0 4.2 GB in
    double, 2.1 in single): every cycle visits it once, and the preconditioner
    stays symmetric positive definite whatever its rounding (the symmetric
    sweeps' M + M^T - A is the block diagonal, the coarse correction a
    Galerkin product of the double A).  The coarser levels, visited twice
    per W-cycle (below the second level in every cycle: CYCLES), must hold
    the operator their own coarse levels were made from: rounding moves the lowest eigenvalues (a free plate's rigid
    modes: 1e-5 instead of 1e-14 of |A|), which the coarsest level's
    regularized factor then amplifies (the W-cycle indefinite; also when
    the coarse operators were made from the rounded ones: 199k leaf)."""
    from pyamg.util.utils import get_block_diag
    dinv = get_block_diag(A, blocksize=A.blocksize[0], inv_flag=True)
    level.A = op = _SingleBSR(A) if single else A

    def smoother(_, x, b):
        _block_gauss_seidel(op.indptr, op.indices, op.data, dinv, x, b, AMG_SMOOTHER_SWEEPS)
    level.presmoother = level.postsmoother = smoother


@nb.njit(cache=True)
def _block_gauss_seidel(indptr, indices, data, dinv, x, b, sweeps):
    """``sweeps`` symmetric block Gauss-Seidel sweeps on A x = b, x in place
    (A the BSR (indptr, indices, data (blocks, m, m)) in any precision, dinv
    the inverses of its diagonal blocks; summed in double): block row i of
    each sweep, forward then backward, sets x_i = dinv_i (b_i - sum over
    j != i of A_ij x_j) (pyamg's block_gauss_seidel)."""
    m = data.shape[1]
    n = len(indptr) - 1
    r = np.empty(m)
    for s in range(2 * sweeps):
        for step in range(n):
            i = step if s % 2 == 0 else n - 1 - step
            for a in range(m):
                r[a] = b[i * m + a]
            for k in range(indptr[i], indptr[i + 1]):
                j = indices[k]
                if j != i:
                    for a in range(m):
                        acc = 0.0
                        for c in range(m):
                            acc += data[k, a, c] * x[j * m + c]
                        r[a] -= acc
            for a in range(m):
                acc = 0.0
                for c in range(m):
                    acc += dinv[i, a, c] * r[c]
                x[i * m + a] = acc


def _smoothed_prolongator(A, T, omega):
    """P = T - (omega / rho) D^-1 A T, D the block diagonal of A (its nodal
    blocks; of each block only the part on its positive eigenvalues is
    inverted, the rest left unsmoothed) and rho the spectral radius of
    D^-1 A (pyamg's Jacobi prolongation smoother with weighting 'block'),
    written into A T.  Block, not scalar, Jacobi (pyamg's 'diagonal', used
    until 2026-12-07): a nodal block holds positions (lengths) and tangent
    derivatives (numbers) coupled by the membrane and strain-gradient
    terms, and the scalar diagonal smooths their coupled errors poorly (CG
    to 1e-8 on the default leaf's Hessian at its solution: 27 -> 13
    iterations at 50k triangles, 37 -> 22 at 100k; README "Scaling").
    Before that, until 2026-12-05, pyamg's 'local' weighting (rho D replaced
    by the row sums of |A|, several times rho D on the DKT Hessians) smoothed
    it less still (50k: 38 iterations)."""
    S = _block_inverse_sqrt(A)
    rho = _spectral_radius(A, S)
    # rho = 0: nothing to smooth with (D^-1 A = 0); P = T
    coef = -omega / rho if rho > 0 else 0.0
    AT = (A @ T).tobsr(blocksize=T.blocksize)
    AT.sort_indices()
    T.sort_indices()
    _block_rows_add(coef, S, AT.indptr, AT.indices, AT.data, T.indptr, T.indices, T.data)
    return AT


def _block_inverse_sqrt(A):
    """S_i = D_i^-1/2 for each diagonal block D_i of the BSR matrix A
    (blocks, m, m), on D_i's eigenvalues above 1e-12 of its largest (0 on
    the others and for a missing block): D^-1 = S S, S D S the identity on
    the positive part."""
    m = A.blocksize[0]
    A.sort_indices()
    S = np.zeros((A.shape[0] // m, m, m))
    run_chunks(_block_inverse_sqrt_rows, 0, len(S), A.indptr, A.indices, A.data, S, min_chunk=256)
    return S


@nb.njit(cache=True, nogil=True)
def _block_inverse_sqrt_rows(lo, hi, indptr, indices, data, S):
    m = data.shape[1]
    D = np.empty((m, m))
    for i in range(lo, hi):
        k = indptr[i] + np.searchsorted(indices[indptr[i]:indptr[i + 1]], i)
        if k == indptr[i + 1] or indices[k] != i:
            continue
        for a in range(m):
            for c in range(m):
                D[a, c] = 0.5 * (data[k, a, c] + data[k, c, a])
        w, Q = np.linalg.eigh(D)
        floor = 1e-12 * max(w[-1], 0.0)
        for j in range(m):
            if w[j] > floor and w[j] > 0.0:
                f = 1.0 / np.sqrt(w[j])
                for a in range(m):
                    for c in range(m):
                        S[i, a, c] += f * Q[a, j] * Q[c, j]


def _spectral_radius(A, S):
    """The spectral radius of D^-1 A (S = D^-1/2 by blocks: _block_inverse_sqrt),
    that of the symmetric S A S: ARPACK's Lanczos (scipy eigsh) on it as an
    operator, to 1e-2 as pyamg (no scaled copy of A: 4 GB for the
    1M-triangle leaf)."""
    m = S.shape[1]
    Sb = sp.bsr_matrix((S, np.arange(len(S)), np.arange(len(S) + 1)), shape=A.shape, blocksize=(m, m))
    op = spla.LinearOperator(A.shape, matvec=lambda x: Sb @ (A @ (Sb @ x.ravel())), dtype=np.float64)
    v0 = np.random.default_rng(0).standard_normal(A.shape[0])
    if not op.matvec(v0).any():                   # D^-1 A = 0 (ARPACK refuses it)
        return 0.0
    try:
        lam = spla.eigsh(op, k=1, which="LM", tol=1e-2, ncv=min(12, A.shape[0] - 1), v0=v0,
                         return_eigenvectors=False)
    except spla.ArpackNoConvergence as exc:       # its best Ritz value (a lower bound), or none
        lam = exc.eigenvalues
    rho = float(np.abs(lam).max()) if len(lam) else 0.0
    return rho if np.isfinite(rho) else 0.0


@nb.njit(cache=True)
def _block_rows_add(coef, S, ptr, idx, data, t_ptr, t_idx, t_data):
    """data (the BSR A T) <- T + coef D_i^-1 data by block rows i (D_i^-1 =
    S_i S_i), T's blocks added at their positions in A T's pattern (which
    holds them: A has its diagonal blocks)."""
    m = data.shape[1]
    Dinv = np.empty((m, m))
    col = np.empty(m)
    for i in range(len(ptr) - 1):
        for a in range(m):
            for c in range(m):
                acc = 0.0
                for j in range(m):
                    acc += S[i, a, j] * S[i, j, c]
                Dinv[a, c] = coef * acc
        for k in range(ptr[i], ptr[i + 1]):
            for c in range(data.shape[2]):
                for a in range(m):
                    col[a] = data[k, a, c]
                for a in range(m):
                    acc = 0.0
                    for j in range(m):
                        acc += Dinv[a, j] * col[j]
                    data[k, a, c] = acc
        for kt in range(t_ptr[i], t_ptr[i + 1]):
            k = ptr[i] + np.searchsorted(idx[ptr[i]:ptr[i + 1]], t_idx[kt])
            if k == ptr[i + 1] or idx[k] != t_idx[kt]:
                raise ValueError("A T lacks a block of T")
            data[k] += t_data[kt]


def _galerkin(A, P):
    """P^T A P (A BSR, P a _SingleBSR), summed row by row of P^T into its
    block pattern (the rows in chunks on the assembly's threads,
    kernels/parallel.py):
    for each coarse row I, the products P_iI^T A_ij P_jJ over the fine
    rows i of P's column I, their A blocks (i, j) and P's blocks (j, J);
    no transposed copy of P and no A P (pyamg's R A and R A P held 1.2 GB
    beyond the result at 199k triangles, A P alone would be about twice P)."""
    n_coarse = P.shape[1] // P.blocksize[1]
    A.sort_indices()
    t_ptr, t_row, t_blk, ptr, idx = _galerkin_pattern(A.indptr, A.indices, P.indptr, P.indices, n_coarse)
    data = np.zeros((len(idx), P.blocksize[1], P.blocksize[1]))
    run_chunks(_galerkin_rows, 0, n_coarse, t_ptr, t_row, t_blk, ptr, idx, A.indptr, A.indices, A.data,
               P.indptr, P.indices, P.data, data, min_chunk=64)
    return sp.bsr_matrix((data, idx, ptr), shape=(P.shape[1], P.shape[1]))


@nb.njit(cache=True)
def _galerkin_pattern(a_ptr, a_idx, p_ptr, p_idx, n_coarse):
    """The block pattern (ptr, idx) of P^T A P for the BSR patterns of A
    and P, with P^T's (t_ptr; fine rows t_row, P's block numbers t_blk)."""
    n_fine = len(p_ptr) - 1
    # P^T's pattern: for each coarse row I the fine rows i and P's block numbers k
    t_ptr = np.zeros(n_coarse + 1, np.int64)
    for k in range(len(p_idx)):
        t_ptr[p_idx[k] + 1] += 1
    for I in range(n_coarse):
        t_ptr[I + 1] += t_ptr[I]
    t_row = np.empty(len(p_idx), np.int64)
    t_blk = np.empty(len(p_idx), np.int64)
    fill = t_ptr[:-1].copy()
    for i in range(n_fine):
        for k in range(p_ptr[i], p_ptr[i + 1]):
            I = p_idx[k]
            t_row[fill[I]] = i
            t_blk[fill[I]] = k
            fill[I] += 1
    # the product's pattern, counted in the first sweep, written in the second
    mark = np.full(n_coarse, -1, np.int64)
    ptr = np.zeros(n_coarse + 1, np.int64)
    idx = np.empty(0, np.int64)
    for sweep in range(2):
        mark[:] = -1
        for I in range(n_coarse):
            at = ptr[I] if sweep == 1 else 0
            for q in range(t_ptr[I], t_ptr[I + 1]):
                i = t_row[q]
                for ka in range(a_ptr[i], a_ptr[i + 1]):
                    j = a_idx[ka]
                    for kp in range(p_ptr[j], p_ptr[j + 1]):
                        J = p_idx[kp]
                        if mark[J] != I:
                            mark[J] = I
                            if sweep == 1:
                                idx[at] = J
                            at += 1
            if sweep == 0:
                ptr[I + 1] = at
            else:
                idx[ptr[I]:at] = np.sort(idx[ptr[I]:at])
        if sweep == 0:
            for I in range(n_coarse):
                ptr[I + 1] += ptr[I]
            idx = np.empty(ptr[n_coarse], np.int64)
    return t_ptr, t_row, t_blk, ptr, idx


@nb.njit(cache=True, nogil=True)
def _galerkin_rows(lo, hi, t_ptr, t_row, t_blk, ptr, idx, a_ptr, a_idx, a_data, p_ptr, p_idx, p_data, data):
    """Rows lo .. hi - 1 of P^T A P into data (blocks in _galerkin_pattern's
    pattern).  Per coarse row I, first W_j = sum_i P_iI^T A_ij over the
    fine rows i of P's column I, one W per fine node j they reach, then
    W_j P_jJ into block (I, J): the second, dearer product once per j, not
    once per pair (i, j) (the 50k leaf's product with its finest smoothed
    prolongator, about 10 blocks per row: 7.1 -> 2.0 s).  slot[J] is the
    position of block (I, J), w_of[j] the position of W_j (valid where
    seen[j] == I) while row I is summed.  Loops, not @: P is single, A double precision."""
    n_fine = len(a_ptr) - 1
    slot = np.empty(len(t_ptr) - 1, np.int64)
    seen = np.full(n_fine, -1, np.int64)
    w_of = np.empty(n_fine, np.int64)
    br, bc = p_data.shape[1], p_data.shape[2]
    reach = 0                   # at most this many W per row: the A blocks of its fine rows
    for I in range(lo, hi):
        count = 0
        for q in range(t_ptr[I], t_ptr[I + 1]):
            count += a_ptr[t_row[q] + 1] - a_ptr[t_row[q]]
        reach = max(reach, count)
    W = np.empty((reach, bc, br))
    nodes = np.empty(reach, np.int64)
    for I in range(lo, hi):
        for s in range(ptr[I], ptr[I + 1]):
            slot[idx[s]] = s
        m = 0
        for q in range(t_ptr[I], t_ptr[I + 1]):
            i, kt = t_row[q], t_blk[q]
            for ka in range(a_ptr[i], a_ptr[i + 1]):
                j = a_idx[ka]
                if seen[j] != I:
                    seen[j], w_of[j], nodes[m] = I, m, j
                    W[m] = 0.0
                    m += 1
                w = W[w_of[j]]
                for c in range(bc):
                    for q2 in range(br):
                        acc = 0.0
                        for r in range(br):
                            acc += p_data[kt, r, c] * a_data[ka, r, q2]
                        w[c, q2] += acc
        for u in range(m):
            j, w = nodes[u], W[u]
            for kp in range(p_ptr[j], p_ptr[j + 1]):
                s = slot[p_idx[kp]]
                for c in range(bc):
                    for c2 in range(bc):
                        acc = 0.0
                        for r in range(br):
                            acc += w[c, r] * p_data[kp, r, c2]
                        data[s, c, c2] += acc


class _CoarseDirect:
    """The coarsest level's solve (pyamg ``coarse_solver``): one LDL^T
    factorization of the best direct method here (PARDISO's nested
    dissection; SuperLU without it), made at the first call.  pyamg's
    'splu' (SuperLU's column ordering of an unsymmetric LU) took 30 s and
    0.84 GB for the 26k-DOF coarsest level of the 199k-triangle leaf (in
    the first W-cycle of every hierarchy: 33.6 s, with PARDISO 6.2 s); the
    coarsest level grows with the mesh (AMG_MAX_LEVELS), to about 130k
    DOFs at 1M triangles.  Zero rows (an aggregate whose near-null vectors
    were dependent: a zero column of P) get a unit diagonal; the
    factorization is regularized (REGULARIZATION: the coarse level of a
    free body carries its rigid modes exactly)."""

    def __init__(self):
        self._A = self._solver = None

    def __call__(self, A, b):
        if A is not self._A:
            self.release()
            L = sp.tril(A.tocsr(), format="csr")
            L.eliminate_zeros()
            empty = L.diagonal() == 0.0
            L = sp.csr_matrix(L + sp.diags(empty.astype(np.float64)))
            L.sort_indices()
            n = A.shape[0]
            self._solver = DirectSolver(resolve_method("auto", n, has_blocks=False), n,
                                        L.indptr, L.indices, regularize=True)
            self._solver.factorize(L)
            self._A = A
        return self._solver.solve(np.ravel(b))

    def release(self):
        if self._solver is not None:
            self._solver.release()
        self._A = self._solver = None


class _SingleBSR:
    """A BSR operator of the hierarchy held in single precision: a
    prolongator P, or the finest operator A (_smooth); products are summed
    in double (_bsr_matvec).  P is rounded before the Galerkin product
    (_galerkin sums in double), so each coarse operator is exactly P^T A P
    of the P applied, A after it (_smoothed_aggregation).  Half the
    memory: P_0 of the 1M-triangle leaf 2.8 GB in double, A_0 4.2; the
    rounding (relative 6e-8) is far below what P approximates (the smoothed
    near-null vectors) and what the smoother does."""

    def __init__(self, M):
        """M's values rounded in place (M keeps the float32 array: no
        reference to M elsewhere holds on to the double one)."""
        M.sort_indices()
        M.data = M.data.astype(np.float32)
        self.indptr, self.indices, self.data = M.indptr, M.indices, M.data
        self.shape, self.blocksize = M.shape, M.blocksize
        self.dtype = np.dtype(np.float64)

    def __matmul__(self, x):
        return _bsr_matvec(self.indptr, self.indices, self.data, np.ascontiguousarray(x), self.shape[0],
                           False)

    def tobsr(self):
        """The operator as a SciPy BSR matrix in double (tests, inspection)."""
        return sp.bsr_matrix((self.data.astype(np.float64), self.indices, self.indptr), shape=self.shape)


class _TransposeOf:
    """P^T as an operator on P's own storage (the restriction of a
    symmetric hierarchy; pyamg holds it as a second copy of P: 0.56 GB for
    the finest level of the 199k-triangle leaf)."""

    def __init__(self, P):
        self.P = P
        self.shape = (P.shape[1], P.shape[0])
        self.dtype = P.dtype

    def __matmul__(self, x):
        P = self.P
        return _bsr_matvec(P.indptr, P.indices, P.data, np.ascontiguousarray(x), self.shape[0], True)


@nb.njit(cache=True)
def _bsr_matvec(indptr, indices, data, x, n_out, transpose):
    """y = P x (or P^T x) for the BSR matrix P = (indptr, indices, data
    (blocks, br, bc)), summed in double."""
    br, bc = data.shape[1], data.shape[2]
    y = np.zeros(n_out)
    for i in range(len(indptr) - 1):
        for k in range(indptr[i], indptr[i + 1]):
            j = indices[k]
            for r in range(br):
                for c in range(bc):
                    if transpose:
                        y[j * bc + c] += data[k, r, c] * x[i * br + r]
                    else:
                        y[i * br + r] += data[k, r, c] * x[j * bc + c]
    return y


def _hierarchy_bytes(ml):
    """Bytes held by the matrices of a pyamg hierarchy."""
    total = 0
    for level in ml.levels:
        for name in ("A", "P", "R"):
            M = getattr(level, name, None)
            if sp.issparse(M) or isinstance(M, _SingleBSR):
                total += M.data.nbytes + M.indices.nbytes + M.indptr.nbytes
    return total


def _hierarchy_need(A, K, k):
    """Bytes a hierarchy with k near-null vectors on the finest operator A
    needs beyond A, with room for the Newton iteration (AMG_LEAN_NEAR_NULL)."""
    a = A.data.nbytes + A.indices.nbytes
    return (a * (AMG_P_SHARE * k / 18 + AMG_COARSE_SHARE * (k / 18) ** 2 - 0.5)
            + AMG_NEWTON_HESSIANS * K.data.nbytes)


def _available_memory():
    """Bytes of memory the process can still use (Linux: MemAvailable;
    elsewhere the free physical pages; unknown: unlimited)."""
    try:
        with open("/proc/meminfo") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    try:
        return os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (AttributeError, ValueError, OSError):
        return float("inf")


@nb.njit(cache=True)
def _lower_to_full_bsr(indptr, indices, data, free_full, n_full, b, scale):
    """BSR (block size b) of the full symmetric matrix whose lower triangle
    is the CSR (indptr, indices, data) over the free DOFs free_full (in
    ascending order) of n_full DOFs; the fixed DOFs get ``scale`` on the
    diagonal.  Returns (block indptr, block indices, data (blocks, b, b))."""
    nb_rows = n_full // b
    # block columns bj <= bi of each block row of the lower triangle, the
    # diagonal block always (it holds the fixed DOFs' rows), found with a
    # marker per block column: counted in the first sweep, written in the second
    mark = np.full(nb_rows, -1, np.int64)
    low_ptr = np.zeros(nb_rows + 1, np.int64)
    low_idx = np.empty(0, np.int64)
    for sweep in range(2):
        mark[:] = -1
        i = 0
        for bi in range(nb_rows):
            at = low_ptr[bi]
            mark[bi] = bi
            if sweep == 1:
                low_idx[at] = bi
            at += 1
            while i < len(free_full) and free_full[i] // b == bi:
                for k in range(indptr[i], indptr[i + 1]):
                    bj = free_full[indices[k]] // b
                    if mark[bj] != bi:
                        mark[bj] = bi
                        if sweep == 1:
                            low_idx[at] = bj
                        at += 1
                i += 1
            if sweep == 0:
                low_ptr[bi + 1] = at
        if sweep == 0:
            low_idx = np.empty(low_ptr[nb_rows], np.int64)
    # full pattern: row bi holds its lower blocks and the mirrors (bj, bi)
    # of the lower blocks below the diagonal
    ptr = np.zeros(nb_rows + 1, np.int64)
    for bi in range(nb_rows):
        for k in range(low_ptr[bi], low_ptr[bi + 1]):
            ptr[bi + 1] += 1
            if low_idx[k] != bi:
                ptr[low_idx[k] + 1] += 1
    for bi in range(nb_rows):
        ptr[bi + 1] += ptr[bi]
    cols = np.empty(ptr[nb_rows], np.int64)
    fill = ptr[:-1].copy()
    for bi in range(nb_rows):
        for k in range(low_ptr[bi], low_ptr[bi + 1]):
            bj = low_idx[k]
            cols[fill[bi]] = bj
            fill[bi] += 1
            if bj != bi:
                cols[fill[bj]] = bi
                fill[bj] += 1
    for bi in range(nb_rows):
        cols[ptr[bi]:ptr[bi + 1]] = np.sort(cols[ptr[bi]:ptr[bi + 1]])
    # values: each lower entry and its mirror into their blocks
    out = np.zeros((ptr[nb_rows], b, b))
    for i in range(len(free_full)):
        fi = free_full[i]
        bi, r = fi // b, fi % b
        for k in range(indptr[i], indptr[i + 1]):
            fj = free_full[indices[k]]
            bj, c = fj // b, fj % b
            out[ptr[bi] + np.searchsorted(cols[ptr[bi]:ptr[bi + 1]], bj), r, c] = data[k]
            if fj != fi:
                out[ptr[bj] + np.searchsorted(cols[ptr[bj]:ptr[bj + 1]], bi), c, r] = data[k]
    is_free = np.zeros(n_full, np.bool_)
    is_free[free_full] = True
    for f in range(n_full):
        if not is_free[f]:
            bi, r = f // b, f % b
            out[ptr[bi] + np.searchsorted(cols[ptr[bi]:ptr[bi + 1]], bi), r, r] = scale
    return ptr, cols, out


# factor_precision="single" (DirectSolver): PARDISO in single precision.
# Measured on the leaf (2 threads): the 50k leaf Hessian (226k DOFs) factorizes
# in 3.4 instead of 6.4 s with 0.67 instead of 1.33 GB of factor memory (PARDISO
# iparm 17; 0.65 GB of analysis data either way); a whole solve of the 50k
# leaf took the same time (267.8 s against 267.9 s: factorizations 78 against
# 105 s, but 159 instead of 72 CG iterations and reused factorizations that
# no longer converge in REUSE_MAX_CG), so double stays the default and single
# is the option for memory.
PRECISIONS = ("double", "single")


def make_linear_solver(method, n, indptr, indices, layout=None, singular=False, precision="double"):
    """The linear solver for a Hessian pattern (lower CSR of n free DOFs).
    ``layout``: (block size, free DOFs in the full numbering, number of full
    DOFs, callable -> rigid modes (n_full, 6), callable -> near null space
    (n_full, k)) for AMG; ``singular``: the
    problem has free rigid motions (regularized factorizations);
    ``precision`` of the factorizations (PRECISIONS)."""
    if precision not in PRECISIONS:
        raise ValueError(f"precision={precision!r}: choose one of {', '.join(PRECISIONS)}")
    method = resolve_method(method, n, has_blocks=layout is not None)
    if method == "amg":
        return AMGSolver(n, layout)
    return DirectSolver(method, n, indptr, indices, regularize=singular, single=precision == "single")


def negative_eigenvalues(K, method="auto"):
    """Number of negative eigenvalues of the symmetric sparse matrix given by
    its lower triangle K (CSR), from the pivots of one LDL^T factorization."""
    K = sp.csr_matrix(K)
    K.sort_indices()
    return DirectSolver(resolve_method(method, K.shape[0], has_blocks=False), K.shape[0],
                        K.indptr, K.indices).factorize(K)


# -------------------------------------------------------------- Krylov: CG
def steihaug_cg(matvec, g, precond, radius=np.inf, rtol=1e-10, maxiter=200, project=None, path=None):
    """Approximate minimizer of the model m(p) = g.p + p.K p / 2 with
    ||p||_M <= radius by preconditioned conjugate gradients (Steihaug 1983,
    Toint 1981; Conn, Gould & Toint, Trust-Region Methods, alg. 7.5.1, with
    their recurrences for the M-norms, so M itself is never applied).

    matvec: p -> K p; precond: r -> M^-1 r (symmetric positive definite);
    project: the orthogonal projector P onto the complement of the free
    rigid motions (None: there are none), applied to the preconditioned
    residuals, so the iterates never move the body rigidly (a free rigid
    rotation of a stressed state away from equilibrium has curvature of
    either sign, which the iteration would otherwise follow), and to the
    products K d: the iteration solves the projected model, whose residual
    is P(-g - K p) (K p has a part along the rigid rotations away from
    equilibrium, which no step orthogonal to them can reduce: unprojected,
    it held the residual up and CG ran to maxiter on a buckled free disc).
    Stops when ||K p + g|| <= rtol ||g||, on the boundary, or on negative
    curvature.  With radius = inf (truncated Newton for a line search) a
    negative curvature direction met in the first iteration is returned as is
    (-M^-1 g: a descent direction), later ones end the iteration.

    path: a :class:`CGPath` that records the iteration (directions, step
    lengths, M-norm recurrences), so that the same model can be solved at a
    smaller radius without new iterations.

    Returns (p, info) with info = dict(iterations, reason in {"converged",
    "boundary", "negative curvature", "maxiter"}, norm_M (of p),
    curvature (d.Kd / d.Md at a negative-curvature exit, else None)).
    """
    n = len(g)
    p = np.zeros(n)
    r = -np.asarray(g, dtype=np.float64)
    gnorm = np.linalg.norm(r)
    if gnorm == 0.0:
        return p, dict(iterations=0, reason="converged", norm_M=0.0, curvature=None)
    P = project or (lambda v: v)
    r = P(r)
    z = P(precond(r))
    rz = r @ z
    if not rz > 0.0:
        raise LinearSolverError(f"preconditioner not positive definite (r.M^-1 r = {rz:.3e})")
    d = z.copy()
    pMp, pMd, dMd = 0.0, 0.0, rz
    for it in range(1, maxiter + 1):
        Kd = P(matvec(d))
        dKd = d @ Kd
        if path is not None:
            path.add(d, rz / dKd if dKd > 0.0 else None, pMp, pMd, dMd)
        if dKd <= 0.0:
            if np.isfinite(radius):
                p += _to_boundary(pMp, pMd, dMd, radius) * d
                return p, dict(iterations=it, reason="negative curvature", norm_M=radius,
                               curvature=dKd / dMd)
            if it == 1:
                return d, dict(iterations=it, reason="negative curvature", norm_M=np.sqrt(dMd),
                               curvature=dKd / dMd)
            return p, dict(iterations=it, reason="negative curvature", norm_M=np.sqrt(pMp),
                           curvature=dKd / dMd)
        alpha = rz / dKd
        if pMp + 2 * alpha * pMd + alpha * alpha * dMd >= radius * radius:
            p += _to_boundary(pMp, pMd, dMd, radius) * d
            return p, dict(iterations=it, reason="boundary", norm_M=radius, curvature=None)
        p += alpha * d
        r -= alpha * Kd
        pMp += 2 * alpha * pMd + alpha * alpha * dMd
        if np.linalg.norm(r) <= rtol * gnorm:
            return p, dict(iterations=it, reason="converged", norm_M=np.sqrt(max(pMp, 0.0)),
                           curvature=None)
        z = P(precond(r))
        rz_new = r @ z
        if not rz_new > 0.0 and np.linalg.norm(r) <= 1e-6 * gnorm:
            # r.M^-1 r lost to round-off (r nearly in the numerical null
            # space of a regularized factor): converged as far as it can
            return p, dict(iterations=it, reason="converged", norm_M=np.sqrt(max(pMp, 0.0)),
                           curvature=None)
        if not rz_new > 0.0:
            raise LinearSolverError(f"preconditioner not positive definite (r.M^-1 r = {rz_new:.3e})")
        beta = rz_new / rz
        rz = rz_new
        pMd = beta * (pMd + alpha * dMd)
        dMd = rz + beta * beta * dMd
        d = z + beta * d
    return p, dict(iterations=maxiter, reason="maxiter", norm_M=np.sqrt(max(pMp, 0.0)), curvature=None)


class CGPath:
    """The iterations of one Steihaug CG solve.  The CG sequence does not
    depend on the radius: the iterates' M-norms grow monotonically (Steihaug
    1983, thm 2.1), and the solution at a smaller radius is where the same
    path first leaves it.  After a rejected trust-region step the model
    (g, K, M) is unchanged, so :meth:`step` gives the new step without CG
    iterations.  At most ``limit`` directions are kept (memory: one vector
    each)."""

    def __init__(self, limit=50):
        self.limit = limit
        self.entries = []           # (d, alpha or None at negative curvature, pMp, pMd, dMd)

    def add(self, d, alpha, pMp, pMd, dMd):
        if len(self.entries) < self.limit:
            self.entries.append((d.copy(), alpha, pMp, pMd, dMd))

    def step(self, radius):
        """(p, info) of steihaug_cg at ``radius`` (0 iterations), or None
        where the recorded path stays inside it."""
        if not self.entries:
            return None
        p = np.zeros_like(self.entries[0][0])
        for d, alpha, pMp, pMd, dMd in self.entries:
            if alpha is None:
                p += _to_boundary(pMp, pMd, dMd, radius) * d
                return p, dict(iterations=0, reason="negative curvature", norm_M=radius, curvature=None)
            if pMp + 2 * alpha * pMd + alpha * alpha * dMd >= radius * radius:
                p += _to_boundary(pMp, pMd, dMd, radius) * d
                return p, dict(iterations=0, reason="boundary", norm_M=radius, curvature=None)
            p += alpha * d
        return None


def _to_boundary(pMp, pMd, dMd, radius):
    """tau >= 0 with ||p + tau d||_M = radius."""
    disc = pMd * pMd + dMd * (radius * radius - pMp)
    return (-pMd + np.sqrt(max(disc, 0.0))) / dMd


def jacobi(K):
    """A diagonal SPD preconditioner from |diag K| (the last resort)."""
    d = np.abs(K.diagonal())
    d = np.where(d > 0, d, max(d.max(initial=0.0), 1.0))
    inv = 1.0 / d
    return lambda r: (inv * r.T).T


def lower_matvec(K):
    """p -> K p for the symmetric K given by its lower triangle (CSR); p may
    be a block of vectors (n, k).  (One pass over K in Numba was no faster
    on one thread, 1.06 against 1.05 ms at 0.9M entries; on two, 49 against
    71 ms at the 100k leaf's 26.5M, and slower below 0.5M: not kept.)"""
    KT = K.T                   # a CSC view, no copy
    diag = K.diagonal()
    return lambda p: K @ p + KT @ p - (diag * p.T).T


def free_rigid_modes(layout):
    """An orthonormal basis (free DOFs, columns) of the rigid motions that
    the fixed DOFs leave free (None if none are): the rigid modes of the
    layout, combined so that they vanish on every fixed DOF."""
    if layout is None:
        return None
    free, n_full = layout.free, layout.n_full
    B = layout.rigid_modes()
    fixed = np.ones(n_full, bool)
    fixed[free] = False
    Bf = B[fixed]
    # combinations N with Bf N = 0: the null space of the 6 x 6 Gram matrix
    # (relative 1e-12 in the squares: singular values below 1e-6 of the largest)
    w, V = np.linalg.eigh(Bf.T @ Bf)
    N = V[:, w <= 1e-12 * max(w.max(), 0.0)] if len(Bf) else np.eye(B.shape[1])
    if N.shape[1] == 0:
        return None
    Q, _ = np.linalg.qr(B[free] @ N)
    return Q


def projector(Q):
    """v -> v minus its part in span(Q) (Q orthonormal; None: identity)."""
    if Q is None:
        return None
    return lambda v: v - Q @ (Q.T @ v)
