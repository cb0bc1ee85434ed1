"""Growth tensors from data: principal stretches with directions, target
fundamental forms (abar, bbar) per triangle, cell values to nodes.

The engine takes growth as ``G(Z) = G0 + Z G1`` (MODEL.md section 5), nodal
3x3 tensors in global components.  This module turns the other usual
descriptions into that form.

Target fundamental forms (the convention of libshell and of MorphoShell's
inputs): per triangle, the components (11, 12, 22) of the target first and
second fundamental forms ``abar``, ``bbar`` of the grown, stress-free middle
surface in the triangle's edge basis ``E1 = X1 - X0``, ``E2 = X2 - X0``, so
``abar_ij = (target length element) E_i . E_j``.  Derivation (README, section
"Growth from target fundamental forms"): a layer ``Z`` of the reference shell
has tangent vectors ``(1 - Z kappa) E_i`` (``kappa = -dn/dR``); growth maps
them to ``G(Z) (1 - Z kappa) E_i``, and the stress-free grown body is a shell
whose layers at distance ``Z`` have metric ``abar - 2 Z bbar + O(Z^2)``.
Matching orders 0 and 1 in ``Z`` in the orthonormal tangent basis ``(t1, t2)``
of the triangle, with ``e`` the 2x2 components of the edges
(``E = [t1 t2] e``):

    C    = e^-T abar e^-1            (target metric, orthonormal components)
    U    = C^(1/2)                   (symmetric square root)
    k    = e^-T b e^-1               (reference curvature, b_ij = -(N_i - N_0) . E_j)
    Bbar = e^-T bbar e^-1
    S    = -Bbar + (k C + C k) / 2
    G0   = T U T^T + n (x) n,   G1 = T U^-1 S T^T,   T = [t1 t2]

``G0`` keeps the normal (thickness) unchanged and ``G1 n = 0``; any rotation
``Q G`` gives the same energy for an isotropic law, and the symmetric choice
``U``, ``U^-1 S`` is the one without spin.  ``abar = a``, ``bbar = b`` (the
reference itself) gives ``G0 = I``, ``G1 = 0``.  The second-order terms of the
layer metric (``Z^2``) are not matched: a shell grown this way is stress free
to ``O(h^2)`` relative strain.
"""

import numpy as np

__all__ = ["from_stretches", "from_fundamental_forms", "cells_to_nodes"]


def _sym2(c, name):
    """(m, 3) components (11, 12, 22) -> (m, 2, 2) symmetric matrices."""
    c = np.asarray(c, dtype=np.float64)
    if c.ndim != 2 or c.shape[1] != 3:
        raise ValueError(f"{name}: expected cell data of shape (n_triangles, 3) with the "
                         f"components (11, 12, 22), got shape {c.shape}")
    bad = np.where(~np.all(np.isfinite(c), axis=1))[0]
    if len(bad):
        raise ValueError(f"{name}: non-finite values at triangles {bad[:8].tolist()}")
    M = np.empty((len(c), 2, 2))
    M[:, 0, 0], M[:, 0, 1], M[:, 1, 0], M[:, 1, 1] = c[:, 0], c[:, 1], c[:, 1], c[:, 2]
    return M


def _triangle_frames(X, tri):
    """Edge vectors E (m, 3, 2), unit normals n, orthonormal tangents T (m, 3, 2)
    with t1 along E1, and the edge components e (m, 2, 2): E = T e."""
    E = np.stack([X[tri[:, 1]] - X[tri[:, 0]], X[tri[:, 2]] - X[tri[:, 0]]], axis=2)
    n = np.cross(E[:, :, 0], E[:, :, 1])
    n /= np.linalg.norm(n, axis=1)[:, None]
    t1 = E[:, :, 0] / np.linalg.norm(E[:, :, 0], axis=1)[:, None]
    T = np.stack([t1, np.cross(n, t1)], axis=2)
    e = np.einsum("mci,mcj->mij", T, E)
    return E, n, T, e


