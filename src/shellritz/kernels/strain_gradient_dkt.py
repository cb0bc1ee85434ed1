"""The strain-gradient term of strain_gradient.py on DKT triangles.

In the coordinates xi of an element's flat facet (discretize/dkt.py) the
elastic membrane strain is e_ab = (a_ab - g_ab) / 2 with a_ab = r_a . r_b and
the grown metric g_ab = u_a . u_b, u_a = G0 R_a (G0 interpolated linearly from
the nodes, as the point kernel does).  The term measures its covariant
derivatives (Levi-Civita connection of the reference metric A_ab = R_a . R_b:
Christoffel symbols from R_ab . R_c, their derivatives from R_abc):

    element:  C_R int_e |grad grad e|^2 dA           (components in an orthonormal frame)
    edge:     C_R (l_E / h_E) sum_points w |[grad e]|^2   (both sides in the edge frame)

so that a uniform strain on a curved surface (a parallel tensor, e.g. the
growing cylinder) gives zero.  The building blocks are the chart derivatives
of a_ab up to second order,

    P0 = a_ab,  P1 = d_c a_ab = r_ac.r_b + r_a.r_bc,
    P2 = d_cd a_ab = r_acd.r_b + r_ac.r_bd + r_ad.r_bc + r_a.r_bcd,

(r_a, r_ab the DKT fields at the point; r_abc = d r_ab / dxi_c is constant in
the element, r_ab being linear in the barycentric coordinates) less the same
of g_ab; each covariant component is a fixed linear combination of them.  A
block is a bilinear form in the element's 9 nodal 3-vectors X, P = X : M X,
evaluated as (X - X_ref) : M (X + X_ref) less its growth part, so that it
vanishes exactly at the reference without growth; dP/dX = 2 M X and
d2P/dX2 = 2 M (x) I3: energy, gradient and Hessian are exact.
"""

import numpy as np
from numba import njit

from ..discretize.dkt import element_chart, gather_element, point_map
from . import KERNEL
from .parallel import run_chunks
from .assembly import add_block, scatter_element, zero_element

NP1 = 9           # blocks P0 (3) and P1 (6): first covariant derivatives
NP2 = 18          # and P2 (9): second
N_PRODUCTS = 51   # products u.v making the blocks: 3 (P0) + 12 (P1) + 36 (P2)
N_BASIS = 11      # coefficient rows of u, v: b[0:5] (r_a, r_ab), D3[p, c] (r_abc)
N_T = 12          # distinct orthonormal components of grad grad e (element_strain_gradient)
SQRT2 = np.sqrt(2.0)


@njit(**KERNEL, inline="always")
def _pair(a, b):
    return a + b                      # symmetric pair index: 00 -> 0, 01 -> 1, 11 -> 2


@njit(**KERNEL, inline="always")
def _i0(a, b):
    return _pair(a, b)


@njit(**KERNEL, inline="always")
def _i1(a, b, c):
    return 3 + 2 * _pair(a, b) + c


@njit(**KERNEL, inline="always")
def _i2(a, b, c, d):
    return 9 + 3 * _pair(a, b) + _pair(c, d)


@njit(**KERNEL, inline="always")
def _dot(u, v):
    return u[0] * v[0] + u[1] * v[1] + u[2] * v[2]


@njit(**KERNEL, inline="always")
def _mv(G, x, out):
    for i in range(3):
        out[i] = G[i, 0] * x[0] + G[i, 1] * x[1] + G[i, 2] * x[2]


@njit(**KERNEL, inline="always")
def _apply(row, Xb, out):
    """out = sum_k row[k] Xb[k] (a 3-vector from the 9 nodal vectors)."""
    for j in range(3):
        s = 0.0
        for k in range(9):
            s += row[k] * Xb[k, j]
        out[j] = s


