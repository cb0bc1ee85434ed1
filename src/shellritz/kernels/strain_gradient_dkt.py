"""The strain-gradient term of strain_gradient.py on DKT triangles.

In the orthonormal coordinates xi of an element's flat facet (discretize/dkt.py)
the elastic membrane strain has the components e_ab = (r_a . r_b - u_a . u_b) / 2,
u_a = G0 R_a the grown reference tangents (G0 interpolated linearly from the
nodes, as the point kernel does); the term is

    R_e = C_R int_e sum_abcd (d2 e_ab / dxi_c dxi_d)^2 dA,
    d2 (r_a . r_b) / dxi_c dxi_d = r_acd . r_b + r_ac . r_bd + r_ad . r_bc + r_a . r_bcd,

with r_a, r_ab the DKT fields at the quadrature points and r_abc = d r_ab /
dxi_c, constant in the element (r_ab is linear in the barycentric
coordinates: the sum over the vertices of grad(lambda_i) times r_ab there).
Each component is a bilinear form in the element's 9 nodal 3-vectors X less a
constant, Q = X : M X - X_ref : M X_ref - s, evaluated as (X - X_ref) : M (X +
X_ref) - s so that it vanishes exactly at the reference when there is no
growth (s = the same derivatives of u_a . u_b - R_a . R_b);
dQ/dX = 2 M X, d2Q/dX2 = 2 M (x) I3, so R_e, its gradient and Hessian are exact.  Only the element interiors are
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
            np.zeros((9, 9)), np.zeros((9, 3)),                     # M, dQ/dX
            np.zeros((9, 3)))                                       # X_ref


@njit(**KERNEL, inline="always")
def _dot(u, v):
    return u[0] * v[0] + u[1] * v[1] + u[2] * v[2]


@njit(**KERNEL, inline="always")
def _sym_add(M, cu, cv, f):
    """M += f (cu cv^T + cv cu^T) / 2 for coefficient rows cu, cv (9)."""
    for k in range(9):
        for l in range(9):
            M[k, l] += 0.5 * f * (cu[k] * cv[l] + cv[k] * cu[l])


@njit(**KERNEL, inline="always")
def _mv(G, x, out):
    for i in range(3):
        out[i] = G[i, 0] * x[0] + G[i, 1] * x[1] + G[i, 2] * x[2]


@njit(**KERNEL)
def _grown(G0n, tri, e, lam, gl, b, D3, Xr, gw, second):
    """Grown reference tangents at a point and their xi-derivatives (first,
    and second if asked), with and without growth: gw = (G, dG (2, 3, 3),
    R_a (2, 3), R_ab (3, 3), R_abc (3, 2, 3), u (2, 3), du (2, 2, 3),
    ddu (2, 2, 2, 3), tmp (3)); dG0 is constant in the element (linear
    interpolation), so d2 u_a = dG_c R_ad + dG_d R_ac + G R_acd."""
    G, dG, Ra, Rab, Rabc, u, du, ddu, tmp = gw
    for r in range(3):
        for c in range(3):
            # relative to node 0, so that equal nodal values give G0 and dG0 = 0 exactly
            g0 = G0n[tri[e, 0], r, c]
            G[r, c] = g0
            dG[0, r, c] = 0.0
            dG[1, r, c] = 0.0
            for i in range(1, 3):
                g = G0n[tri[e, i], r, c] - g0
                G[r, c] += lam[i] * g
                dG[0, r, c] += gl[i, 0] * g
                dG[1, r, c] += gl[i, 1] * g
    for j in range(3):
        for a in range(2):
            acc = 0.0
            for k in range(9):
                acc += b[a, k] * Xr[k, j]
            Ra[a, j] = acc
        for p in range(3):
            acc = 0.0
            for k in range(9):
                acc += b[2 + p, k] * Xr[k, j]
            Rab[p, j] = acc
            if second:
                for c in range(2):
                    acc = 0.0
                    for k in range(9):
                        acc += D3[p, c, k] * Xr[k, j]
                    Rabc[p, c, j] = acc
    for a in range(2):
        _mv(G, Ra[a], u[a])
        for c in range(2):
            _mv(dG[c], Ra[a], tmp)
            _mv(G, Rab[_pair(a, c)], du[a, c])
            for j in range(3):
                du[a, c, j] += tmp[j]
            if second:
                for d in range(2):
                    _mv(G, Rabc[_pair(a, c), d], ddu[a, c, d])
                    _mv(dG[c], Rab[_pair(a, d)], tmp)
                    for j in range(3):
                        ddu[a, c, d, j] += tmp[j]
                    _mv(dG[d], Rab[_pair(a, c)], tmp)
                    for j in range(3):
                        ddu[a, c, d, j] += tmp[j]


@njit(**KERNEL, inline="always")
def _shift_q(gw, a, b, c):
    """(d_c (u_a . u_b) - d_c (R_a . R_b)) / 2."""
    Ra, Rab, u, du = gw[2], gw[3], gw[5], gw[6]
    return 0.5 * ((_dot(du[a, c], u[b]) + _dot(u[a], du[b, c]))
                  - (_dot(Rab[_pair(a, c)], Ra[b]) + _dot(Ra[a], Rab[_pair(b, c)])))


@njit(**KERNEL, inline="always")
def _shift_Q(gw, a, b, c, d):
    """(d_cd (u_a . u_b) - d_cd (R_a . R_b)) / 2."""
    Ra, Rab, Rabc, u, du, ddu = gw[2], gw[3], gw[4], gw[5], gw[6], gw[7]
    grown = (_dot(ddu[a, c, d], u[b]) + _dot(du[a, c], du[b, d]) + _dot(du[a, d], du[b, c])
             + _dot(u[a], ddu[b, c, d]))
    ref = (_dot(Rabc[_pair(a, c), d], Ra[b]) + _dot(Rab[_pair(a, c)], Rab[_pair(b, d)])
           + _dot(Rab[_pair(a, d)], Rab[_pair(b, c)]) + _dot(Ra[a], Rabc[_pair(b, c), d]))
    return 0.5 * (grown - ref)


@njit(cache=True)
def _growth_work():
    return (np.zeros((3, 3)), np.zeros((2, 3, 3)), np.zeros((2, 3)), np.zeros((3, 3)),
            np.zeros((3, 2, 3)), np.zeros((2, 3)), np.zeros((2, 2, 3)), np.zeros((2, 2, 2, 3)),
            np.zeros(3))


@njit(**KERNEL)
def element_strain_gradient(e, mode, C, tri, X, T, U, G0n, bary, wts, ge, ke, wk, gw):
    """R_e of element e; ge (9, 3) and the upper triangle of ke (27, 27) if
    mode asks (overwritten).  G0n: nodal growth G0 (n, 3, 3)."""
    (Xe, Te, Q, gl, et, el, b, Cw, Xd, Xs, Xc, D3, bv, lam, r1d, r1s, r3d, r3s, r2d, r2s,
     M, dQ, Xr) = wk
    for i in range(3):
        nd = tri[e, i]
        for c in range(3):
            Xe[i, c] = X[nd, c]
            Te[i, c, 0] = T[nd, c, 0]
            Te[i, c, 1] = T[nd, c, 1]
            ref = (X[nd, c], T[nd, c, 0], T[nd, c, 1])
            for s in range(3):
                Xr[3 * i + s, c] = ref[s]
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
        _grown(G0n, tri, e, bary[iq], gl, b, D3, Xr, gw, True)
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
                val -= _shift_Q(gw, a, bb, c, d)
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
def add_dkt_strain_gradient(mode, C, tri, X, T, U, G0n, bary, wts, order, colour_start, emap,
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
            gw = _growth_work()
            ge = np.zeros((9, 3))
            ke = np.zeros((27, 27))
            for j in range(first + ch * n // nchunk, first + (ch + 1) * n // nchunk):
                e = order[j]
                Re[e] = element_strain_gradient(e, mode, C, tri, X, T, U, G0n, bary, wts, ge, ke,
                                                wk, gw)
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


# ---------------------------------------------------------------------------
# jumps across interior edges
# ---------------------------------------------------------------------------
#
# At the edge Gauss points the first derivatives q_abc = d e_ab / dxi_c of
# both triangles are taken to the common edge frame (t, nu) (t along the edge,
# nu in the mean tangent plane): q_(alpha beta gamma) = sum_abc q_abc
# (E_a.e_alpha) (E_b.e_beta) (E_c.e_gamma), E_a the facet basis.  R_E =
# sum_points w |q^1 - q^2|^2, w = C_R wg l_E / h_E (h_E = (A_1 + A_2) / l_E):
# the interior-penalty part of the same seminorm.  The Hessian couples the
# four nodes of the two triangles (strain_gradient.DKTStrainGradient adds the
# pair of opposite vertices to the pattern).

@njit(cache=True)
def _edge_work():
    return (np.zeros((3, 3)), np.zeros((3, 3, 2)), np.zeros((3, 2, 2)), np.zeros((3, 2)),
            np.zeros((3, 2)), np.zeros(3), np.zeros((5, 9)), np.zeros((2, 9)),
            np.zeros((9, 3)), np.zeros((9, 3)), np.zeros((9, 3)),
            np.zeros((2, 3)), np.zeros((2, 3)), np.zeros((3, 3)), np.zeros((3, 3)),
            np.zeros((2, 3)),                  # 15 facet basis E_a
            np.zeros((2, 8)),                  # 16 projected q of both sides
            np.zeros((2, 8, 9, 3)),            # 17 their derivatives in the nodal vectors
            np.zeros((2, 8, 9, 9)),            # 18 M_abc of both sides (index 4 a + 2 b + c)
            np.zeros((2, 8, 8)),               # 19 projections P[side, c, abc]
            np.zeros((2, 9, 3)),               # 20 gradient per side
            np.zeros((36, 36)),                # 21 Hessian on the edge-node DOFs
            np.zeros((9, 9)),                  # 22 jump-weighted sum of M_abc
            np.zeros((9, 3)),                  # 23 X_ref
            np.zeros((3, 2, 9)))               # 24 (no third derivatives at edges)


@njit(**KERNEL)
def _side(e, lam, frame, tri, X, T, U, G0n, wk, gw, s):
    """Projected first derivatives of the strain (8) of triangle e at the
    barycentric point lam, their derivatives in the element's 9 nodal vectors,
    the matrices M_abc and the projection: slot s of wk[16:20]."""
    Xe, Te, Q, gl, et, el, b, Cw = wk[0], wk[1], wk[2], wk[3], wk[4], wk[5], wk[6], wk[7]
    Xd, Xs, Xc, r1d, r1s, r2d, r2s, Ef = wk[8], wk[9], wk[10], wk[11], wk[12], wk[13], wk[14], wk[15]
    val, dval, Ms, Ps, Xr = wk[16], wk[17], wk[18], wk[19], wk[23]
    for i in range(3):
        nd = tri[e, i]
        for c in range(3):
            Xe[i, c] = X[nd, c]
            Te[i, c, 0] = T[nd, c, 0]
            Te[i, c, 1] = T[nd, c, 1]
            ref = (X[nd, c], T[nd, c, 0], T[nd, c, 1])
            for k in range(3):
                Xr[3 * i + k, c] = ref[k]
                Xc[3 * i + k, c] = U[nd, k, c]
                Xd[3 * i + k, c] = U[nd, k, c] - ref[k]
                Xs[3 * i + k, c] = U[nd, k, c] + ref[k]
    element_chart(Xe, Te, Q, gl, et, el)
    # facet basis E_1 = (X_1 - X_0)/|.|, E_2 = n x E_1 (as element_chart)
    a0, a1, a2 = Xe[1, 0] - Xe[0, 0], Xe[1, 1] - Xe[0, 1], Xe[1, 2] - Xe[0, 2]
    b0, b1, b2 = Xe[2, 0] - Xe[0, 0], Xe[2, 1] - Xe[0, 1], Xe[2, 2] - Xe[0, 2]
    la = np.sqrt(a0 * a0 + a1 * a1 + a2 * a2)
    n0, n1, n2 = a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0
    ln = np.sqrt(n0 * n0 + n1 * n1 + n2 * n2)
    Ef[0, 0], Ef[0, 1], Ef[0, 2] = a0 / la, a1 / la, a2 / la
    Ef[1, 0] = (n1 * Ef[0, 2] - n2 * Ef[0, 1]) / ln
    Ef[1, 1] = (n2 * Ef[0, 0] - n0 * Ef[0, 2]) / ln
    Ef[1, 2] = (n0 * Ef[0, 1] - n1 * Ef[0, 0]) / ln
    point_map(lam, Q, gl, et, el, b, Cw)
    _grown(G0n, tri, e, lam, gl, b, wk[24], Xr, gw, False)
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
    for cc in range(8):
        val[s, cc] = 0.0
        for k in range(9):
            for j in range(3):
                dval[s, cc, k, j] = 0.0
    for a in range(2):
        for bb in range(2):
            for c in range(2):
                m = 4 * a + 2 * bb + c
                ac, bc = _pair(a, c), _pair(bb, c)
                # q_abc = (r_ac.r_b + r_a.r_bc) / 2, products polarized as in the interior
                qv = 0.25 * (_dot(r2d[ac], r1s[bb]) + _dot(r2s[ac], r1d[bb])
                             + _dot(r1d[a], r2s[bc]) + _dot(r1s[a], r2d[bc])) - _shift_q(gw, a, bb, c)
                Mm = Ms[s, m]
                for k in range(9):
                    for l in range(9):
                        Mm[k, l] = 0.0
                _sym_add(Mm, b[2 + ac], b[bb], 0.5)
                _sym_add(Mm, b[a], b[2 + bc], 0.5)
                for al in range(2):
                    pa = _dot(Ef[a], frame[al])
                    for be in range(2):
                        pb = _dot(Ef[bb], frame[be])
                        for ga in range(2):
                            Ps[s, 4 * al + 2 * be + ga, m] = pa * pb * _dot(Ef[c], frame[ga])
                for k in range(9):
                    for j in range(3):
                        mx = 0.0
                        for l in range(9):
                            mx += Mm[k, l] * Xc[l, j]
                        for cc in range(8):
                            dval[s, cc, k, j] += 2.0 * Ps[s, cc, m] * mx
                for cc in range(8):
                    val[s, cc] += Ps[s, cc, m] * qv


@njit(**KERNEL)
def edge_strain_gradient(j, mode, C, tri, X, T, U, G0n, edge_tri, edge_lam, edge_w, edge_frame,
                         edge_node, wk, gw):
    """R_E of interior edge j; the gradient per side into wk[20] (2, 9, 3) and
    the lower triangle of the Hessian on the edge-node DOFs (9 A + 3 slot +
    component, A = edge_node[j, side, i] of the side's node i) into wk[21]."""
    val, dval, Ms, Ps, gs, Hn, Mw = wk[16], wk[17], wk[18], wk[19], wk[20], wk[21], wk[22]
    if mode >= 1:
        for s in range(2):
            for k in range(9):
                for jj in range(3):
                    gs[s, k, jj] = 0.0
    if mode >= 2:
        for p in range(36):
            for q in range(36):
                Hn[p, q] = 0.0
    RE = 0.0
    for g in range(edge_lam.shape[2]):
        for s in range(2):
            _side(edge_tri[j, s], edge_lam[j, s, g], edge_frame[j], tri, X, T, U, G0n, wk, gw, s)
        w = C * edge_w[j, g]
        for cc in range(8):
            J = val[0, cc] - val[1, cc]
            RE += w * J * J
        if mode == 0:
            continue
        for s in range(2):
            sg = 1.0 if s == 0 else -1.0
            for k in range(9):
                for jj in range(3):
                    acc = 0.0
                    for cc in range(8):
                        acc += (val[0, cc] - val[1, cc]) * dval[s, cc, k, jj]
                    gs[s, k, jj] += 2.0 * w * sg * acc
        if mode < 2:
            continue
        for s1 in range(2):
            # jump-weighted second derivatives of this side: sum_c J_c P_c,abc 2 M_abc
            sg1 = 1.0 if s1 == 0 else -1.0
            for k in range(9):
                for l in range(9):
                    Mw[k, l] = 0.0
            for m in range(8):
                om = 0.0
                for cc in range(8):
                    om += (val[0, cc] - val[1, cc]) * Ps[s1, cc, m]
                for k in range(9):
                    for l in range(9):
                        Mw[k, l] += 2.0 * sg1 * om * Ms[s1, m, k, l]
            for k1 in range(9):
                A = edge_node[j, s1, k1 // 3]
                for j1 in range(3):
                    P1 = 9 * A + 3 * (k1 % 3) + j1
                    for s2 in range(2):
                        sg = sg1 * (1.0 if s2 == 0 else -1.0)
                        for k2 in range(9):
                            B = edge_node[j, s2, k2 // 3]
                            for j2 in range(3):
                                P2 = 9 * B + 3 * (k2 % 3) + j2
                                if P2 > P1:
                                    continue
                                acc = 0.0
                                for cc in range(8):
                                    acc += dval[s1, cc, k1, j1] * dval[s2, cc, k2, j2]
                                h2 = sg * acc
                                if s1 == s2 and j1 == j2:
                                    h2 += Mw[k1, k2]
                                Hn[P1, P2] += 2.0 * w * h2
    return RE


@njit(cache=True, parallel=True)
def add_dkt_edge_strain_gradient(mode, C, tri, X, T, U, G0n, edge_tri, edge_lam, edge_w,
                                 edge_frame, edge_node, edge_local, edge_oo, order, colour_start,
                                 emap, RE, G, data):
    """The edge terms into RE (per edge, overwritten), G (n, 3, 3) and data.
    edge_local[j, A, s]: local index of edge node A in the triangle of side s
    (-1: not in it); edge_oo[j, a, b]: data position of DOF a of the first
    side's opposite vertex and DOF b of the second's (-1: fixed).  Edges are
    coloured (no shared node within a colour)."""
    for c in range(colour_start.shape[0] - 1):
        first = colour_start[c]
        n = colour_start[c + 1] - first
        nchunk = min(n, 64)
        for ch in prange(nchunk):
            wk = _edge_work()
            gw = _growth_work()
            for jo in range(first + ch * n // nchunk, first + (ch + 1) * n // nchunk):
                j = order[jo]
                RE[j] = edge_strain_gradient(j, mode, C, tri, X, T, U, G0n, edge_tri, edge_lam,
                                             edge_w, edge_frame, edge_node, wk, gw)
                if mode >= 1:
                    gs = wk[20]
                    for s in range(2):
                        for i in range(3):
                            nd = tri[edge_tri[j, s], i]
                            for k in range(3):
                                for cc in range(3):
                                    G[nd, k, cc] += gs[s, 3 * i + k, cc]
                if mode >= 2:
                    Hn = wk[21]
                    for P1 in range(36):
                        A, a = P1 // 9, P1 % 9
                        for P2 in range(P1 + 1):
                            B, b = P2 // 9, P2 % 9
                            found = False
                            pos = -1
                            for s in range(2):
                                la, lb = edge_local[j, A, s], edge_local[j, B, s]
                                if not found and la >= 0 and lb >= 0:
                                    p, q = 9 * la + a, 9 * lb + b
                                    if p < q:
                                        p, q = q, p
                                    pos = emap[edge_tri[j, s], p * (p + 1) // 2 + q]
                                    found = True
                            if not found:      # the two opposite vertices (A = 3 > B)
                                pos = edge_oo[j, b, a]
                            if pos >= 0:
                                data[pos] += Hn[P1, P2]