def from_fundamental_forms(X, tri, normals, abar, bbar):
    """Per-triangle (G0, G1), each (m, 3, 3), from the target fundamental forms
    (cell data (m, 3) in the edge basis; module docstring).  ``normals``: the
    reference nodal normals (for the reference curvature b)."""
    A = _sym2(abar, "abar")
    Bt = _sym2(bbar, "bbar")
    m = len(tri)
    if len(A) != m or len(Bt) != m:
        raise ValueError(f"abar, bbar: expected one row per triangle ({m}), "
                         f"got {len(A)} and {len(Bt)}")
    det = A[:, 0, 0] * A[:, 1, 1] - A[:, 0, 1] ** 2
    bad = np.where((A[:, 0, 0] <= 0) | (det <= 0))[0]
    if len(bad):
        k = bad[0]
        raise ValueError(f"abar: not positive definite at triangles {bad[:8].tolist()} "
                         f"(triangle {k}: abar = {abar[k].tolist()}); a metric must be")
    E, n, T, e = _triangle_frames(X, tri)
    dN = np.stack([normals[tri[:, 1]] - normals[tri[:, 0]],
                   normals[tri[:, 2]] - normals[tri[:, 0]]], axis=2)
    b = -np.einsum("mci,mcj->mij", dN, E)
    b = 0.5 * (b + b.transpose(0, 2, 1))
    ei = np.linalg.inv(e)
    eiT = ei.transpose(0, 2, 1)
    C = eiT @ A @ ei
    k = eiT @ b @ ei
    Bbar = eiT @ Bt @ ei
    w, Q = np.linalg.eigh(C)
    U = Q @ (np.sqrt(w)[:, :, None] * Q.transpose(0, 2, 1))
    Ui = Q @ ((1.0 / np.sqrt(w))[:, :, None] * Q.transpose(0, 2, 1))
    S = -Bbar + 0.5 * (k @ C + C @ k)
    TT = T.transpose(0, 2, 1)
    G0 = T @ U @ TT + n[:, :, None] * n[:, None, :]
    G1 = T @ (Ui @ S) @ TT
    return G0, G1


def from_stretches(normals, stretches, gradients=None, direction=None, frames=None):
    """Nodal (G0, G1) from principal growth stretches (MODEL.md section 5):
    ``G0 = g1 d1 (x) d1 + g2 d2 (x) d2 + gn n (x) n`` and ``G1`` the same with
    the through-thickness gradients, ``d1`` = ``direction`` projected on the
    tangent plane (default: the first nodal frame vector), ``d2 = n x d1``.

    ``stretches``, ``gradients``: (n, 3) nodal values; ``direction``: (n, 3)."""
    N = np.asarray(normals, dtype=np.float64)
    n = len(N)
    g = np.asarray(stretches, dtype=np.float64).reshape(n, 3)
    gz = np.zeros((n, 3)) if gradients is None else np.asarray(gradients, dtype=np.float64).reshape(n, 3)
    if direction is None:
        d1 = frames[:, :, 0].copy()
    else:
        d = np.asarray(direction, dtype=np.float64).reshape(n, 3)
        d1 = d - np.einsum("ij,ij->i", d, N)[:, None] * N
        length = np.linalg.norm(d1, axis=1)
        bad = np.where(~(length > 1e-8 * np.maximum(np.linalg.norm(d, axis=1), 1e-300)))[0]
        if len(bad):
            raise ValueError(f"direction: parallel to the surface normal (or zero) at nodes "
                             f"{bad[:8].tolist()} (node {bad[0]}: direction {d[bad[0]].tolist()}, "
                             f"normal {N[bad[0]].tolist()})")
        d1 /= length[:, None]
    d2 = np.cross(N, d1)
    basis = (d1, d2, N)
    G0 = sum(g[:, k, None, None] * basis[k][:, :, None] * basis[k][:, None, :] for k in range(3))
    G1 = sum(gz[:, k, None, None] * basis[k][:, :, None] * basis[k][:, None, :] for k in range(3))
    return G0, G1


def cells_to_nodes(mesh, values):
    """Area-weighted average of per-triangle values (m, ...) at the nodes."""
    values = np.asarray(values, dtype=np.float64)
    w = mesh.areas
    out = np.zeros((mesh.n_nodes,) + values.shape[1:])
    wsum = np.zeros(mesh.n_nodes)
    wv = w.reshape((-1,) + (1,) * (values.ndim - 1)) * values
    for k in range(3):
        np.add.at(out, mesh.triangles[:, k], wv)
        np.add.at(wsum, mesh.triangles[:, k], w)
    return out / wsum.reshape((-1,) + (1,) * (values.ndim - 1))