@njit(cache=True)
def _work():
    """Work arrays of one element, or of one side of an edge (see _blocks)."""
    return (np.zeros((3, 3)), np.zeros((3, 3, 2)), np.zeros((3, 2, 2)), np.zeros((3, 2)),   # 0-3 Xe Te Q gl
            np.zeros((3, 2)), np.zeros(3), np.zeros((5, 9)), np.zeros((2, 9)),              # 4-7 et el b Cw
            np.zeros((9, 3)), np.zeros((9, 3)), np.zeros((9, 3)), np.zeros((9, 3)),         # 8-11 Xd Xs Xc Xr
            np.zeros((3, 2, 9)), np.zeros((5, 9)), np.zeros(3),                             # 12-14 D3 bv lam
            np.zeros((5, 3)), np.zeros((5, 3)), np.zeros((5, 3)), np.zeros((5, 3)),         # 15-18 vd vs vc vR
            np.zeros((3, 2, 3)), np.zeros((3, 2, 3)), np.zeros((3, 2, 3)), np.zeros((3, 2, 3)),  # 19-22 3rd derivs
            np.zeros((3, 3)), np.zeros((2, 3, 3)),                                          # 23-24 G dG
            np.zeros((2, 3)), np.zeros((2, 2, 3)), np.zeros((2, 2, 2, 3)), np.zeros(3),     # 25-28 u du ddu tmp
            np.zeros(NP2), np.zeros((NP2, 9, 3)), np.zeros((N_BASIS, N_BASIS)),             # 29-31 P dP Wt
            np.zeros((2, 2)), np.zeros((2, 2, 2)), np.zeros((2, 2, 2, 2)), np.zeros((2, 2)),  # 32-35 Ainv Gam dGam L
            np.zeros((2, 3)), np.zeros((2, 2)),                                             # 36-37 g^a, dA^-1
            np.zeros((2, 2, 2, NP2)), np.zeros(NP2), np.zeros((16, NP2)),                   # 38-40 k1 k2 chi
            np.zeros(16), np.zeros((16, 9, 3)), np.zeros((9, 9)),                           # 41-43 val dval Mw
            np.zeros((N_PRODUCTS, 3), np.int64), np.zeros(1, np.int64),                     # 44-45 products
            np.zeros(NP2), np.zeros((N_BASIS, 9)), np.zeros((N_BASIS, 9)))                  # 46-48 om Bas T


@njit(**KERNEL)
def _load_element(e, tri, X, T, U, wk):
    """Nodal blocks X - Xref, X + Xref, X, Xref of element e and its facet chart;
    returns the facet area."""
    Xe, Te, Q, gl, et, el = wk[0], wk[1], wk[2], wk[3], wk[4], wk[5]
    Xd, Xs, Xc, Xr = wk[8], wk[9], wk[10], wk[11]
    gather_element(e, tri, X, T, U, Xe, Te, Xr, Xc)
    for k in range(9):
        for c in range(3):
            Xd[k, c] = Xc[k, c] - Xr[k, c]
            Xs[k, c] = Xc[k, c] + Xr[k, c]
    return element_chart(Xe, Te, Q, gl, et, el)


@njit(**KERNEL)
def _third_derivative_map(wk):
    """D3[ab, c] (coefficients on the 9 nodal vectors): r_abc = sum_i gl[i, c]
    r_ab(vertex i)."""
    Q, gl, et, el, Cw, D3, bv, lam = wk[2], wk[3], wk[4], wk[5], wk[7], wk[12], wk[13], wk[14]
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
    Bas = wk[47]
    for p in range(3):
        for c in range(2):
            for k in range(9):
                Bas[_basis_row(p, c), k] = D3[p, c, k]


@njit(**KERNEL)
def _product(wk, idx, iu, iv, ud, us, uc, uR, vd, vs, vc, vR, ug, vg, mode):
    """Block idx += u.v for two linear maps with coefficient rows cu = Bas[iu],
    cv = Bas[iv] (their vectors of X - Xref (d), X + Xref (s), X (c), Xref (R))
    less the growth part ug.vg - uR.vR; gradient cu (x) v + cv (x) u.  The
    second derivative, M_idx += (cu cv^T + cv cu^T)/2 (x) I3, is not formed:
    the product is listed and _weighted_M sums the weighted M_idx at once."""
    P, dP, Bas = wk[29], wk[30], wk[47]
    cu, cv = Bas[iu], Bas[iv]
    P[idx] += 0.5 * (_dot(ud, vs) + _dot(us, vd)) - (_dot(ug, vg) - _dot(uR, vR))
    if mode >= 1:
        for k in range(9):
            for j in range(3):
                dP[idx, k, j] += cu[k] * vc[j] + cv[k] * uc[j]
    if mode >= 2:
        tab, n = wk[44], wk[45]
        tab[n[0], 0] = idx
        tab[n[0], 1] = iu
        tab[n[0], 2] = iv
        n[0] += 1


