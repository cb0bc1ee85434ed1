"""Is the AMG smoother what makes CG slow where elements are shorter than
the thickness?  A prototype study (the smoothers here are not in the
product; issue 10: "Krylov iterations per Newton step growing at most
logarithmically", and the default leaf at 1M triangles, h/l = 8.2).

bench/amg_thickness_ratio.py showed that on the leaf's reference stiffness
the CG iterations of shellritz's AMG follow h/l, the thickness over the
element length (12k triangles: 12 at h/l = 1.8, 44 at 3.6, 136 at 7.3),
not the mesh size.  Here the same measure (bench/amg_cg.py: CG to a relative
residual of 1e-8, one W-cycle per iteration, the leaf on shapes.disc(rings)
with h = ratio / rings, its Hessian at the flat reference) with the finest
level's smoother replaced, the rest of the hierarchy unchanged:

* ``block-gs``: the product's (two symmetric block Gauss-Seidel sweeps on
  the 9 x 9 nodal blocks);
* ``aggregates``: one symmetric multiplicative sweep of exact solves on
  the DOFs of each aggregate of the finest level (non-overlapping blocks of
  about ten nodes);
* ``pairs``: the same on every pair of nodes coupled in the Hessian
  (overlapping, 18 x 18);
* ``ring``: on each node with its mesh neighbours (overlapping
  Schwarz, about 7 nodes, 63 x 63);
* ``row``: on each node with every node its Hessian row couples (the
  strain-gradient term also couples the opposite vertices of the
  neighbouring triangles: about 13 nodes);
* ``strong``: on each node with its strongly coupled nodes (the strength
  graph of the aggregation, symmetric strength with the product's theta:
  a purely algebraic patch);
* ``rim``: the product's block Gauss-Seidel sweeps and, after the
  pre-sweeps and before the post-sweeps, an exact solve (SuperLU) on the
  band of nodes within 3 h of the disc's rim, where the worst error of the
  free body lies: does the rim hold the cycle back?

The coarse levels (``--hierarchies``): ``sa``, the product's smoothed
aggregation (18 near-null vectors, three levels); ``nested``, the product's
multigrid over nested meshes (linalg._geometric_hierarchy on the discs of
rings / 2, rings / 4, ... down to 11 rings: amg_cg.leaf_reference).
The supports (``--supports``): ``clamp``, the scene's (its centre node
clamped), or ``rigid``, the disc as a free body (3-2-1 supports that take
away only the rigid motions).  With the clamp the disc has a soft turn about
that node (the nodal tangent derivatives of a single node hold it), which
a cycle reduces about as slowly as the worst mode of the free body: the two
share the rate, and worst_mode picks either (rows before 2026-12-07,
late evening, are all ``clamp``).

Rows: rings, n_triangles, h_over_l, smoother, hierarchy, cg_its, reason,
setup_s (hierarchy and smoother), cg_s, smoother_gb (the dense patch
inverses, in double precision), levels, and the error the cycle reduces
least (worst_mode: mode_rate, mode_in_plane, mode_outer, mode_oscillation,
mode_rayleigh, mode_strain_gradient, mode_diag_strain_gradient; rows from before
2026-12-07 evening have none, the last two are since late evening), supports,
band_nodes (``rim``).  Writes
bench/results/amg_smoother.json.
Run:  python bench/amg_smoother.py [--rings 45 91] [--ratios 3.6 7.3]
      [--smoothers block-gs aggregates pairs ring row strong rim] [--hierarchies sa nested]
"""

import time

import numba as nb
import numpy as np

SMOOTHERS = ("block-gs", "aggregates", "pairs", "ring", "row", "strong", "rim")
RIM_BAND = 3.0          # the rim smoother's band: nodes within RIM_BAND h of the rim
HIERARCHIES = ("sa", "nested")
SUPPORTS = ("clamp", "rigid")


