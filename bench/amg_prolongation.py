"""How the finest prolongator of multigrid over nested meshes is smoothed,
where elements are shorter than the thickness (issue 10: "Krylov
iterations per Newton step growing at most logarithmically").  A prototype
study: only ``jacobi`` is the product's.

bench/amg_smoother.py found the error a cycle reduces least to be an
in-plane field whose energy is mostly the strain-gradient term's; an exact
solve on the band of nodes within 3 h of the free rim (``rim`` there) moves
it inwards, smooth over the disc, at the same rate: the coarse space, not
the smoother, misses it.  The interpolation of nested iteration carries the
nodal gradients linearly over a coarse triangle, so an interpolated smooth
field has kinks in its gradient along the coarse edges, which the
strain-gradient term (weight h^5 against the membrane's h) charges where
the elements are shorter than h.  Smoothing the prolongator lowers the
energy of the coarse basis functions; here three ways on the finest one,
the third in two implementations (the coarser ones interpolate plainly,
as in the product):

* ``jacobi``: the product's (linalg._smoothed_prolongator, one block
  Jacobi step, P = (I - omega/rho D^-1 A) T);
* ``jacobi2``: two such steps (the stencil of P grows: a denser second
  operator, more memory);
* ``emin``: pyamg's energy minimization (Olson, Schroder & Tuminaro 2011;
  ``pyamg.aggregation.smooth.energy_prolongation_smoother``, 4 CG steps
  on the pattern of the Jacobi step's P, block-diagonal preconditioning)
  with the near null space as a constraint, P B_c = B (B the leaf's 18
  near-null vectors, Shell.block_layout, zero on the fixed DOFs; B_c their
  least-squares fit by the plain interpolation, coarse_near_null, whose
  relative residual is ``constraint_fit``): the same memory as ``jacobi``
  for the hierarchy;
* ``emin-native``: the same algorithm in Numba on the assembly's threads
  (energy_minimized: equal to pyamg's to 1e-13), a prototype of what it
  would cost in the product (its temporaries, four arrays of P's pattern
  in double precision: ``emin_gb``).

The measure of bench/amg_cycle.py (the leaf, meshes/leaf.toml, on
shapes.disc(rings) at h = h_over_l / rings, its reference stiffness, CG to
a relative residual of 1e-8, the product's "VW" cycle over the discs of
rings / 2, rings / 4, ... down to 11 rings); ``--supports``: ``rigid``
(the disc as a free body, 3-2-1 supports) or ``clamp`` (the scene's centre
node clamped, whose slow turn about that node is a different error).

Rows: rings, n_triangles, h_over_l, prolongation, supports, cg_its, reason,
setup_s (the hierarchy, prolongation included), prolongation_s (the
finest prolongator's smoothing alone, fit_s of it the fit of B_c), cg_s,
complexity (values of all levels' operators over the finest one's:
memory), constraint_fit, emin_gb.  Writes
bench/results/amg_prolongation.json.
Run:  python bench/amg_prolongation.py [--rings 45 91 129] [--ratios 3.6 7.3 14.6]
      [--prolongations jacobi jacobi2 emin emin-native] [--supports rigid clamp]
"""

import numba as nb
import numpy as np
import scipy.sparse as sp

PROLONGATIONS = ("jacobi", "jacobi2", "emin", "emin-native")
SUPPORTS = ("rigid", "clamp")
EMIN_STEPS = 4          # CG steps of the energy minimization (pyamg's default)
FIT_STEPS = 20          # CG steps of the near-null fit (coarse_near_null)


def coarse_near_null(T, B, steps=FIT_STEPS):
    """B_c with T B_c = B as nearly as it goes (the least-squares fit, column
    by column): CG on T^T T B_c = T^T B preconditioned by the nodal
    diagonal blocks of T^T T, all columns at once.  On the leaf (rows of
    the supports' fixed DOFs left out) it reaches 2e-11 of B in 20 steps
    (constraint_fit; scipy's lsqr, column by column, took about 40 times as
    long)."""
    from pyamg.util.utils import get_block_diag
    mc = T.blocksize[1]
    TT = (T.T @ T).tobsr(blocksize=(mc, mc))
    Minv = get_block_diag(TT, blocksize=mc, inv_flag=True)

    def prec(R):
        return np.einsum("nij,njk->nik", Minv, R.reshape(-1, mc, R.shape[1])).reshape(R.shape)
    X = np.zeros((T.shape[1], B.shape[1]))
    R = T.T @ B
    Z = prec(R)
    D, rz = Z.copy(), (R * Z).sum(axis=0)
    for _ in range(steps):
        Q = TT @ D
        alpha = rz / np.maximum((D * Q).sum(axis=0), 1e-300)
        X += alpha * D
        R -= alpha * Q
        Z = prec(R)
        rz, rz_old = (R * Z).sum(axis=0), rz
        D = Z + (rz / np.maximum(rz_old, 1e-300)) * D
    return X