@njit(**KERNEL, inline="always")
def _basis_row(p, c):
    """Row of Bas holding D3[p, c] (rows 0-4 are b[0:5])."""
    return 5 + 2 * p + c


@njit(**KERNEL)
def _blocks(e, lam, tri, G0n, mode, second, wk):
    """The blocks P0, P1 (and P2 if second) at the barycentric point lam of
    the loaded element, and the reference geometry there: A^-1, the
    Christoffel symbols Gam[c, a, d] = Gamma^d_ca (and dGam[e, c, a, d] =
    d_e Gamma^d_ca), L with L^T A L = I, the dual basis g^a."""
    Q, gl, et, el, b, Cw, D3 = wk[2], wk[3], wk[4], wk[5], wk[6], wk[7], wk[12]
    Xd, Xs, Xc, Xr = wk[8], wk[9], wk[10], wk[11]
    vd, vs, vc, vR = wk[15], wk[16], wk[17], wk[18]        # rows: r_1, r_2, r_11, r_12, r_22
    td, ts, tc, tR = wk[19], wk[20], wk[21], wk[22]        # r_abc
    G, dG, u, du, ddu, tmp = wk[23], wk[24], wk[25], wk[26], wk[27], wk[28]
    P, dP = wk[29], wk[30]
    Ainv, Gam, dGam, L, gup, dAi = wk[32], wk[33], wk[34], wk[35], wk[36], wk[37]
    point_map(lam, Q, gl, et, el, b, Cw)
    Bas = wk[47]
    for r in range(5):
        for k in range(9):
            Bas[r, k] = b[r, k]
    wk[45][0] = 0
    for p in range(NP2):
        P[p] = 0.0
        if mode >= 1:
            for k in range(9):
                for j in range(3):
                    dP[p, k, j] = 0.0
    for r in range(5):
        _apply(b[r], Xd, vd[r])
        _apply(b[r], Xs, vs[r])
        _apply(b[r], Xc, vc[r])
        _apply(b[r], Xr, vR[r])
    if second:
        for p in range(3):
            for c in range(2):
                _apply(D3[p, c], Xd, td[p, c])
                _apply(D3[p, c], Xs, ts[p, c])
                _apply(D3[p, c], Xc, tc[p, c])
                _apply(D3[p, c], Xr, tR[p, c])
    # growth at the point, relative to node 0 (equal nodal values give dG = 0 exactly)
    for r in range(3):
        for c in range(3):
            g0 = G0n[tri[e, 0], r, c]
            G[r, c] = g0
            dG[0, r, c] = 0.0
            dG[1, r, c] = 0.0
            for i in range(1, 3):
                g = G0n[tri[e, i], r, c] - g0
                G[r, c] += lam[i] * g
                dG[0, r, c] += gl[i, 0] * g
                dG[1, r, c] += gl[i, 1] * g
    # grown tangents u_a = G R_a and their derivatives (dG constant in the element)
    for a in range(2):
        _mv(G, vR[a], u[a])
        for c in range(2):
            _mv(dG[c], vR[a], tmp)
            _mv(G, vR[2 + _pair(a, c)], du[a, c])
            for j in range(3):
                du[a, c, j] += tmp[j]
            if second:
                for d in range(2):
                    _mv(G, tR[_pair(a, c), d], ddu[a, c, d])
                    _mv(dG[c], vR[2 + _pair(a, d)], tmp)
                    for j in range(3):
                        ddu[a, c, d, j] += tmp[j]
                    _mv(dG[d], vR[2 + _pair(a, c)], tmp)
                    for j in range(3):
                        ddu[a, c, d, j] += tmp[j]
    for a in range(2):
        for bb in range(a, 2):
            _product(wk, _i0(a, bb), a, bb, vd[a], vs[a], vc[a], vR[a],
                     vd[bb], vs[bb], vc[bb], vR[bb], u[a], u[bb], mode)
            for c in range(2):
                ac, bc = 2 + _pair(a, c), 2 + _pair(bb, c)
                i1 = _i1(a, bb, c)
                _product(wk, i1, ac, bb, vd[ac], vs[ac], vc[ac], vR[ac],
                         vd[bb], vs[bb], vc[bb], vR[bb], du[a, c], u[bb], mode)
                _product(wk, i1, a, bc, vd[a], vs[a], vc[a], vR[a],
                         vd[bc], vs[bc], vc[bc], vR[bc], u[a], du[bb, c], mode)
                if not second:
                    continue
                for d in range(c, 2):
                    ad, bd = 2 + _pair(a, d), 2 + _pair(bb, d)
                    pac, pbc = ac - 2, bc - 2
                    i2 = _i2(a, bb, c, d)
                    _product(wk, i2, _basis_row(pac, d), bb, td[pac, d],
                             ts[pac, d], tc[pac, d], tR[pac, d],
                             vd[bb], vs[bb], vc[bb], vR[bb], ddu[a, c, d], u[bb], mode)
                    _product(wk, i2, ac, bd, vd[ac], vs[ac], vc[ac], vR[ac],
                             vd[bd], vs[bd], vc[bd], vR[bd], du[a, c], du[bb, d], mode)
                    _product(wk, i2, ad, bc, vd[ad], vs[ad], vc[ad], vR[ad],
                             vd[bc], vs[bc], vc[bc], vR[bc], du[a, d], du[bb, c], mode)
                    _product(wk, i2, a, _basis_row(pbc, d), vd[a], vs[a],
                             vc[a], vR[a], td[pbc, d], ts[pbc, d], tc[pbc, d], tR[pbc, d], u[a],
                             ddu[bb, c, d], mode)
    # reference metric, dual basis, orthonormalizing L = C^-T (A = C C^T)
    A00, A01, A11 = _dot(vR[0], vR[0]), _dot(vR[0], vR[1]), _dot(vR[1], vR[1])
    det = A00 * A11 - A01 * A01
    Ainv[0, 0], Ainv[0, 1], Ainv[1, 0], Ainv[1, 1] = A11 / det, -A01 / det, -A01 / det, A00 / det
    for a in range(2):
        for j in range(3):
            gup[a, j] = Ainv[a, 0] * vR[0, j] + Ainv[a, 1] * vR[1, j]
    c00 = np.sqrt(A00)
    c10 = A01 / c00
    c11 = np.sqrt(A11 - c10 * c10)
    L[0, 0], L[0, 1], L[1, 0], L[1, 1] = 1.0 / c00, -c10 / (c00 * c11), 0.0, 1.0 / c11
    # Gamma^d_ca = A^{db} R_ca . R_b
    for c in range(2):
        for a in range(2):
            for d in range(2):
                Rca = vR[2 + _pair(c, a)]
                Gam[c, a, d] = Ainv[d, 0] * _dot(Rca, vR[0]) + Ainv[d, 1] * _dot(Rca, vR[1])
    if not second:
        return
    # d_e Gamma^d_ca = d_e A^{db} Gamma_{ca,b} + A^{db} (R_cae . R_b + R_ca . R_be),
    # d_e A^{db} = -A^{dg} (R_eg . R_h + R_g . R_eh) A^{hb}
    for ee in range(2):
        for g in range(2):
            for hh in range(2):
                s = 0.0
                for p in range(2):
                    for q in range(2):
                        dA = _dot(vR[2 + _pair(ee, p)], vR[q]) + _dot(vR[p], vR[2 + _pair(ee, q)])
                        s -= Ainv[g, p] * dA * Ainv[q, hh]
                dAi[g, hh] = s
        for c in range(2):
            for a in range(2):
                Rca = vR[2 + _pair(c, a)]
                for d in range(2):
                    s = 0.0
                    for bb in range(2):
                        s += dAi[d, bb] * _dot(Rca, vR[bb])
                        s += Ainv[d, bb] * (_dot(tR[_pair(c, a), ee], vR[bb])
                                            + _dot(Rca, vR[2 + _pair(bb, ee)]))
                    dGam[ee, c, a, d] = s