@nb.njit(cache=True)
def patch_inverses(indptr, indices, data, patch_ptr, patch_nodes):
    """The pseudo-inverse of A restricted to the DOFs of each patch (its
    nodes sorted), flattened; A the BSR (indptr, indices, data (k, m, m))."""
    m = data.shape[1]
    n = len(patch_ptr) - 1
    inv_ptr = np.zeros(n + 1, np.int64)
    for i in range(n):
        inv_ptr[i + 1] = inv_ptr[i] + ((patch_ptr[i + 1] - patch_ptr[i]) * m) ** 2
    inv = np.empty(inv_ptr[n])
    for i in range(n):
        nodes = patch_nodes[patch_ptr[i]:patch_ptr[i + 1]]
        k = len(nodes)
        M = np.zeros((k * m, k * m))
        for a in range(k):
            for q in range(indptr[nodes[a]], indptr[nodes[a] + 1]):
                b = np.searchsorted(nodes, indices[q])
                if b < k and nodes[b] == indices[q]:
                    M[a * m:(a + 1) * m, b * m:(b + 1) * m] = data[q]
        inv[inv_ptr[i]:inv_ptr[i + 1]] = np.linalg.pinv(M).ravel()
    return inv_ptr, inv


@nb.njit(cache=True)
def schwarz_sweep(indptr, indices, data, patch_ptr, patch_nodes, inv_ptr, inv, x, b):
    """One symmetric multiplicative Schwarz sweep on A x = b (x in place):
    patch by patch, forward then backward, x_P += A_PP^+ (b - A x)_P."""
    m = data.shape[1]
    n = len(patch_ptr) - 1
    for s in range(2):
        for step in range(n):
            i = step if s == 0 else n - 1 - step
            k = patch_ptr[i + 1] - patch_ptr[i]
            r = np.empty(k * m)
            for a in range(k):
                p = patch_nodes[patch_ptr[i] + a]
                for c in range(m):
                    r[a * m + c] = b[p * m + c]
                for q in range(indptr[p], indptr[p + 1]):
                    j = indices[q]
                    for c in range(m):
                        acc = 0.0
                        for d in range(m):
                            acc += data[q, c, d] * x[j * m + d]
                        r[a * m + c] -= acc
            size = k * m
            base = inv_ptr[i]
            for a in range(k):
                p = patch_nodes[patch_ptr[i] + a]
                for c in range(m):
                    row = base + (a * m + c) * size
                    acc = 0.0
                    for col in range(size):
                        acc += inv[row + col] * r[col]
                    x[p * m + c] += acc


def patches(kind, A, triangles, theta):
    """(patch_ptr, patch_nodes) of the smoother ``kind`` on the BSR A."""
    n = A.shape[0] // A.blocksize[0]
    if kind == "aggregates":
        from pyamg.aggregation import standard_aggregation
        from pyamg.strength import symmetric_strength_of_connection
        agg = standard_aggregation(symmetric_strength_of_connection(A, theta=theta))[0].tocsc()
        groups = [np.sort(agg.indices[agg.indptr[c]:agg.indptr[c + 1]]) for c in range(agg.shape[1])]
    elif kind == "pairs":
        rows = np.repeat(np.arange(n), np.diff(A.indptr))
        groups = [np.array([i, j]) for i, j in zip(rows, A.indices) if j > i]
    elif kind == "ring":
        ring = [{i} for i in range(n)]
        for tri in triangles:
            for u in tri:
                ring[u].update(int(v) for v in tri)
        groups = [np.array(sorted(r)) for r in ring]
    elif kind == "row":
        groups = [np.sort(A.indices[A.indptr[i]:A.indptr[i + 1]]) for i in range(n)]
    elif kind == "strong":
        from pyamg.strength import symmetric_strength_of_connection
        C = symmetric_strength_of_connection(A, theta=theta).tocsr()
        groups = [np.union1d(C.indices[C.indptr[i]:C.indptr[i + 1]], [i]) for i in range(n)]
    else:
        raise ValueError(kind)
    ptr = np.concatenate([[0], np.cumsum([len(g) for g in groups])]).astype(np.int64)
    return ptr, np.concatenate(groups).astype(np.int64)