@nb.njit(cache=True, nogil=True)
def _restricted_product(lo, hi, a_ptr, a_idx, a_data, ptr, idx, z, out):
    """out = (A Z) on the pattern (ptr, idx) of Z, block rows lo..hi (pyamg's
    incomplete_mat_mult_bsr)."""
    m, mc = z.shape[1], z.shape[2]
    for i in range(lo, hi):
        s0, s1 = ptr[i], ptr[i + 1]
        out[s0:s1] = 0.0
        for k in range(a_ptr[i], a_ptr[i + 1]):
            j = a_idx[k]
            for q in range(ptr[j], ptr[j + 1]):
                t = s0 + np.searchsorted(idx[s0:s1], idx[q])
                if t == s1 or idx[t] != idx[q]:
                    continue
                for a in range(m):
                    for c in range(mc):
                        acc = 0.0
                        for d in range(m):
                            acc += a_data[k, a, d] * z[q, d, c]
                        out[t, a, c] += acc


@nb.njit(cache=True, nogil=True)
def _gram_inverses(lo, hi, ptr, idx, Bc, G):
    """G_i = pinv(sum over the pattern's J of row i of Bc_J^T Bc_J)."""
    k = Bc.shape[2]
    M = np.empty((k, k))
    for i in range(lo, hi):
        M[:] = 0.0
        for q in range(ptr[i], ptr[i + 1]):
            M += Bc[idx[q]].T @ Bc[idx[q]]
        G[i] = np.linalg.pinv(M)


@nb.njit(cache=True, nogil=True)
def _project(lo, hi, ptr, idx, U, Bc, G):
    """U_i <- U_i - (U_i Bc) G_i Bc^T by block rows: U Bc = 0 (pyamg's
    satisfy_constraints)."""
    W = np.empty((U.shape[1], Bc.shape[2]))
    for i in range(lo, hi):
        W[:] = 0.0
        for q in range(ptr[i], ptr[i + 1]):
            W += U[q] @ Bc[idx[q]]
        V = W @ G[i]
        for q in range(ptr[i], ptr[i + 1]):
            U[q] -= V @ Bc[idx[q]].T


@nb.njit(cache=True, nogil=True)
def _scale_rows(lo, hi, ptr, Dinv, U, out):
    for i in range(lo, hi):
        for q in range(ptr[i], ptr[i + 1]):
            out[q] = Dinv[i] @ U[q]


@nb.njit(cache=True)
def _into_pattern(ptr, idx, t_ptr, t_idx, t_data, out):
    for i in range(len(ptr) - 1):
        for q in range(t_ptr[i], t_ptr[i + 1]):
            out[ptr[i] + np.searchsorted(idx[ptr[i]:ptr[i + 1]], t_idx[q])] = t_data[q]


