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
energy of the coarse basis functions; here three ways on the finest one
(the coarser ones interpolate plainly, as in the product):

* ``jacobi``: the product's (linalg._smoothed_prolongator, one block
  Jacobi step, P = (I - omega/rho D^-1 A) T);
* ``jacobi2``: two such steps (the stencil of P grows: a denser second
  operator, more memory);
* ``emin``: pyamg's energy minimization (Olson, Schroder & Tuminaro 2011;
  ``pyamg.aggregation.smooth.energy_prolongation_smoother``, 4 CG steps
  on the pattern of the Jacobi step's P, block-diagonal preconditioning)
  with the near null space as a constraint, P B_c = B (B the leaf's 18
  near-null vectors, Shell.block_layout; B_c their least-squares fit by
  the plain interpolation, whose relative residual is ``constraint_fit``):
  the same memory as ``jacobi``.

The measure of bench/amg_cycle.py (the leaf, meshes/leaf.toml, on
shapes.disc(rings) at h = h_over_l / rings, its reference stiffness, CG to
a relative residual of 1e-8, the product's "VW" cycle over the discs of
rings / 2, rings / 4, ... down to 11 rings); ``--supports``: ``rigid``
(the disc as a free body, 3-2-1 supports) or ``clamp`` (the scene's centre
node clamped, whose slow turn about that node is a different error).

Rows: rings, n_triangles, h_over_l, prolongation, supports, cg_its, reason,
setup_s (the hierarchy, prolongation included), prolongation_s (the
finest prolongator's smoothing alone), cg_s, complexity (values of all
levels' operators over the finest one's: memory), constraint_fit.  Writes
bench/results/amg_prolongation.json.
Run:  python bench/amg_prolongation.py [--rings 45 91 129] [--ratios 3.6 7.3 14.6]
      [--prolongations jacobi jacobi2 emin] [--supports rigid clamp]
"""

PROLONGATIONS = ("jacobi", "jacobi2", "emin")
SUPPORTS = ("rigid", "clamp")

CHILD = r"""
import json, sys, time
import numpy as np
import scipy.sparse as sp
from scipy.sparse.linalg import lsqr
from amg_cg import amg_cg_iterations, leaf_reference
from shellritz import linalg
rings, ratio, kind, supports = int(sys.argv[1]), float(sys.argv[2]), sys.argv[3], sys.argv[4]
shell, K, prolongators = leaf_reference(rings, ratio, nested=True, supports=supports)
B = np.asarray(shell.block_layout().near_null(), dtype=float)
product, record = linalg._smoothed_prolongator, dict(prolongation_s=0.0, constraint_fit=None)


def finest(A, T, omega):
    # only the finest prolongator is smoothed (linalg.GEOMETRIC_SMOOTHED_LEVELS = 1)
    t = time.perf_counter()
    if kind == "jacobi":
        P = product(A, T, omega)
    elif kind == "jacobi2":
        P = product(A, product(A, T, omega), omega)
    else:
        from pyamg.aggregation.smooth import energy_prolongation_smoother
        Tc = T.tocsr()
        Bc = np.column_stack([lsqr(Tc, B[:, j], atol=1e-14, btol=1e-14, iter_lim=5000)[0]
                              for j in range(B.shape[1])])
        record["constraint_fit"] = float(np.linalg.norm(Tc @ Bc - B) / np.linalg.norm(B))
        m = A.blocksize[0]
        pattern = sp.csr_matrix((np.ones(len(A.indices)), A.indices, A.indptr), shape=(A.shape[0] // m,) * 2)
        P = energy_prolongation_smoother(A, T, pattern, Bc, B, (False, {}), krylov="cg", maxiter=4,
                                         degree=1, weighting="block").tobsr(blocksize=T.blocksize)
        P.sort_indices()
    record["prolongation_s"] = time.perf_counter() - t
    return P


linalg._smoothed_prolongator = finest
linalg._available_memory = lambda: 1e12      # the full 18-vector hierarchy in every case
m = amg_cg_iterations(K, shell.block_layout(), options=dict(cycle="VW"), prolongators=prolongators)
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