def install(kind, shell, record):
    """Replace the finest level's smoother of the hierarchies built from now
    on (linalg._smooth) by the smoother ``kind`` (patches of the mesh of
    ``shell``, or its rim band); ``record`` gets its set-up time and memory."""
    from shellritz import linalg
    product = linalg._smooth

    def smooth(level, A, single):
        product(level, A, single)
        if not single:                     # coarser levels: the product's
            return
        t = time.perf_counter()
        if kind == "rim":
            smoother = rim_band_smoother(level, A, shell, record)
        else:
            data = np.asarray(A.data, dtype=np.float64)
            ptr, nodes = patches(kind, A, shell.mesh.triangles, linalg.AMG_STRENGTH_THETA)
            inv_ptr, inv = patch_inverses(A.indptr, A.indices, data, ptr, nodes)
            record.update(smoother_gb=inv.nbytes / 1e9)

            def smoother(_, x, b):
                schwarz_sweep(A.indptr, A.indices, data, ptr, nodes, inv_ptr, inv, x, b)
            smoother = (smoother, smoother)
        record.update(smoother_setup_s=time.perf_counter() - t)
        level.presmoother, level.postsmoother = smoother
    linalg._smooth = smooth


def rim_band_smoother(level, A, shell, record):
    """(pre, post) of the ``rim`` smoother: the level's block Gauss-Seidel
    sweeps (the product's, already on ``level``) and an exact solve of the
    residual equation on the DOFs of the nodes within RIM_BAND h of the
    rim, x_band += A_band^-1 (b - A x)_band (SuperLU of the band's rows and
    columns in double precision)."""
    from scipy.sparse.linalg import splu
    radius = np.linalg.norm(shell.X[:, :2], axis=1)
    band = np.flatnonzero(radius > radius.max() - RIM_BAND * shell.h)
    m = A.blocksize[0]
    dofs = (band[:, None] * m + np.arange(m)).ravel()
    rows = A.tocsr().astype(np.float64)[dofs]
    lu = splu(rows[:, dofs].tocsc())
    record.update(smoother_gb=(lu.L.nnz + lu.U.nnz) * 12 / 1e9, band_nodes=len(band))
    gs_pre, gs_post = level.presmoother, level.postsmoother

    def band_solve(x, b):
        x[dofs] += lu.solve(b[dofs] - rows @ x).astype(x.dtype)

    def pre(lv, x, b):
        gs_pre(lv, x, b)
        band_solve(x, b)

    def post(lv, x, b):
        band_solve(x, b)
        gs_post(lv, x, b)
    return pre, post