@njit(**KERNEL)
def _kappa1(wk):
    """k1[a, b, c] (NP2): grad_c a_ab = P1[ab,c] - Gamma^f_ca P0[fb] - Gamma^f_cb P0[af]."""
    Gam, k1 = wk[33], wk[38]
    for a in range(2):
        for bb in range(2):
            for c in range(2):
                row = k1[a, bb, c]
                for p in range(NP2):
                    row[p] = 0.0
                row[_i1(a, bb, c)] += 1.0
                for f in range(2):
                    row[_i0(f, bb)] -= Gam[c, a, f]
                    row[_i0(a, f)] -= Gam[c, bb, f]


@njit(**KERNEL)
def _kappa2(a, bb, c, d, wk):
    """k2 (NP2): grad_d grad_c a_ab = d_d(grad_c a_ab) - Gamma^g_dc grad_g a_ab
    - Gamma^g_da grad_c a_gb - Gamma^g_db grad_c a_ag."""
    Gam, dGam, k1, out = wk[33], wk[34], wk[38], wk[39]
    for p in range(NP2):
        out[p] = 0.0
    out[_i2(a, bb, c, d)] += 1.0
    for f in range(2):
        out[_i0(f, bb)] -= dGam[d, c, a, f]
        out[_i1(f, bb, d)] -= Gam[c, a, f]
        out[_i0(a, f)] -= dGam[d, c, bb, f]
        out[_i1(a, f, d)] -= Gam[c, bb, f]
    for g in range(2):
        for p in range(NP2):
            out[p] -= (Gam[d, c, g] * k1[a, bb, g, p] + Gam[d, a, g] * k1[g, bb, c, p]
                       + Gam[d, bb, g] * k1[a, g, c, p])


