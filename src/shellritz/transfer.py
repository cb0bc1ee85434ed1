"""A solved state carried onto another mesh of the same reference surface
(``Shell.solve(start=result)``: nested iteration, a solve on a fine mesh that
starts from the equilibrium of a coarser one).

Each node p of the new mesh is located on the old reference mesh: the old
triangle whose plane holds its projection with the largest smallest
barycentric coordinate lambda (the nearest few triangles by centroid are
tried).  At the old nodes i the deformation gradient of the state is
``F_i = U_i1 T_i1^T + U_i2 T_i2^T + n_i N_i^T`` (U_ia the tangent derivatives
of the DKT state along the frame T_ia, n_i the unit normal of U_i1 x U_i2,
N_i the reference normal).  The new node gets

    r_p = sum_i lambda_i (r_i + (1/2) F_i (X_p - X_i)),
    U_pa = (sum_i lambda_i F_i) T_pa.

The first is the mean of the linear interpolant (which overestimates a
quadratic field by sum_i lambda_i d_i.C.d_i, d_i = X_p - X_i) and of the
Taylor expansions from the vertices (which underestimate it by the same
amount): on a flat reference exact for deformations quadratic in the
reference position, as the gradients are (tested); on a curved one the
normal offset of the new node from the old triangle's plane (of the order
l^2 / R) is carried by ``n_i N_i^T``.

The derivative of this map with respect to the old state
(interpolation_jacobian) is the prolongation of multigrid over the nested
meshes a solve started from (carry_over, linalg._geometric_hierarchy).
"""

import numpy as np
from scipy.spatial import cKDTree

CANDIDATES = 12        # old triangles tried per new node (nearest centroids)
OUTSIDE = 0.5          # a node may lie this far outside its old triangle (barycentric)


def deformation_gradients(shell, U):
    """F_i (n, 3, 3) of the state U at the nodes of ``shell`` (module docstring)."""
    T, N = shell.frames, shell.mesh.normals
    n = np.cross(U[:, 1], U[:, 2])
    n /= np.linalg.norm(n, axis=1)[:, None]
    return (np.einsum("nk,nj->nkj", U[:, 1], T[:, :, 0]) + np.einsum("nk,nj->nkj", U[:, 2], T[:, :, 1])
            + np.einsum("nk,nj->nkj", n, N))


def locate(X_old, tri_old, P):
    """For each point P: (old triangle, barycentric coordinates of its
    projection onto that triangle's plane, distance to the plane).  The
    triangle of the largest smallest coordinate among the CANDIDATES nearest
    centroids."""
    k = min(CANDIDATES, len(tri_old))
    _, cand = cKDTree(X_old[tri_old].mean(axis=1)).query(P, k=k)
    cand = cand.reshape(len(P), k)
    best = np.zeros(len(P), np.int64)
    lam = np.zeros((len(P), 3))
    dist = np.zeros(len(P))
    score = np.full(len(P), -np.inf)
    for j in range(k):
        t = tri_old[cand[:, j]]
        a = X_old[t[:, 0]]
        e1, e2, d = X_old[t[:, 1]] - a, X_old[t[:, 2]] - a, P - a
        g11, g12, g22 = (e1 * e1).sum(1), (e1 * e2).sum(1), (e2 * e2).sum(1)
        r1, r2 = (d * e1).sum(1), (d * e2).sum(1)
        det = g11 * g22 - g12 * g12
        l1, l2 = (g22 * r1 - g12 * r2) / det, (g11 * r2 - g12 * r1) / det
        lj = np.stack([1.0 - l1 - l2, l1, l2], axis=1)
        s = lj.min(axis=1)
        better = s > score
        score[better], best[better], lam[better] = s[better], cand[better, j], lj[better]
        dist[better] = np.linalg.norm(d - l1[:, None] * e1 - l2[:, None] * e2, axis=1)[better]
    return best, lam, dist, score


def carry_over(result, shell):
    """``result`` (a Result of a Shell on the same reference surface) carried
    onto ``shell`` (set up): (U, prolongators).  U (n, 3, 3) is its state
    interpolated onto ``shell``'s nodes.  The prolongators are those of the
    nested meshes below ``shell`` for multigrid (linalg.BlockLayout, finest
    first): from ``result``'s mesh, where it has at most half of ``shell``'s
    nodes, linearized at its state (interpolation_jacobian, values in single
    precision: half the memory, the hierarchy rounds them anyway), followed
    by the levels that ``result``'s shell started from; none otherwise.
    The new nodes are located once for both.  Raises ValueError naming the
    first node of ``shell`` that lies off the old reference mesh (outside
    its triangles by more than OUTSIDE in barycentric coordinates, or
    farther from their plane than their size)."""
    old, U_old = result.shell, _state_of(result)
    located = _located(old, shell)
    U = interpolate(old, U_old, shell, located)
    if 2 * old.mesh.n_nodes > shell.mesh.n_nodes:
        return U, ()
    P = interpolation_jacobian(old, U_old, shell, located)
    P.data = P.data.astype(np.float32)
    return U, (P, *old.prolongators)