def worst_mode(shell, K, amg, cycles=30):
    """The error one cycle reduces least (the stationary iteration
    e <- (I - B K) e from a random e, free rigid motions projected out; B a
    cycle of the solver ``amg``'s hierarchy, smoother included) and what it
    looks like: mode_rate, the energy-norm reduction of the last cycle;
    mode_in_plane, the share of its squared nodal values along the
    reference plane (x, y); mode_outer, the share on the nodes of the outer
    fifth of the disc's radius; mode_oscillation, |grad u| l / |u| of its
    positions u (gradients per triangle, root mean squares; about 1: it
    changes from node to node, l / R: smooth); mode_rayleigh, e^T K e over
    e^T D e, D the nodal 9 x 9 diagonal blocks (near 1 the smoother damps
    it; small, the coarse levels must); mode_strain_gradient and
    mode_diag_strain_gradient, the strain-gradient term's share of e^T K e and
    of e^T D e (the Hessian assembled once more without it)."""
    from pyamg.util.utils import get_block_diag
    from shellritz.linalg import free_rigid_modes, lower_matvec, projector
    layout = shell.block_layout()
    project = projector(free_rigid_modes(layout)) or (lambda v: v)
    cycle, matvec = amg.preconditioner(), lower_matvec(K)
    energy = lambda v: float(v @ matvec(v))
    e = project(np.random.default_rng(1).standard_normal(K.shape[0]))
    e /= np.sqrt(energy(e))
    for _ in range(cycles):
        e = project(e - cycle(matvec(e)))
        rate = np.sqrt(energy(e))
        e /= rate
    D = get_block_diag(amg._embed(K), blocksize=9, inv_flag=False)
    term, shell.strain_gradient = shell.strain_gradient, None
    K0 = shell.evaluate(shell.free_state(), 2)[2]
    shell.strain_gradient = term
    D0 = get_block_diag(amg._embed(K0), blocksize=9, inv_flag=False)
    full = np.zeros(layout.n_full)
    full[layout.free] = e
    E = full.reshape(-1, 3, 3)                         # node, (r, a_1, a_2), component
    X, tri = shell.X, shell.mesh.triangles
    size = (E ** 2).sum(axis=(1, 2))
    u = E[:, 0]
    edges = np.stack([X[tri[:, 1]] - X[tri[:, 0]], X[tri[:, 2]] - X[tri[:, 0]]], axis=2)[:, :2]
    du = np.stack([u[tri[:, 1]] - u[tri[:, 0]], u[tri[:, 2]] - u[tri[:, 0]]], axis=2)
    grad_u = np.sqrt((np.einsum("tkj,tjl->tkl", du, np.linalg.inv(edges)) ** 2).sum(axis=(1, 2)).mean())
    radius = np.linalg.norm(X[:, :2], axis=1)
    f = full.reshape(-1, 9)
    return dict(mode_rate=float(rate), mode_in_plane=float((E[:, :, :2] ** 2).sum() / size.sum()),
                mode_outer=float(size[radius > 0.8 * radius.max()].sum() / size.sum()),
                mode_oscillation=float(grad_u * np.sqrt(2.0 * shell.mesh.areas.mean())
                                       / np.sqrt((u ** 2).sum(axis=1).mean())),
                mode_rayleigh=float(1.0 / np.einsum("ni,nij,nj->", f, D, f)),
                mode_strain_gradient=float(1.0 - e @ lower_matvec(K0)(e)),
                mode_diag_strain_gradient=float(1.0 - np.einsum("ni,nij,nj->", f, D0, f)
                                           / np.einsum("ni,nij,nj->", f, D, f)))


CHILD = r"""
import json, sys
from amg_cg import amg_cg_iterations, leaf_reference
from amg_smoother import install, worst_mode
from shellritz import linalg
rings, ratio, kind, hierarchy, supports = (int(sys.argv[1]), float(sys.argv[2]), sys.argv[3], sys.argv[4],
                                           sys.argv[5])
shell, K, prolongators = leaf_reference(rings, ratio, nested=hierarchy == "nested", supports=supports)
record = dict(smoother_setup_s=0.0, smoother_gb=0.0)
if kind != "block-gs":
    install(kind, shell, record)
linalg._available_memory = lambda: 1e12      # the full 18-vector hierarchy in every case
m = amg_cg_iterations(K, shell.block_layout(), options=dict(cycle="W"), prolongators=prolongators,
                      inspect=lambda amg: worst_mode(shell, K, amg))
print("ROW " + json.dumps(dict(rings=rings, n_triangles=int(shell.mesh.n_triangles), h_over_l=ratio,
                               smoother=kind, hierarchy=hierarchy, supports=supports, cg_its=m["its"],
                               reason=m["reason"],
                               setup_s=m["setup_s"], cg_s=m["cg_s"], levels=m["levels"], **record,
                               **{k: v for k, v in m.items() if k.startswith("mode_")})), flush=True)
"""


def main():
    from amg_cg import study
    study(__doc__, "amg_smoother.json",
          "AMG CG iterations to 1e-8 on the leaf's reference stiffness: finest-level smoothers", CHILD,
          [("rings", "rings", int, [45, 91], None), ("ratios", "h_over_l", float, [3.6, 7.3], None),
           ("smoothers", "smoother", str, SMOOTHERS, SMOOTHERS),
           ("hierarchies", "hierarchy", str, ["sa"], HIERARCHIES), ("supports", "supports", str, ["clamp"], SUPPORTS)])


if __name__ == "__main__":
    main()