@njit(**KERNEL)
def _components(ncomp, nblock, mode, wk):
    """val[t] = chi[t] . P / 2 (the covariant components of e) and, if mode
    asks, dval[t] = chi[t] . dP / 2 (9, 3); chi[t] is zero beyond nblock."""
    P, dP, chi, val, dval = wk[29], wk[30], wk[40], wk[41], wk[42]
    for t in range(ncomp):
        s = 0.0
        for p in range(nblock):
            s += chi[t, p] * P[p]
        val[t] = 0.5 * s
        if mode >= 1:
            for k in range(9):
                for j in range(3):
                    s = 0.0
                    for p in range(nblock):
                        s += chi[t, p] * dP[p, k, j]
                    dval[t, k, j] = 0.5 * s


@njit(**KERNEL)
def _weighted_M(ncomp, nbasis, weights, wk):
    """Mw = sum_t weights[t] (chi[t] . M) / 2: the second derivative of
    sum_t weights_t val_t is 2 Mw (x) I3.  With om = sum_t weights_t chi[t]
    and the listed products n (block idx_n, basis rows u_n, v_n; _product),
    Mw = sum_n om[idx_n] (c_u c_v^T + c_v c_u^T) / 4 = Bas^T Wt Bas on the
    first nbasis basis rows (5 when the blocks stop at P1)."""
    Wt, chi, Mw = wk[31], wk[40], wk[43]
    tab, n, om, Bas, T = wk[44], wk[45], wk[46], wk[47], wk[48]
    for p in range(NP2):
        s = 0.0
        for t in range(ncomp):
            s += weights[t] * chi[t, p]
        om[p] = s
    for u in range(nbasis):
        for v in range(nbasis):
            Wt[u, v] = 0.0
    for r in range(n[0]):
        w = 0.25 * om[tab[r, 0]]
        Wt[tab[r, 1], tab[r, 2]] += w
        Wt[tab[r, 2], tab[r, 1]] += w
    for u in range(nbasis):
        for l in range(9):
            s = 0.0
            for v in range(nbasis):
                s += Wt[u, v] * Bas[v, l]
            T[u, l] = s
    for k in range(9):
        for l in range(k, 9):
            s = 0.0
            for u in range(nbasis):
                s += Bas[u, k] * T[u, l]
            Mw[k, l] = s
            Mw[l, k] = s


