"""Numba assembly of the DKT shell energy, gradient and Hessian.

Element loop in parallel (prange over chunks of elements, one scratch per
chunk) writing per-element results; the scatter into the global gradient and
into the sparse Hessian (lower triangle of the free DOFs, CSR pattern built
once per mesh and constraint set) is serial.  Global DOFs of node n:
U[n, s, c], s = 0 position, 1 and 2 the derivatives along T_n1, T_n2.
"""

import numpy as np
from numba import njit, prange

from ..discretize.dkt import apply_map, element_chart, point_map
from .point import OK, _reference_geometry, new_scratch, point_kernel

N_CHUNK = 512


@njit(cache=True)
def _element_work():
    return (np.zeros((3, 3)), np.zeros((3, 3, 2)), np.zeros((3, 2, 2)), np.zeros((3, 2)),
            np.zeros((3, 2)), np.zeros(3), np.zeros((5, 9)), np.zeros((2, 9)),
            np.zeros((9, 3)), np.zeros((9, 3)), np.zeros(15), np.zeros(15),
            np.zeros((3, 3)), np.zeros((3, 3)), np.zeros((2, 3, 3)), np.zeros(3), np.zeros(3),
            np.zeros((2, 3)), np.zeros(15), np.zeros((15, 15)), np.zeros((15, 27)),
            np.zeros((3, 3)), np.zeros((2, 3)), np.zeros((2, 2, 3)), np.zeros((2, 3)),
            np.zeros((3, 3)), np.zeros((2, 3)))


@njit(cache=True)
def _element(e, mode, level, kind, psi, params, h, tri, X, T, U, bary, wts, G0n, G1n,
             qp, qm, has_load, Y1, Y2, ge, ke, sc, wk):
    """Energy of element e; ge (9, 3) and ke (27, 27) if mode asks. Returns (L, status)."""
    (Xe, Te, Q, gl, et, el, b, C, bref, bcur, ref, v, G0, G1, dG0, qb, m, dm, grad, hess,
     T15, gE, gLam, gdg, gna, gkap, gup) = wk
    n0, n1, n2 = tri[e, 0], tri[e, 1], tri[e, 2]
    nodes = (n0, n1, n2)
    for i in range(3):
        nd = nodes[i]
        for c in range(3):
            Xe[i, c] = X[nd, c]
            Te[i, c, 0] = T[nd, c, 0]
            Te[i, c, 1] = T[nd, c, 1]
            bref[3 * i, c] = X[nd, c]
            bref[3 * i + 1, c] = T[nd, c, 0]
            bref[3 * i + 2, c] = T[nd, c, 1]
            for s in range(3):
                bcur[3 * i + s, c] = U[nd, s, c]
    area = element_chart(Xe, Te, Q, gl, et, el)
    Le = 0.0
    if mode >= 1:
        for k in range(9):
            for c in range(3):
                ge[k, c] = 0.0
    if mode >= 2:
        for p in range(27):
            for q in range(27):
                ke[p, q] = 0.0
    for iq in range(bary.shape[0]):
        lam = bary[iq]
        point_map(lam, Q, gl, et, el, b, C)
        apply_map(b, bref, ref)
        apply_map(b, bcur, v)
        jx = ref[1] * ref[5] - ref[2] * ref[4]
        jy = ref[2] * ref[3] - ref[0] * ref[5]
        jz = ref[0] * ref[4] - ref[1] * ref[3]
        w = wts[iq] * area * np.sqrt(jx * jx + jy * jy + jz * jz)
        for r in range(3):
            for c in range(3):
                G0[r, c] = lam[0] * G0n[n0, r, c] + lam[1] * G0n[n1, r, c] + lam[2] * G0n[n2, r, c]
                G1[r, c] = lam[0] * G1n[n0, r, c] + lam[1] * G1n[n1, r, c] + lam[2] * G1n[n2, r, c]
                for a in range(2):
                    dG0[a, r, c] = (gl[0, a] * G0n[n0, r, c] + gl[1, a] * G0n[n1, r, c]
                                    + gl[2, a] * G0n[n2, r, c])
        for c in range(3):
            qb[c] = 0.0
            m[c] = 0.0
            dm[0, c] = 0.0
            dm[1, c] = 0.0
        if has_load:
            H, K, ok = _reference_geometry(ref, gE, gLam, gdg, gna, gkap, gup)
            mup = 1.0 - H * h + 0.25 * K * h * h      # mu(+h/2)
            mum = 1.0 + H * h + 0.25 * K * h * h      # mu(-h/2)
            for c in range(3):
                qpc = lam[0] * qp[n0, c] + lam[1] * qp[n1, c] + lam[2] * qp[n2, c]
                qmc = lam[0] * qm[n0, c] + lam[1] * qm[n1, c] + lam[2] * qm[n2, c]
                qb[c] = (mup * qpc + mum * qmc) / h
                m[c] = 0.5 * (mup * qpc - mum * qmc)
                for a in range(2):
                    dqp = gl[0, a] * qp[n0, c] + gl[1, a] * qp[n1, c] + gl[2, a] * qp[n2, c]
                    dqm = gl[0, a] * qm[n0, c] + gl[1, a] * qm[n1, c] + gl[2, a] * qm[n2, c]
                    dm[a, c] = 0.5 * (mup * dqp - mum * dqm)
        y1 = Y1[e, iq]
        y2 = Y2[e, iq]
        L, st = point_kernel(mode, level, kind, psi, params, h, v, ref, G0, G1, dG0, qb, m, dm,
                             y1, y2, grad, hess, sc)
        if st != OK:
            return np.nan, st
        Le += w * L
        if mode >= 1:
            for k in range(9):
                for c in range(3):
                    s = 0.0
                    for a in range(5):
                        s += b[a, k] * grad[3 * a + c]
                    ge[k, c] += w * s
        if mode >= 2:
            # T15 = H (b (x) I3): T15[(a,c), (k,c')] = sum_a' H[(a,c),(a',c')] b[a',k]
            for r in range(15):
                for k in range(9):
                    for c2 in range(3):
                        s = 0.0
                        for a2 in range(5):
                            s += hess[r, 3 * a2 + c2] * b[a2, k]
                        T15[r, 3 * k + c2] = s
            for k in range(9):
                for c in range(3):
                    row = 3 * k + c
                    for col in range(row, 27):
                        s = 0.0
                        for a in range(5):
                            s += b[a, k] * T15[3 * a + c, col]
                        ke[row, col] += w * s
    if mode >= 2:
        for row in range(27):
            for col in range(row):
                ke[row, col] = ke[col, row]
    return Le, OK


