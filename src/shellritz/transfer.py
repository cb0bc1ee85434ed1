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


def interpolate_state(result, shell):
    """The state ``U`` (n, 3, 3) of ``shell`` (set up) interpolated from
    ``result`` (a Result of a Shell on the same reference surface).  Raises
    ValueError naming the first node of ``shell`` that lies off the old
    reference mesh (outside its triangles by more than OUTSIDE in
    barycentric coordinates, or farther from their plane than their size)."""
    old = result.shell
    U_old = np.concatenate([result.r[:, None], result.derivatives], axis=1)
    if not np.all(np.isfinite(U_old)):
        raise ValueError("start: the result's state has non-finite values")
    tri = old.mesh.triangles
    P = shell.X
    e, lam, dist, score = locate(old.X, tri, P)
    size = np.sqrt(2.0 * old.mesh.areas[e])
    off = (score < -OUTSIDE) | (dist > size)
    if off.any():
        p = int(np.argmax(off))
        raise ValueError(f"start: node {p} at {P[p].tolist()} is not on the start's reference mesh "
                         f"(nearest triangle {int(e[p])}: barycentric {lam[p].round(3).tolist()}, "
                         f"{dist[p]:.3g} from its plane); start= needs a mesh of the same "
                         "reference surface")
    F_old = deformation_gradients(old, U_old)
    nodes = tri[e]
    F = np.einsum("pi,pikj->pkj", lam, F_old[nodes])
    d = P[:, None, :] - old.X[nodes]
    r = np.einsum("pi,pik->pk", lam, U_old[nodes, 0] + 0.5 * np.einsum("pikj,pij->pik", F_old[nodes], d))
    U = np.empty((len(P), 3, 3))
    U[:, 0] = r
    U[:, 1] = np.einsum("pkj,pj->pk", F, shell.frames[:, :, 0])
    U[:, 2] = np.einsum("pkj,pj->pk", F, shell.frames[:, :, 1])
    return U