# ---------------------------------------------------------------------------
# element interiors
# ---------------------------------------------------------------------------

@njit(**KERNEL)
def element_strain_gradient(e, mode, C, tri, X, T, U, G0n, bary, wts, ge, ke, wk):
    """R_e of element e; ge (9, 3) and the upper triangle of ke (27, 27) if
    mode asks (overwritten).  G0n: nodal growth G0 (n, 3, 3)."""
    L, chi, k2, val, dval, Mw = wk[35], wk[40], wk[39], wk[41], wk[42], wk[43]
    area = _load_element(e, tri, X, T, U, wk)
    _third_derivative_map(wk)
    zero_element(mode, ge, ke)
    Re = 0.0
    for iq in range(bary.shape[0]):
        _blocks(e, bary[iq], tri, G0n, mode, True, wk)
        _kappa1(wk)
        for t in range(N_T):
            for p in range(NP2):
                chi[t, p] = 0.0
        # orthonormal components T_IJKL = L_aI L_bJ L_cK L_dL grad_d grad_c e_ab;
        # T_IJKL = T_JIKL (e is symmetric), so |T|^2 sums IJ = 00, 11 once and
        # IJ = 01 twice: component t = (IJ = 00 | 01 | 11, K, L) is scaled by
        # sqrt(2) for IJ = 01 and the sums below run over N_T = 12 unweighted.
        for a in range(2):
            for bb in range(2):
                for c in range(2):
                    for d in range(2):
                        _kappa2(a, bb, c, d, wk)
                        for t in range(N_T):
                            ij = t // 4
                            I, J, K_, Lq = ij // 2, (ij + 1) // 2, (t // 2) % 2, t % 2
                            f = L[a, I] * L[bb, J] * L[c, K_] * L[d, Lq]
                            if ij == 1:
                                f *= SQRT2
                            if f != 0.0:
                                for p in range(NP2):
                                    chi[t, p] += f * k2[p]
        _components(N_T, NP2, mode, wk)
        w = C * wts[iq] * area
        for t in range(N_T):
            Re += w * val[t] * val[t]
        if mode == 0:
            continue
        for t in range(N_T):
            for k in range(9):
                for j in range(3):
                    ge[k, j] += 2.0 * w * val[t] * dval[t, k, j]
        if mode < 2:
            continue
        _weighted_M(N_T, N_BASIS, val, wk)
        # Gauss-Newton part sum_t dval_t dval_t^T as axpys over contiguous
        # rows (upper triangle), then the second-derivative part 2 Mw (x) I3
        D = dval.reshape((dval.shape[0], 27))         # a view, (k, j) -> 3 k + j
        for p in range(27):
            kep = ke[p]
            for t in range(N_T):
                a = 2.0 * w * D[t, p]
                if a != 0.0:
                    Dt = D[t]
                    for q in range(p, 27):
                        kep[q] += a * Dt[q]
        for kp in range(9):
            for kq in range(kp, 9):
                m = 4.0 * w * Mw[kp, kq]
                for j in range(3):
                    ke[3 * kp + j, 3 * kq + j] += m
    return Re


def add_dkt_strain_gradient(mode, C, active, tri, X, T, U, G0n, bary, wts, order, colour_start,
                            hmap, Re, Le, G, data):
    """R_e of every active element into Re (overwritten; 0 elsewhere) and added to the element
    energies Le; for mode >= 1 the gradient added to G (n, 3, 3), for mode >= 2
    the Hessian to data (the DKT assembly's CSR values, positions hmap).
    Local DOF 9 i + 3 s + c of the element's node i is U[node, s, c], as in
    kernels/assembly.py; colours as there (no race), in parallel chunks."""
    for c in range(colour_start.shape[0] - 1):
        run_chunks(_add_elements, colour_start[c], colour_start[c + 1], mode, C, active, tri, X,
                   T, U, G0n, bary, wts, order, hmap, Re, Le, G, data)