def _state_of(result):
    """U (n, 3, 3) of a Result: positions and tangent derivatives."""
    U = np.concatenate([result.r[:, None], result.derivatives], axis=1)
    if not np.all(np.isfinite(U)):
        raise ValueError("start: the result's state has non-finite values")
    return U


def _located(old, shell):
    """(old triangle, barycentric coordinates) of each node of ``shell`` on
    the reference mesh of ``old`` (carry_over's error where a node
    lies off it)."""
    P = shell.X
    e, lam, dist, score = locate(old.X, old.mesh.triangles, P)
    size = np.sqrt(2.0 * old.mesh.areas[e])
    off = (score < -OUTSIDE) | (dist > size)
    if off.any():
        p = int(np.argmax(off))
        raise ValueError(f"start: node {p} at {P[p].tolist()} is not on the start's reference mesh "
                         f"(nearest triangle {int(e[p])}: barycentric {lam[p].round(3).tolist()}, "
                         f"{dist[p]:.3g} from its plane); start= needs a mesh of the same "
                         "reference surface")
    return e, lam


def interpolate(old, U_old, shell, located=None):
    """The state (n, 3, 3) of ``shell`` interpolated from the state
    ``U_old`` of the shell ``old`` (module docstring); ``located``: the
    new nodes' (old triangle, barycentric coordinates), if known (_located)."""
    e, lam = _located(old, shell) if located is None else located
    F_old = deformation_gradients(old, U_old)
    nodes = old.mesh.triangles[e]
    F = np.einsum("pi,pikj->pkj", lam, F_old[nodes])
    d = shell.X[:, None, :] - old.X[nodes]
    r = np.einsum("pi,pik->pk", lam, U_old[nodes, 0] + 0.5 * np.einsum("pikj,pij->pik", F_old[nodes], d))
    U = np.empty((len(shell.X), 3, 3))
    U[:, 0] = r
    U[:, 1] = np.einsum("pkj,pj->pk", F, shell.frames[:, :, 0])
    U[:, 2] = np.einsum("pkj,pj->pk", F, shell.frames[:, :, 1])
    return U


def interpolation_jacobian(old, U_old, shell, located=None):
    """d interpolate(old, U, shell) / dU at U_old: a BSR matrix
    (9 n_new, 9 n_old) of nodal 9 x 9 blocks (a node's DOFs (r, U_1, U_2),
    three per new node: the vertices of its old triangle), the prolongation
    of increments from ``old``'s mesh to ``shell``'s.  With
    n = U_1 x U_2 / |U_1 x U_2|,
    dF_i v = dU_i1 (T_i1.v) + dU_i2 (T_i2.v) + dn_i (N_i.v) and
    dn = (I - n n^T) (dU_1 x U_2 + U_1 x dU_2) / |U_1 x U_2|;
    ``located`` as in interpolate."""
    import scipy.sparse as sp
    e, lam = _located(old, shell) if located is None else located
    nodes = old.mesh.triangles[e]                              # (p, 3)
    T, N = old.frames, old.mesh.normals
    c = np.cross(U_old[:, 1], U_old[:, 2])
    s = np.linalg.norm(c, axis=1)
    n = c / s[:, None]
    Pi = (np.eye(3) - np.einsum("ik,il->ikl", n, n)) / s[:, None, None]
    dn_dU1 = -Pi @ _skew(U_old[:, 2])                          # dU_1 x U_2 = -[U_2]x dU_1
    dn_dU2 = Pi @ _skew(U_old[:, 1])

    def dF(v):
        """(p, 3, 3, 9): the matrices dF_i v (rows) of (dr, dU_1, dU_2)
        (columns) at the three old vertices, v (p, 3, 3) per vertex."""
        out = np.zeros(v.shape[:2] + (3, 9))
        eye = np.eye(3)
        along_n = np.einsum("pij,pij->pi", N[nodes], v)[..., None, None]
        for a, dn in ((0, dn_dU1), (1, dn_dU2)):
            along = np.einsum("pij,pij->pi", T[nodes, :, a], v)[..., None, None]
            out[..., 3 + 3 * a:6 + 3 * a] = along * eye + along_n * dn[nodes]
        return out
    B = np.zeros((len(e), 3, 9, 9))
    B[:, :, 0:3, 0:3] = np.eye(3)
    B[:, :, 0:3] += 0.5 * dF(shell.X[:, None, :] - old.X[nodes])
    for a in (1, 2):
        B[:, :, 3 * a:3 * a + 3] = dF(np.repeat(shell.frames[:, None, :, a - 1], 3, axis=1))
    B *= lam[:, :, None, None]
    J = sp.bsr_matrix((B.reshape(-1, 9, 9), nodes.reshape(-1), np.arange(0, 3 * len(e) + 1, 3)),
                      shape=(9 * len(e), 9 * len(old.X)))
    J.sort_indices()
    return J


def _skew(v):
    """[v]x (n, 3, 3): [v]x w = v x w."""
    S = np.zeros(v.shape[:-1] + (3, 3))
    S[..., 0, 1], S[..., 0, 2], S[..., 1, 2] = -v[..., 2], v[..., 1], -v[..., 0]
    return S - np.swapaxes(S, -1, -2)