@njit(cache=True, parallel=True)
def assemble_dkt(mode, level, kind, psi, params, h, tri, X, T, U, bary, wts, G0n, G1n,
                 qp, qm, has_load, Y1, Y2, Le, Ge, Ke, status):
    """Element energies Le (E), gradients Ge (E, 9, 3), Hessians Ke (E, 27, 27).

    status[e] = point-kernel status of the first failing point (0: ok).
    """
    ne = tri.shape[0]
    nchunk = min(ne, N_CHUNK)
    for ch in prange(nchunk):
        sc = new_scratch()
        wk = _element_work()
        for e in range(ch * ne // nchunk, (ch + 1) * ne // nchunk):
            # Ge / Ke may be (1, ...) placeholders when not asked for
            Le[e], status[e] = _element(e, mode, level, kind, psi, params, h, tri, X, T, U,
                                        bary, wts, G0n, G1n, qp, qm, has_load, Y1, Y2,
                                        Ge[e if mode >= 1 else 0], Ke[e if mode >= 2 else 0],
                                        sc, wk)


@njit(cache=True)
def scatter_gradient(tri, Ge, out):
    """out (n, 3, 3) = sum of element gradients."""
    out[:] = 0.0
    for e in range(tri.shape[0]):
        for i in range(3):
            nd = tri[e, i]
            for s in range(3):
                for c in range(3):
                    out[nd, s, c] += Ge[e, 3 * i + s, c]


@njit(cache=True)
def scatter_hessian(Ke, emap, data):
    """data[emap[e, p, q]] += Ke[e, p, q] for emap >= 0 (free lower-triangle entries)."""
    data[:] = 0.0
    for e in range(Ke.shape[0]):
        for p in range(27):
            for q in range(p + 1):
                k = emap[e, p, q]
                if k >= 0:
                    data[k] += Ke[e, p, q]