@njit(cache=True, nogil=True)
def _add_elements(lo, hi, mode, C, active, tri, X, T, U, G0n, bary, wts, order, hmap, Re, Le, G,
                  data):
    """The elements order[lo:hi] of add_dkt_strain_gradient."""
    wk = _work()
    ge = np.zeros((9, 3))
    ke = np.zeros((27, 27))
    for j in range(lo, hi):
        e = order[j]
        if not active[e]:
            Re[e] = 0.0
            continue
        Re[e] = element_strain_gradient(e, mode, C, tri, X, T, U, G0n, bary, wts, ge, ke, wk)
        Le[e] += Re[e]
        scatter_element(e, mode, tri, ge, ke, hmap, G, data)


# ---------------------------------------------------------------------------
# jumps across interior edges
# ---------------------------------------------------------------------------
#
# At the edge Gauss points the first covariant derivatives of e on both
# sides, taken to the common edge frame (t, nu): q_(alpha beta gamma) =
# grad_c e_ab (g^a.e_alpha)(g^b.e_beta)(g^c.e_gamma).  R_E = sum_points w
# |q^1 - q^2|^2, w = C_R wg l_E / h_E (h_E = (A_1 + A_2) / l_E): the
# interior-penalty part of the same seminorm.  The Hessian couples the four
# nodes of the two triangles (strain_gradient.DKTStrainGradient adds the pair
# of opposite vertices to the pattern).

@njit(**KERNEL)
def _edge_side(e, lam, frame, tri, G0n, mode, wk):
    """Projected first covariant derivatives (8) of the strain of triangle e
    (loaded into wk) at lam, into val[:8] / dval[:8] of wk; chi[:8] keeps
    their combination."""
    gup, k1, chi = wk[36], wk[38], wk[40]
    _blocks(e, lam, tri, G0n, mode, False, wk)
    _kappa1(wk)
    for t in range(8):
        al, be, ga = t // 4, (t // 2) % 2, t % 2
        for p in range(NP2):
            chi[t, p] = 0.0
        for a in range(2):
            pa = _dot(gup[a], frame[al])
            for bb in range(2):
                pb = _dot(gup[bb], frame[be])
                for c in range(2):
                    f = pa * pb * _dot(gup[c], frame[ga])
                    for p in range(NP1):
                        chi[t, p] += f * k1[a, bb, c, p]
    _components(8, NP1, mode, wk)


@njit(cache=True)
def _edge_work():
    return _work(), _work(), np.zeros(8), np.zeros((36, 36)), np.zeros((2, 9, 3)), np.zeros((8, 36))


