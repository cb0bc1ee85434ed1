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

The products u.v making the blocks are listed (the basis rows of u and v:
u = Bas[iu] . X).  The gradient of a weighted sum of blocks, om . P, is
never formed block by block: with the vectors V = Bas . X of the point,
d(om . P)/dX = 2 Bas^T Z(om), Z(om)[iu] += om[idx] V[iv] / 2 and
Z(om)[iv] += om[idx] V[iu] / 2 over the listed products (_gradient_of):
the gradient of the energy is one such map (om = sum_t val_t chi_t).  The
Hessian's Gauss-Newton part needs the gradient of every component: there
the blocks' gradients are formed once from the same list and combined by
contiguous axpys (_component_gradients).
"""

import numpy as np
from numba import njit

from ..discretize.dkt import element_chart, gather_element, point_map
from . import KERNEL
from .parallel import run_chunks
from .assembly import add_block, scatter_element, zero_element
from .small import fma

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
            np.zeros((9, 3)), np.zeros((9, 3)), np.zeros((9, 3)),                           # 8-10 Xd Xc Xr
            np.zeros((3, 2, 9)), np.zeros((5, 9)), np.zeros(3),                             # 11-13 D3 bv lam
            np.zeros((5, 3)), np.zeros((5, 3)), np.zeros((5, 3)),                           # 14-16 vd vs vR
            np.zeros((3, 2, 3)), np.zeros((3, 2, 3)), np.zeros((3, 2, 3)),                  # 17-19 td ts tR
            np.zeros((3, 3)), np.zeros((2, 3, 3)),                                          # 20-21 G dG
            np.zeros((2, 3)), np.zeros((2, 2, 3)), np.zeros((2, 2, 2, 3)), np.zeros(3),     # 22-25 u du ddu tmp
            np.zeros(NP2), np.zeros((N_BASIS, 3)), np.zeros((N_BASIS, N_BASIS)),            # 26-28 P V Wt
            np.zeros((2, 2)), np.zeros((2, 2, 2)), np.zeros((2, 2, 2, 2)), np.zeros((2, 2)),  # 29-32 Ainv Gam dGam L
            np.zeros((2, 3)), np.zeros((2, 2)),                                             # 33-34 g^a, dA^-1
            np.zeros(8), np.zeros(8), np.zeros((16, NP2)),                                  # 35-37 g1 w1 chi
            np.zeros(16), np.zeros((16, 9, 3)), np.zeros((9, 9)),                           # 38-40 val dval Mw
            np.zeros((N_PRODUCTS, 3), np.int64), np.zeros(1, np.int64),                     # 41-42 products
            np.zeros(NP2), np.zeros((N_BASIS, 9)), np.zeros((N_BASIS, 9)),                  # 43-45 om Bas T
            np.zeros(16), np.zeros((N_T, 16)), np.zeros(16), np.zeros((N_BASIS, 3)),        # 46-49 wq F s Z
            np.zeros((9, 3)), np.zeros((NP2, 27)))                                          # 50-51 gradient at a point, dP


@njit(**KERNEL)
def _load_element(e, tri, X, T, U, wk):
    """Nodal blocks X - Xref, X, Xref of element e and its facet chart;
    returns the facet area."""
    Xe, Te, Q, gl, et, el = wk[0], wk[1], wk[2], wk[3], wk[4], wk[5]
    Xd, Xc, Xr = wk[8], wk[9], wk[10]
    gather_element(e, tri, X, T, U, Xe, Te, Xr, Xc)
    for k in range(9):
        for c in range(3):
            Xd[k, c] = Xc[k, c] - Xr[k, c]
    return element_chart(Xe, Te, Q, gl, et, el)


@njit(**KERNEL)
def _third_derivative_map(wk):
    """D3[ab, c] (coefficients on the 9 nodal vectors): r_abc = sum_i gl[i, c]
    r_ab(vertex i)."""
    Q, gl, et, el, Cw, D3, bv, lam = wk[2], wk[3], wk[4], wk[5], wk[7], wk[11], wk[12], wk[13]
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
    Bas = wk[44]
    for p in range(3):
        for c in range(2):
            for k in range(9):
                Bas[_basis_row(p, c), k] = D3[p, c, k]


@njit(**KERNEL)
def _product(wk, idx, iu, iv, ud, us, uR, vd, vs, vR, ug, vg, mode):
    """Block idx += u.v for two linear maps with coefficient rows cu = Bas[iu],
    cv = Bas[iv] (their vectors of X - Xref (d), X + Xref (s), Xref (R))
    less the growth part ug.vg - uR.vR.  Its derivatives are not formed:
    the product is listed (mode >= 1) for _gradient_of and _weighted_M."""
    P = wk[26]
    P[idx] += 0.5 * (_dot(ud, vs) + _dot(us, vd)) - (_dot(ug, vg) - _dot(uR, vR))
    if mode >= 1:
        tab, n = wk[41], wk[42]
        tab[n[0], 0] = idx
        tab[n[0], 1] = iu
        tab[n[0], 2] = iv
        n[0] += 1


@njit(**KERNEL, inline="always")
def _basis_row(p, c):
    """Row of Bas holding D3[p, c] (rows 0-4 are b[0:5])."""
    return 5 + 2 * p + c


@njit(**KERNEL)
def _blocks(e, lam, tri, G0n, mode, wk):
    """The blocks P0, P1 at the barycentric point lam of the loaded element
    (P2 zero: _second_blocks), and the reference geometry there: A^-1, the
    Christoffel symbols Gam[c, a, d] = Gamma^d_ca, L with L^T A L = I, the
    dual basis g^a."""
    Q, gl, et, el, b, Cw = wk[2], wk[3], wk[4], wk[5], wk[6], wk[7]
    Xd, Xr = wk[8], wk[10]
    vd, vs, vR = wk[14], wk[15], wk[16]        # rows: r_1, r_2, r_11, r_12, r_22
    G, dG, u, du, tmp = wk[20], wk[21], wk[22], wk[23], wk[25]
    P, V = wk[26], wk[27]
    Ainv, Gam, L, gup = wk[29], wk[30], wk[32], wk[33]
    point_map(lam, Q, gl, et, el, b, Cw)
    Bas = wk[44]
    for r in range(5):
        for k in range(9):
            Bas[r, k] = b[r, k]
    wk[42][0] = 0
    for p in range(NP2):
        P[p] = 0.0
    # the vectors of X - Xref (d, exactly zero at the reference), of Xref
    # (R), of X + Xref (s), and V = Bas . X (rows 0-4 r_1 ... r_22, rows
    # 5-10 r_abc) for _gradient_of
    for r in range(5):
        _apply(b[r], Xd, vd[r])
        _apply(b[r], Xr, vR[r])
        for j in range(3):
            vs[r, j] = vd[r, j] + 2.0 * vR[r, j]
            V[r, j] = vd[r, j] + vR[r, j]
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
    for a in range(2):
        for bb in range(a, 2):
            _product(wk, _i0(a, bb), a, bb, vd[a], vs[a], vR[a],
                     vd[bb], vs[bb], vR[bb], u[a], u[bb], mode)
            for c in range(2):
                ac, bc = 2 + _pair(a, c), 2 + _pair(bb, c)
                i1 = _i1(a, bb, c)
                _product(wk, i1, ac, bb, vd[ac], vs[ac], vR[ac],
                         vd[bb], vs[bb], vR[bb], du[a, c], u[bb], mode)
                _product(wk, i1, a, bc, vd[a], vs[a], vR[a],
                         vd[bc], vs[bc], vR[bc], u[a], du[bb, c], mode)
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


@njit(**KERNEL)
def _second_blocks(mode, wk):
    """After _blocks at the same point: the blocks P2 (second derivatives of
    a_ab, with r_abc from _third_derivative_map) and the derivatives of the
    Christoffel symbols dGam[e, c, a, d] = d_e Gamma^d_ca."""
    D3, Xd, Xr = wk[11], wk[8], wk[10]
    vd, vs, vR = wk[14], wk[15], wk[16]
    td, ts, tR = wk[17], wk[18], wk[19]        # r_abc
    G, dG, u, du, ddu, tmp = wk[20], wk[21], wk[22], wk[23], wk[24], wk[25]
    V, Ainv, dGam, dAi = wk[27], wk[29], wk[31], wk[34]
    for p in range(3):
        for c in range(2):
            _apply(D3[p, c], Xd, td[p, c])
            _apply(D3[p, c], Xr, tR[p, c])
            for j in range(3):
                ts[p, c, j] = td[p, c, j] + 2.0 * tR[p, c, j]
                V[_basis_row(p, c), j] = td[p, c, j] + tR[p, c, j]
    for a in range(2):
        for c in range(2):
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
            for c in range(2):
                ac, bc = 2 + _pair(a, c), 2 + _pair(bb, c)
                for d in range(c, 2):
                    ad, bd = 2 + _pair(a, d), 2 + _pair(bb, d)
                    pac, pbc = ac - 2, bc - 2
                    i2 = _i2(a, bb, c, d)
                    _product(wk, i2, _basis_row(pac, d), bb, td[pac, d],
                             ts[pac, d], tR[pac, d],
                             vd[bb], vs[bb], vR[bb], ddu[a, c, d], u[bb], mode)
                    _product(wk, i2, ac, bd, vd[ac], vs[ac], vR[ac],
                             vd[bd], vs[bd], vR[bd], du[a, c], du[bb, d], mode)
                    _product(wk, i2, ad, bc, vd[ad], vs[ad], vR[ad],
                             vd[bc], vs[bc], vR[bc], du[a, d], du[bb, c], mode)
                    _product(wk, i2, a, _basis_row(pbc, d), vd[a], vs[a],
                             vR[a], td[pbc, d], ts[pbc, d], tR[pbc, d], u[a],
                             ddu[bb, c, d], mode)
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


# The covariant derivatives of a_ab are fixed linear combinations of the
# blocks (NP2 vectors): with Gam[c, a, f] = Gamma^f_ca,
#   grad_c a_ab      = P1[ab,c] - Gamma^f_ca P0[fb] - Gamma^f_cb P0[af],
#   grad_d grad_c a_ab = d_d(grad_c a_ab) - Gamma^g_dc grad_g a_ab
#                      - Gamma^g_da grad_c a_gb - Gamma^g_db grad_c a_ag.
# They are applied to a vector of the blocks' space (_nabla*_dot: the
# derivatives of P, 8 or 16 values, index 4a + 2b + c or 8a + 4b + 2c + d)
# and combined with weights (_nabla*_adjoint: om += the weighted sum of the
# rows, the weights of the blocks in a combination of the derivatives).

@njit(**KERNEL)
def _nabla1_dot(wk, x, out):
    """out[4a + 2b + c] = grad_c a_ab evaluated on the block values x."""
    Gam = wk[30]
    for a in range(2):
        for bb in range(2):
            for c in range(2):
                s = x[_i1(a, bb, c)]
                for f in range(2):
                    s -= Gam[c, a, f] * x[_i0(f, bb)] + Gam[c, bb, f] * x[_i0(a, f)]
                out[4 * a + 2 * bb + c] = s


@njit(**KERNEL)
def _nabla1_adjoint(wk, w1, om):
    """om += sum_abc w1[4a + 2b + c] (the blocks' coefficients of grad_c a_ab)."""
    Gam = wk[30]
    for a in range(2):
        for bb in range(2):
            for c in range(2):
                w = w1[4 * a + 2 * bb + c]
                om[_i1(a, bb, c)] += w
                for f in range(2):
                    om[_i0(f, bb)] -= w * Gam[c, a, f]
                    om[_i0(a, f)] -= w * Gam[c, bb, f]


@njit(**KERNEL)
def _nabla2_dot(wk, x, out):
    """out[8a + 4b + 2c + d] = grad_d grad_c a_ab evaluated on the block values x."""
    Gam, dGam, g1 = wk[30], wk[31], wk[35]
    _nabla1_dot(wk, x, g1)
    for q in range(16):
        a, bb, c, d = q // 8, (q // 4) % 2, (q // 2) % 2, q % 2
        s = x[_i2(a, bb, c, d)]
        for f in range(2):
            s -= (dGam[d, c, a, f] * x[_i0(f, bb)] + Gam[c, a, f] * x[_i1(f, bb, d)]
                  + dGam[d, c, bb, f] * x[_i0(a, f)] + Gam[c, bb, f] * x[_i1(a, f, d)])
            s -= (Gam[d, c, f] * g1[4 * a + 2 * bb + f] + Gam[d, a, f] * g1[4 * f + 2 * bb + c]
                  + Gam[d, bb, f] * g1[4 * a + 2 * f + c])
        out[q] = s


@njit(**KERNEL)
def _nabla2_adjoint(wk, w2, om):
    """om += sum_q w2[q] (the blocks' coefficients of grad_d grad_c a_ab, q = 8a + 4b + 2c + d)."""
    Gam, dGam, w1 = wk[30], wk[31], wk[36]
    for i in range(8):
        w1[i] = 0.0
    for q in range(16):
        w = w2[q]
        if w == 0.0:
            continue
        a, bb, c, d = q // 8, (q // 4) % 2, (q // 2) % 2, q % 2
        om[_i2(a, bb, c, d)] += w
        for f in range(2):
            om[_i0(f, bb)] -= w * dGam[d, c, a, f]
            om[_i1(f, bb, d)] -= w * Gam[c, a, f]
            om[_i0(a, f)] -= w * dGam[d, c, bb, f]
            om[_i1(a, f, d)] -= w * Gam[c, bb, f]
            w1[4 * a + 2 * bb + f] -= w * Gam[d, c, f]
            w1[4 * f + 2 * bb + c] -= w * Gam[d, a, f]
            w1[4 * a + 2 * f + c] -= w * Gam[d, bb, f]
    _nabla1_adjoint(wk, w1, om)


@njit(**KERNEL)
def _components(ncomp, nblock, wk):
    """val[t] = chi[t] . P / 2, the components of e that chi combines."""
    P, chi, val = wk[26], wk[37], wk[38]
    for t in range(ncomp):
        s = 0.0
        for p in range(nblock):
            s += chi[t, p] * P[p]
        val[t] = 0.5 * s


@njit(**KERNEL)
def _combine(ncomp, nblock, weights, wk):
    """om = sum_t weights_t chi[t]: the blocks' weights in sum_t weights_t val_t."""
    chi, om = wk[37], wk[43]
    for p in range(nblock):
        s = 0.0
        for t in range(ncomp):
            s += weights[t] * chi[t, p]
        om[p] = s


@njit(**KERNEL)
def _gradient_of(om, nbasis, wk, out):
    """out (9, 3) = d(om . P / 2)/dX = Bas^T Z(om) (module docstring) over
    the listed products and the first nbasis basis rows."""
    tab, n, Bas, V, Z = wk[41], wk[42], wk[44], wk[27], wk[49]
    for u in range(nbasis):
        for j in range(3):
            Z[u, j] = 0.0
    for r in range(n[0]):
        c = 0.5 * om[tab[r, 0]]
        if c != 0.0:
            iu, iv = tab[r, 1], tab[r, 2]
            for j in range(3):
                Z[iu, j] += c * V[iv, j]
                Z[iv, j] += c * V[iu, j]
    for k in range(9):
        for j in range(3):
            s = 0.0
            for u in range(nbasis):
                s += Bas[u, k] * Z[u, j]
            out[k, j] = s


@njit(**KERNEL)
def _component_gradients(ncomp, nblock, wk):
    """dval[t] (9, 3) = d val_t / dX for the components chi combines: the
    blocks' gradients dP[p] = dP_p / dX (flattened, 3 k + j) from the listed
    products (d(u.v) = cu (x) v + cv (x) u), then dval_t = chi[t] . dP / 2
    as axpys over contiguous rows."""
    tab, n, Bas, V, chi, dP = wk[41], wk[42], wk[44], wk[27], wk[37], wk[51]
    D = wk[39].reshape((wk[39].shape[0], 27))         # a view of dval, (k, j) -> 3 k + j
    for p in range(nblock):
        for kj in range(27):
            dP[p, kj] = 0.0
    for r in range(n[0]):
        idx, iu, iv = tab[r, 0], tab[r, 1], tab[r, 2]
        for k in range(9):
            bu, bv = Bas[iu, k], Bas[iv, k]
            for j in range(3):
                dP[idx, 3 * k + j] += fma(bu, V[iv, j], bv * V[iu, j])
    for t in range(ncomp):
        Dt = D[t]
        for kj in range(27):
            Dt[kj] = 0.0
        for p in range(nblock):
            c = 0.5 * chi[t, p]
            if c != 0.0:
                dPp = dP[p]
                for kj in range(27):
                    Dt[kj] = fma(c, dPp[kj], Dt[kj])


@njit(**KERNEL)
def _weighted_M(nbasis, wk):
    """Mw = sum_p om_p M_p / 2 for the weights om (_combine): the second
    derivative of om . P / 2 is 2 Mw (x) I3.  Over the listed products n
    (block idx_n, basis rows u_n, v_n; _product), Mw = sum_n om[idx_n]
    (c_u c_v^T + c_v c_u^T) / 4 = Bas^T Wt Bas on the first nbasis basis
    rows (5 when the blocks stop at P1)."""
    Wt, Mw = wk[28], wk[40]
    tab, n, om, Bas, T = wk[41], wk[42], wk[43], wk[44], wk[45]
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
                s = fma(Wt[u, v], Bas[v, l], s)
            T[u, l] = s
    for k in range(9):
        for l in range(k, 9):
            s = 0.0
            for u in range(nbasis):
                s = fma(Bas[u, k], T[u, l], s)
            Mw[k, l] = s
            Mw[l, k] = s


# ---------------------------------------------------------------------------
# element interiors
# ---------------------------------------------------------------------------

@njit(**KERNEL)
def element_strain_gradient(e, mode, C, tri, X, T, U, G0n, bary, wts, ge, ke, wk):
    """R_e of element e; ge (9, 3) and the upper triangle of ke (27, 27) if
    mode asks (overwritten).  G0n: nodal growth G0 (n, 3, 3)."""
    L, chi, val, dval, om = wk[32], wk[37], wk[38], wk[39], wk[43]
    wq, F, s2, gq = wk[46], wk[47], wk[48], wk[50]
    area = _load_element(e, tri, X, T, U, wk)
    _third_derivative_map(wk)
    zero_element(mode, ge, ke)
    Re = 0.0
    for iq in range(bary.shape[0]):
        _blocks(e, bary[iq], tri, G0n, mode, wk)
        _second_blocks(mode, wk)
        # orthonormal components T_IJKL = L_aI L_bJ L_cK L_dL grad_d grad_c e_ab
        # = sum_q F[t, q] s2[q] / 2 (s2 = grad grad a of the blocks P);
        # T_IJKL = T_JIKL (e is symmetric), so |T|^2 sums IJ = 00, 11 once
        # and IJ = 01 twice: component t = (IJ = 00 | 01 | 11, K, L) is
        # scaled by sqrt(2) for IJ = 01 and the sums below run over N_T = 12
        # unweighted.
        _nabla2_dot(wk, wk[26], s2)
        for q in range(16):
            a, bb, c, d = q // 8, (q // 4) % 2, (q // 2) % 2, q % 2
            for t in range(N_T):
                ij = t // 4
                I, J, K_, Lq = ij // 2, (ij + 1) // 2, (t // 2) % 2, t % 2
                f = L[a, I] * L[bb, J] * L[c, K_] * L[d, Lq]
                F[t, q] = SQRT2 * f if ij == 1 else f
        for t in range(N_T):
            s = 0.0
            for q in range(16):
                s = fma(F[t, q], s2[q], s)
            val[t] = 0.5 * s
        w = C * wts[iq] * area
        for t in range(N_T):
            Re += w * val[t] * val[t]
        if mode == 0:
            continue
        # the blocks' weights om = sum_t val_t chi_t, chi_t = sum_q F[t, q] (grad grad a)_q
        for q in range(16):
            s = 0.0
            for t in range(N_T):
                s = fma(val[t], F[t, q], s)
            wq[q] = s
        for p in range(NP2):
            om[p] = 0.0
        _nabla2_adjoint(wk, wq, om)
        # d(sum_t w val_t^2) = 2 w d(om . P / 2)
        _gradient_of(om, N_BASIS, wk, gq)
        for k in range(9):
            for j in range(3):
                ge[k, j] += 2.0 * w * gq[k, j]
        if mode < 2:
            continue
        for t in range(N_T):
            for p in range(NP2):
                chi[t, p] = 0.0
            _nabla2_adjoint(wk, F[t], chi[t])
        _component_gradients(N_T, NP2, wk)
        _weighted_M(N_BASIS, wk)
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
                        kep[q] = fma(a, Dt[q], kep[q])
        for kp in range(9):
            for kq in range(kp, 9):
                m = 4.0 * w * wk[40][kp, kq]
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
    (loaded into wk) at lam, into val[:8] of wk; chi[:8] keeps their
    combination of the blocks."""
    gup, w1, chi = wk[33], wk[36], wk[37]
    _blocks(e, lam, tri, G0n, mode, wk)
    for t in range(8):
        al, be, ga = t // 4, (t // 2) % 2, t % 2
        for p in range(NP2):
            chi[t, p] = 0.0
        for a in range(2):
            pa = _dot(gup[a], frame[al])
            for bb in range(2):
                pb = _dot(gup[bb], frame[be])
                for c in range(2):
                    w1[4 * a + 2 * bb + c] = pa * pb * _dot(gup[c], frame[ga])
        _nabla1_adjoint(wk, w1, chi[t])
    _components(8, NP1, wk)


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
            J[t] = wA[38][t] - wB[38][t]
            RE += w * J[t] * J[t]
        if mode == 0:
            continue
        # d(w |J|^2) = 2 w sum_t J_t (d val_t(A) - d val_t(B)): per side
        # the gradient of om . P / 2, om = sum_t J_t chi_t (kept for Mw below)
        for s in range(2):
            sg = 1.0 if s == 0 else -1.0
            wks = sides[s]
            _combine(8, NP1, J, wks)
            gq = wks[50]
            _gradient_of(wks[43], 5, wks, gq)
            for k in range(9):
                for jj in range(3):
                    gs[s, k, jj] += 2.0 * w * sg * gq[k, jj]
        if mode < 2:
            continue
        _component_gradients(8, NP1, wA)
        _component_gradients(8, NP1, wB)
        # d J_t on the edge-node DOFs: Dn = dval(side A) - dval(side B)
        for t in range(8):
            for P1 in range(36):
                Dn[t, P1] = 0.0
        for s1 in range(2):
            sg1 = 1.0 if s1 == 0 else -1.0
            d1 = sides[s1][39]
            for k1 in range(9):
                o1 = 9 * edge_node[j, s1, k1 // 3] + 3 * (k1 % 3)
                for j1 in range(3):
                    for t in range(8):
                        Dn[t, o1 + j1] += sg1 * d1[t, k1, j1]
        for P1 in range(36):
            for P2 in range(P1 + 1):
                acc = 0.0
                for t in range(8):
                    acc = fma(Dn[t, P1], Dn[t, P2], acc)
                Hn[P1, P2] += 2.0 * w * acc
        for s1 in range(2):
            sg1 = 1.0 if s1 == 0 else -1.0
            wk1 = sides[s1]
            _weighted_M(5, wk1)             # sum_t J_t d2 val_t = 2 Mw (x) I3 (this side)
            Mw = wk1[40]
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
    ew = (_work(), _work(), np.zeros(8), np.zeros((36, 36)), np.zeros((2, 9, 3)), np.zeros((8, 36)))
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
