"""The strain-gradient term of strain_gradient.py on DKT triangles.

In the orthonormal coordinates xi of an element's flat facet (discretize/dkt.py)
the membrane strain has the components e_ab = (r_a . r_b - R_a . R_b) / 2; the
term is

    R_e = C_R int_e sum_abcd (d2 e_ab / dxi_c dxi_d)^2 dA,
    d2 e_ab / dxi_c dxi_d = (r_acd . r_b + r_ac . r_bd + r_ad . r_bc + r_a . r_bcd) / 2 - (same of R),

with r_a, r_ab the DKT fields at the quadrature points and r_abc = d r_ab /
dxi_c, constant in the element (r_ab is linear in the barycentric
coordinates: the sum over the vertices of grad(lambda_i) times r_ab there).
Each component is a bilinear form in the element's 9 nodal 3-vectors X,
Q = X : M X - X_ref : M X_ref, evaluated as (X - X_ref) : M (X + X_ref) so
that it vanishes exactly at the reference; dQ/dX = 2 M X, d2Q/dX2 = 2 M (x) I3,
so R_e, its gradient and Hessian are exact.  Only the element interiors are
measured (no jump terms across edges, which would couple the two
triangles of an edge beyond the Hessian pattern; docs/validity.md says what
that leaves).
"""

import numpy as np
from numba import njit, prange

from ..discretize.dkt import element_chart, point_map
from . import KERNEL

# symmetric index pairs (a, b) -> 0: 11, 1: 12, 2: 22, and their multiplicities
_PAIR = ((0, 0), (0, 1), (1, 1))
_MULT = (1.0, 2.0, 1.0)


@njit(**KERNEL, inline="always")
def _pair(a, b):
    return a + b


@njit(cache=True)
def _work():
    return (np.zeros((3, 3)), np.zeros((3, 3, 2)), np.zeros((3, 2, 2)), np.zeros((3, 2)),
            np.zeros((3, 2)), np.zeros(3), np.zeros((5, 9)), np.zeros((2, 9)),
            np.zeros((9, 3)), np.zeros((9, 3)), np.zeros((9, 3)),   # X - Xref, X + Xref, X
            np.zeros((3, 2, 9)),                                    # D3[ab, c]: r_abc coefficients
            np.zeros((5, 9)), np.zeros(3),                          # vertex map, barycentric
            np.zeros((2, 3)), np.zeros((2, 3)), np.zeros((3, 2, 3)), np.zeros((3, 2, 3)),  # r_a, r_abc (d, s)
            np.zeros((3, 3)), np.zeros((3, 3)),                     # r_ab (d, s)
            np.zeros((9, 9)), np.zeros((9, 3)))                     # M, dQ/dX


@njit(**KERNEL, inline="always")
def _dot(u, v):
    return u[0] * v[0] + u[1] * v[1] + u[2] * v[2]


@njit(**KERNEL, inline="always")
def _sym_add(M, cu, cv, f):
    """M += f (cu cv^T + cv cu^T) / 2 for coefficient rows cu, cv (9)."""
    for k in range(9):
        for l in range(9):
            M[k, l] += 0.5 * f * (cu[k] * cv[l] + cv[k] * cu[l])