def energy_minimized(A, T, Bc, steps=EMIN_STEPS, record=None):
    """pyamg's energy_prolongation_smoother (no root nodes, block-diagonal
    weighting, CG, the pattern of A's block graph times T) in Numba on the
    assembly's threads: P = T + the CG steps' updates U, each with U B_c = 0,
    minimizing the trace of P^T A P on the pattern.  Its temporaries:
    four arrays of the pattern's size (``record['emin_gb']``)."""
    from pyamg.util.utils import get_block_diag

    from shellritz.kernels.parallel import run_chunks
    m, mc = T.blocksize
    A.sort_indices()
    T = T.copy()
    T.sort_indices()
    graph = sp.csr_matrix((np.ones(len(A.indices)), A.indices, A.indptr), shape=(A.shape[0] // m,) * 2)
    pattern = graph @ sp.csr_matrix((np.ones(len(T.indices)), T.indices, T.indptr),
                                    shape=(T.shape[0] // m, T.shape[1] // mc))
    pattern.sort_indices()
    ptr, idx = pattern.indptr.astype(np.int64), pattern.indices.astype(np.int64)
    n = len(ptr) - 1
    Bb = np.ascontiguousarray(Bc.reshape(-1, mc, Bc.shape[1]))
    Dinv = get_block_diag(A, blocksize=m, inv_flag=True)
    a = (A.indptr.astype(np.int64), A.indices.astype(np.int64), np.ascontiguousarray(A.data))
    P, R, D, AP = (np.zeros((len(idx), m, mc)) for _ in range(4))
    if record is not None:
        record["emin_gb"] = 4 * P.nbytes / 1e9
    _into_pattern(ptr, idx, T.indptr, T.indices, T.data, P)
    G = np.empty((n, Bc.shape[1], Bc.shape[1]))
    run_chunks(_gram_inverses, 0, n, ptr, idx, Bb, G, min_chunk=256)
    run_chunks(_restricted_product, 0, n, *a, ptr, idx, P, R, min_chunk=64)
    R *= -1.0
    run_chunks(_project, 0, n, ptr, idx, R, Bb, G, min_chunk=256)
    old = 0.0
    for step in range(steps):
        run_chunks(_scale_rows, 0, n, ptr, Dinv, R, AP, min_chunk=256)      # Z = D^-1 R, in AP
        new = float(np.vdot(R, AP))
        if step:
            D *= new / old
            D += AP
        else:
            D[:] = AP
        old = new
        run_chunks(_restricted_product, 0, n, *a, ptr, idx, D, AP, min_chunk=64)
        run_chunks(_project, 0, n, ptr, idx, AP, Bb, G, min_chunk=256)
        alpha = new / float(np.vdot(D, AP))
        P += alpha * D
        R -= alpha * AP
    return sp.bsr_matrix((P, idx, ptr), shape=T.shape)


CHILD = r"""
import json, sys, time
import numpy as np
import scipy.sparse as sp
from amg_cg import amg_cg_iterations, leaf_reference
from amg_prolongation import EMIN_STEPS, coarse_near_null, energy_minimized
from shellritz import linalg
rings, ratio, kind, supports = int(sys.argv[1]), float(sys.argv[2]), sys.argv[3], sys.argv[4]
shell, K, prolongators = leaf_reference(rings, ratio, nested=True, supports=supports)
layout = shell.block_layout()
B = np.asarray(layout.near_null(), dtype=float)
B[np.setdiff1d(np.arange(layout.n_full), layout.free)] = 0.0     # the fixed DOFs' rows (zero in T)
product, record = linalg._smoothed_prolongator, dict(prolongation_s=0.0, fit_s=0.0, constraint_fit=None)
if kind == "emin-native":                     # compile the kernels outside the timed set-up
    tiny = sp.bsr_matrix(np.eye(36), blocksize=(9, 9))
    energy_minimized(tiny, tiny.copy(), np.ones((36, 1)), steps=1)


def finest(A, T, omega):
    # only the finest prolongator is smoothed (linalg.GEOMETRIC_SMOOTHED_LEVELS = 1)
    t = time.perf_counter()
    if kind == "jacobi":
        P = product(A, T, omega)
    elif kind == "jacobi2":
        P = product(A, product(A, T, omega), omega)
    else:
        Bc = coarse_near_null(T, B)
        record["fit_s"] = time.perf_counter() - t
        record["constraint_fit"] = float(np.linalg.norm(T @ Bc - B) / np.linalg.norm(B))
        if kind == "emin":
            from pyamg.aggregation.smooth import energy_prolongation_smoother
            m = A.blocksize[0]
            graph = sp.csr_matrix((np.ones(len(A.indices)), A.indices, A.indptr), shape=(A.shape[0] // m,) * 2)
            P = energy_prolongation_smoother(A, T, graph, Bc, B, (False, {}), krylov="cg", maxiter=EMIN_STEPS,
                                             degree=1, weighting="block").tobsr(blocksize=T.blocksize)
        else:
            P = energy_minimized(A, T, Bc, record=record)
        P.sort_indices()
    record["prolongation_s"] = time.perf_counter() - t
    return P


linalg._smoothed_prolongator = finest
linalg._available_memory = lambda: 1e12      # the full 18-vector hierarchy in every case
m = amg_cg_iterations(K, layout, options=dict(cycle="VW"), prolongators=prolongators)
print("ROW " + json.dumps(dict(rings=rings, n_triangles=int(shell.mesh.n_triangles), h_over_l=ratio,
                               prolongation=kind, supports=supports, cg_its=m["its"], reason=m["reason"],
                               setup_s=m["setup_s"], cg_s=m["cg_s"], complexity=m["complexity"], **record)),
      flush=True)
"""


def main():
    from amg_cg import study
    study(__doc__, "amg_prolongation.json",
          "AMG CG iterations and time to 1e-8 on the leaf's reference stiffness: the smoothing of the "
          "finest prolongator of multigrid over nested meshes", CHILD,
          [("rings", "rings", int, [45, 91, 129], None), ("ratios", "h_over_l", float, [3.6, 7.3, 14.6], None),
           ("prolongations", "prolongation", str, PROLONGATIONS, PROLONGATIONS),
           ("supports", "supports", str, ["rigid"], SUPPORTS)])


if __name__ == "__main__":
    main()