@njit(**KERNEL)
def edge_strain_gradient(j, mode, C, tri, X, T, U, G0n, edge_tri, edge_lam, edge_w, edge_frame,
                         edge_node, ew):
    """R_E of interior edge j; the gradient per side into ew[4] (2, 9, 3) and
    the lower triangle of the Hessian on the edge-node DOFs (9 A + 3 slot +
    component, A = edge_node[j, side, i] of the side's node i) into ew[3]."""
    wA, wB, J, Hn, gs, Dn = ew
    sides = (wA, wB)
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
    _load_element(edge_tri[j, 0], tri, X, T, U, wA)
    _load_element(edge_tri[j, 1], tri, X, T, U, wB)
    for g in range(edge_lam.shape[2]):
        _edge_side(edge_tri[j, 0], edge_lam[j, 0, g], edge_frame[j], tri, G0n, mode, wA)
        _edge_side(edge_tri[j, 1], edge_lam[j, 1, g], edge_frame[j], tri, G0n, mode, wB)
        w = C * edge_w[j, g]
        for t in range(8):
            J[t] = wA[41][t] - wB[41][t]
            RE += w * J[t] * J[t]
        if mode == 0:
            continue
        for s in range(2):
            sg = 1.0 if s == 0 else -1.0
            dval = sides[s][42]
            for k in range(9):
                for jj in range(3):
                    acc = 0.0
                    for t in range(8):
                        acc += J[t] * dval[t, k, jj]
                    gs[s, k, jj] += 2.0 * w * sg * acc
        if mode < 2:
            continue
        # d J_t on the edge-node DOFs: Dn = dval(side A) - dval(side B)
        for t in range(8):
            for P1 in range(36):
                Dn[t, P1] = 0.0
        for s1 in range(2):
            sg1 = 1.0 if s1 == 0 else -1.0
            d1 = sides[s1][42]
            for k1 in range(9):
                o1 = 9 * edge_node[j, s1, k1 // 3] + 3 * (k1 % 3)
                for j1 in range(3):
                    for t in range(8):
                        Dn[t, o1 + j1] += sg1 * d1[t, k1, j1]
        for P1 in range(36):
            for P2 in range(P1 + 1):
                acc = 0.0
                for t in range(8):
                    acc += Dn[t, P1] * Dn[t, P2]
                Hn[P1, P2] += 2.0 * w * acc
        for s1 in range(2):
            sg1 = 1.0 if s1 == 0 else -1.0
            wk1 = sides[s1]
            _weighted_M(8, 5, J, wk1)       # sum_t J_t d2 val_t = 2 Mw (x) I3 (this side)
            Mw = wk1[43]
            for k1 in range(9):
                o1 = 9 * edge_node[j, s1, k1 // 3] + 3 * (k1 % 3)
                for k2 in range(9):
                    o2 = 9 * edge_node[j, s1, k2 // 3] + 3 * (k2 % 3)
                    if o2 > o1:
                        continue
                    for j1 in range(3):
                        Hn[o1 + j1, o2 + j1] += 4.0 * w * sg1 * Mw[k1, k2]
    return RE


@njit(**KERNEL, inline="always")
def _edge_node_id(j, A, tri, edge_tri, edge_local):
    """The node of edge node A of interior edge j (from a side that has it)."""
    s = 0 if edge_local[j, A, 0] >= 0 else 1
    return tri[edge_tri[j, s], edge_local[j, A, s]]


def add_dkt_edge_strain_gradient(mode, C, tri, X, T, U, G0n, edge_tri, edge_lam, edge_w,
                                 edge_frame, edge_node, edge_local, edge_oo, order, colour_start,
                                 hmap, RE, G, data):
    """The edge terms into RE (per edge, overwritten), G (n, 3, 3) and data.
    edge_local[j, A, s]: local index of edge node A in the triangle of side s
    (-1: not in it); edge_oo[j]: the block offset of the two opposite
    vertices (hmap: kernels/assembly.hessian_pattern).
    Edges are coloured (no shared node within a colour), in parallel chunks."""
    for c in range(colour_start.shape[0] - 1):
        run_chunks(_add_edges, colour_start[c], colour_start[c + 1], mode, C, tri, X, T, U, G0n,
                   edge_tri, edge_lam, edge_w, edge_frame, edge_node, edge_local, edge_oo, order,
                   hmap, RE, G, data)


@njit(cache=True, nogil=True)
def _add_edges(lo, hi, mode, C, tri, X, T, U, G0n, edge_tri, edge_lam, edge_w, edge_frame,
               edge_node, edge_local, edge_oo, order, hmap, RE, G, data):
    """The edges order[lo:hi] of add_dkt_edge_strain_gradient."""
    ew = _edge_work()
    eoff = hmap[3]
    for jo in range(lo, hi):
        j = order[jo]
        RE[j] = edge_strain_gradient(j, mode, C, tri, X, T, U, G0n, edge_tri, edge_lam,
                                     edge_w, edge_frame, edge_node, ew)
        if mode >= 1:
            gs = ew[4]
            for s in range(2):
                for i in range(3):
                    nd = tri[edge_tri[j, s], i]
                    for k in range(3):
                        for cc in range(3):
                            G[nd, k, cc] += gs[s, 3 * i + k, cc]
        if mode >= 2:
            Hn = ew[3]
            for A in range(4):
                for B in range(A + 1):
                    off = edge_oo[j]               # the two opposite vertices (A = 3 > B)
                    for s in range(2):
                        la, lb = edge_local[j, A, s], edge_local[j, B, s]
                        if la >= 0 and lb >= 0:
                            off = eoff[edge_tri[j, s], la, lb]
                            break
                    add_block(hmap, _edge_node_id(j, A, tri, edge_tri, edge_local),
                              _edge_node_id(j, B, tri, edge_tri, edge_local), off,
                              Hn[9 * A:9 * A + 9, 9 * B:9 * B + 9], 9, False, A == B, 1.0, data)