@njit(**KERNEL)
def element_strain_gradient(e, mode, C, tri, X, T, U, bary, wts, ge, ke, wk):
    """R_e of element e; ge (9, 3) and the upper triangle of ke (27, 27) if
    mode asks (overwritten)."""
    (Xe, Te, Q, gl, et, el, b, Cw, Xd, Xs, Xc, D3, bv, lam, r1d, r1s, r3d, r3s, r2d, r2s,
     M, dQ) = wk
    for i in range(3):
        nd = tri[e, i]
        for c in range(3):
            Xe[i, c] = X[nd, c]
            Te[i, c, 0] = T[nd, c, 0]
            Te[i, c, 1] = T[nd, c, 1]
            ref = (X[nd, c], T[nd, c, 0], T[nd, c, 1])
            for s in range(3):
                Xc[3 * i + s, c] = U[nd, s, c]
                Xd[3 * i + s, c] = U[nd, s, c] - ref[s]
                Xs[3 * i + s, c] = U[nd, s, c] + ref[s]
    area = element_chart(Xe, Te, Q, gl, et, el)
    # r_abc = sum_i gl[i, c] r_ab(vertex i)
    for p in range(3):
        for c in range(2):
            for k in range(9):
                D3[p, c, k] = 0.0
    for i in range(3):
        lam[0], lam[1], lam[2] = 0.0, 0.0, 0.0
        lam[i] = 1.0
        point_map(lam, Q, gl, et, el, bv, Cw)
        for p in range(3):
            for c in range(2):
                for k in range(9):
                    D3[p, c, k] += gl[i, c] * bv[2 + p, k]
    for p in range(3):
        for c in range(2):
            for j in range(3):
                sd = 0.0
                ss = 0.0
                for k in range(9):
                    sd += D3[p, c, k] * Xd[k, j]
                    ss += D3[p, c, k] * Xs[k, j]
                r3d[p, c, j] = sd
                r3s[p, c, j] = ss
    if mode >= 1:
        for k in range(9):
            for c in range(3):
                ge[k, c] = 0.0
    if mode >= 2:
        for p in range(27):
            for q in range(27):
                ke[p, q] = 0.0
    Re = 0.0
    for iq in range(bary.shape[0]):
        point_map(bary[iq], Q, gl, et, el, b, Cw)
        w = C * wts[iq] * area
        for j in range(3):
            for a in range(2):
                sd = 0.0
                ss = 0.0
                for k in range(9):
                    sd += b[a, k] * Xd[k, j]
                    ss += b[a, k] * Xs[k, j]
                r1d[a, j] = sd
                r1s[a, j] = ss
            for p in range(3):
                sd = 0.0
                ss = 0.0
                for k in range(9):
                    sd += b[2 + p, k] * Xd[k, j]
                    ss += b[2 + p, k] * Xs[k, j]
                r2d[p, j] = sd
                r2s[p, j] = ss
        for pab in range(3):
            a, bb = _PAIR[pab]
            for pcd in range(3):
                c, d = _PAIR[pcd]
                ac, bd, ad, bc = _pair(a, c), _pair(bb, d), _pair(a, d), _pair(bb, c)
                # Q = (r_acd.r_b + r_ac.r_bd + r_ad.r_bc + r_a.r_bcd)/2, each product
                # u.v - U.V = (u(Xd).v(Xs) + u(Xs).v(Xd))/2
                val = 0.25 * (_dot(r3d[ac, d], r1s[bb]) + _dot(r3s[ac, d], r1d[bb])
                              + _dot(r2d[ac], r2s[bd]) + _dot(r2s[ac], r2d[bd])
                              + _dot(r2d[ad], r2s[bc]) + _dot(r2s[ad], r2d[bc])
                              + _dot(r1d[a], r3s[bc, d]) + _dot(r1s[a], r3d[bc, d]))
                f = w * _MULT[pab] * _MULT[pcd]
                Re += f * val * val
                if mode == 0:
                    continue
                for k in range(9):
                    for l in range(9):
                        M[k, l] = 0.0
                _sym_add(M, D3[ac, d], b[bb], 0.5)
                _sym_add(M, b[2 + ac], b[2 + bd], 0.5)
                _sym_add(M, b[2 + ad], b[2 + bc], 0.5)
                _sym_add(M, b[a], D3[bc, d], 0.5)
                for k in range(9):
                    for j in range(3):
                        s = 0.0
                        for l in range(9):
                            s += M[k, l] * Xc[l, j]
                        dQ[k, j] = 2.0 * s
                        ge[k, j] += 2.0 * f * val * dQ[k, j]
                if mode < 2:
                    continue
                for p in range(27):
                    kp, jp = p // 3, p % 3
                    for q in range(p, 27):
                        kq, jq = q // 3, q % 3
                        h = dQ[kp, jp] * dQ[kq, jq]
                        if jp == jq:
                            h += 2.0 * val * M[kp, kq]
                        ke[p, q] += 2.0 * f * h
    return Re


@njit(cache=True, parallel=True)
def add_dkt_strain_gradient(mode, C, tri, X, T, U, bary, wts, order, colour_start, emap,
                            n_threads, Re, Le, G, data):
    """R_e of every element into Re (overwritten) and added to the element
    energies Le; for mode >= 1 the gradient added to G (n, 3, 3), for mode >= 2
    the Hessian to data (the DKT assembly's CSR values, positions emap).
    Local DOF 9 i + 3 s + c of the element's node i is U[node, s, c], the same
    layout as kernels/assembly.py; colours as there (no race)."""
    for c in range(colour_start.shape[0] - 1):
        first = colour_start[c]
        n = colour_start[c + 1] - first
        nchunk = min(n, 4 * n_threads)
        for ch in prange(nchunk):
            wk = _work()
            ge = np.zeros((9, 3))
            ke = np.zeros((27, 27))
            for j in range(first + ch * n // nchunk, first + (ch + 1) * n // nchunk):
                e = order[j]
                Re[e] = element_strain_gradient(e, mode, C, tri, X, T, U, bary, wts, ge, ke, wk)
                Le[e] += Re[e]
                if mode >= 1:
                    for i in range(3):
                        nd = tri[e, i]
                        for s in range(3):
                            for k in range(3):
                                G[nd, s, k] += ge[3 * i + s, k]
                if mode >= 2:
                    k = 0
                    for p in range(27):
                        for q in range(p + 1):
                            pos = emap[e, k]
                            if pos >= 0:
                                data[pos] += ke[q, p]
                            k += 1
