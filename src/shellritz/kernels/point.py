"""The point kernel: shell energy density L (MODEL.md section 4), exact gradient
and Hessian with respect to the 15 local variables v = (r_1, r_2, r_11, r_12, r_22).

How it works
------------
Everything is written in the orthonormal reference frame (e1, e2, n) of the
point: a tensor X is stored as X[i, J] = e_i . X E_J (i spatial, Cartesian;
J = reference frame index).  With the auxiliary 3-vectors
y1 (director), Y_a = y1_{,a} (its surface derivatives) and y2, every strain
measure of the model is LINEAR in the block matrix

    U = [r_1 r_2 r_11 r_12 r_22 | y1 Y_1 Y_2 | y2]    (3 x 9, "xi-space", 27 numbers)

    F0      = grad r + y1 (x) n                     (F0 = [f_1 f_2 y1])
    F1      = rho + y2 (x) n,  rho = (grad r) kappa + grad y1
    F0_{,a} = (grad r)_{,a} + y1 (x) n_{,a} + Y_a (x) n

and the law is evaluated at the elastic slots
    A0 = F0 G0^{-1},  A1 = (F1 - F0 M1) G0^{-1},  A1a = (F0_{,a} - F0 Ma) G0^{-1}
(M1 = G0^{-1} G1, Ma = G0^{-1} G0_{,a}); each slot is U times a constant 9x3
coefficient matrix CA.

With phi(Z) = Wbar(F0 + Z F1, Z) = det G(Z) W((F0 + Z F1) G(Z)^{-1}) the
energy of MODEL.md section 4 is exactly (expand phi'' and eliminate y2)

    L = h (1 + h^2 K/12) Wbar(F0) - h m.y1
        + (h^3/24) min_y2 [ phi''(0) - 4 H phi'(0) + 2 P:(rho kappa) - 2 qbar.y2 ]

which is what is evaluated (model levels drop terms, see LEVEL_*).  y1 solves
the membrane condition c0 = P(F0) n - m = 0 (eq:mm; Newton), Y_a solves its
surface derivative c_a = d c0/d theta^a = 0 (linear, MODEL.md section 4), y2
the inner minimum (linear).  The reduced function L(v) = Ltil(v, w(v)) is
differentiated with multipliers lam for (c0, c1, c2):

    grad L = d/dv [Ltil + lam.c],         c_z^T lam = -dLtil/dz
    hess L = P^T  Hess(Ltil + lam.c)  P,  P = d(v, y1, Y, y2)/dv

so only the first to fourth derivatives of W at A0, contracted with the slot
directions, are needed (kernels/material.py): one AA, five D3, three D4.
The load term -h qbar.r is linear in r and left to the discretization.
"""

import numpy as np
from numba import njit

from . import KERNEL
from .parallel import run_chunks
from .material import (M_AA, S_W, V_P, mat_combination, mat_d3, mat_d3_vec,
                       mat_prepare, new_state)
from .small import chol3, chol3_inverse, chol3_solve, cross, det3, fma, inv3, mm3, mv3

LEVEL_MEMBRANE = 0
LEVEL_BENDING = 1
LEVEL_CONSISTENT = 2

MODE_ENERGY = 0
MODE_GRADIENT = 1
MODE_HESSIAN = 2

# status codes (the caller turns them into errors naming the element/point)
OK = 0
ERR_INVERTED = 1        # det A <= 0 during or after the y1 solve
ERR_LAW = 2             # law returned non-finite values
ERR_ELLIPTICITY = 3     # acoustic tensor B not positive definite
ERR_Y1_NEWTON = 4       # y1 Newton did not converge
ERR_REFERENCE = 5       # degenerate reference tangents
ERR_GROWTH = 6          # det G0 <= 0
ERR_CURRENT = 7         # degenerate current tangents (r_1 x r_2 = 0)
ERR_THICKNESS = 8       # F0 + Z F1 inverts within |Z| <= h/2 (bending levels)

STATUS_TEXT = {
    OK: "ok",
    ERR_INVERTED: "inverted material (det A <= 0)",
    ERR_LAW: "the material law returned a non-finite value",
    ERR_ELLIPTICITY: "loss of strong ellipticity (acoustic tensor not positive definite)",
    ERR_Y1_NEWTON: "the director y1 (membrane condition, eq:mm) did not converge",
    ERR_REFERENCE: "degenerate reference tangents (R_1 x R_2 = 0)",
    ERR_GROWTH: "growth tensor with det G0 <= 0",
    ERR_CURRENT: "degenerate current tangents (r_1 x r_2 = 0)",
    ERR_THICKNESS: "the deformation through the thickness F0 + Z F1 inverts within |Z| <= h/2 "
                   "(folded offset surfaces: outside the model's range)",
}

NV = 15          # local variables v
NX = 6           # of which first derivatives r_1, r_2
NXI = 27         # xi-space: 9 blocks of 3-vectors
Y1_BLOCK = 5     # U[:, 5] = y1, U[:, 6:8] = Y_a, U[:, 8] = y2

_Y1_MAXIT = 60


@njit(cache=True)
def new_scratch():
    """Work arrays of one point evaluation (allocate once per thread/element)."""
    return (new_state(),            # 0 material state
            np.zeros((3, 3)),       # 1 E: frame (columns e1, e2, n)
            np.zeros((2, 3)),       # 2 Lam: Lam[a, J] = g^a . e_J (J < 2)
            np.zeros((2, 2, 3)),    # 3 dgup[a, b] = d g^b / d theta^a (global)
            np.zeros((2, 3)),       # 4 n_{,a} (global)
            np.zeros((3, 3)),       # 5 kappa (local, zero 3rd row/col)
            np.zeros((10, 3, 3)),   # 6 growth: G0L G1L Gi M1 N1 M_1 M_2 work/Q1 Q0 kappa.Gi
            np.zeros((4, 9, 3)),    # 7 CA: slot coefficients A0, A1, A1_1, A1_2
            np.zeros((3, 9)),       # 8 U
            np.zeros((4, 9)),       # 9 slot values
            np.zeros((13, 9)),      # 10 vectors: D0^k(3), D1_a^k(6), X, Xtot, work x2
            np.zeros((6, 3)),       # 11 small vectors
            np.zeros((3, 3, 3)),    # 12 B, chol(B), work
            np.zeros((7, 9, 9)),    # 13 9x9: D3(A1a) x2, H00, H01, H0a x2, work
            np.zeros(NXI),          # 14 dLtil/dxi
            np.zeros((9, NXI)),     # 15 dc/dxi
            np.zeros((9, NV)),      # 16 Zv = d(y1, Y1, Y2)/dv
            np.zeros((4, 9, NV)),   # 17 slot Jacobians dA/dv (y2 fixed)
            np.zeros((9, NV)),      # 18 work
            np.zeros((3, NV)),      # 19 d2 Ltil / dy2 dv
            np.zeros(9),            # 20 lambda (c0, c1, c2)
            np.zeros(15),           # 21 v in the local frame
            np.zeros((6, 3)),       # 22 qbar, m, dm_1, dm_2, y1, y2 in the local frame
            np.zeros((2, 3)),       # 23 g^a (global)
            np.zeros((4, 9, 3)),    # 24 CF: slot coefficients before G0^-1
            np.zeros((4, 3)),       # 25 Newton work: res, trial y, step
            np.zeros((2, 3, 3)),    # 26 3x3 work
            np.zeros((2, 3, 9)),    # 27 D4 pairs (c, d) of the Hessian block H00
            np.zeros(3),            # 28 D4 pair weights
            np.zeros((2, 9, NV)),   # 29 H01^T J0, H0a^T J0
            np.zeros((NV, NX)),     # 30 cross block of the Hessian
            np.zeros((NV + 9, NV + 9)),   # 31 face pressure: Hessian in (v, y1, Y1, Y2)
            np.zeros((NV + 9, NV)))       # 32 face pressure: work


# ---------------------------------------------------------------------------
# helpers
# ---------------------------------------------------------------------------

@njit(**KERNEL)
def _reference_geometry(ref, E, Lam, dgup, na, kap, gup):
    """Frame, dual basis and curvature of the reference surface at the point.

    Derivatives of g^a and n are exact directional derivatives of their
    algebraic formulas in (R_1, R_2) along the given R_ab (DESIGN.md), so a
    discrete reference is exactly stress free.  Returns (H, K, ok).
    """
    m00 = ref[0] * ref[0] + ref[1] * ref[1] + ref[2] * ref[2]
    m01 = ref[0] * ref[3] + ref[1] * ref[4] + ref[2] * ref[5]
    m11 = ref[3] * ref[3] + ref[4] * ref[4] + ref[5] * ref[5]
    det = m00 * m11 - m01 * m01
    if not det > 1e-28 * (m00 * m11) or not np.isfinite(det):
        return 0.0, 0.0, False
    i00 = m11 / det
    i11 = m00 / det
    i01 = -m01 / det
    s = 1.0 / np.sqrt(det)
    l1 = 1.0 / np.sqrt(m00)
    n0 = (ref[1] * ref[5] - ref[2] * ref[4]) * s
    n1 = (ref[2] * ref[3] - ref[0] * ref[5]) * s
    n2 = (ref[0] * ref[4] - ref[1] * ref[3]) * s
    for i in range(3):
        gup[0, i] = i00 * ref[i] + i01 * ref[3 + i]
        gup[1, i] = i01 * ref[i] + i11 * ref[3 + i]
        E[i, 0] = ref[i] * l1
    E[0, 2], E[1, 2], E[2, 2] = n0, n1, n2
    E[0, 1] = n1 * E[2, 0] - n2 * E[1, 0]
    E[1, 1] = n2 * E[0, 0] - n0 * E[2, 0]
    E[2, 1] = n0 * E[1, 0] - n1 * E[0, 0]
    # b_ab = n . R_ab (R_ab = ref[6 + 3 * (a + b) ...]); n_{,a} = -b_ac g^c
    b00 = n0 * ref[6] + n1 * ref[7] + n2 * ref[8]
    b01 = n0 * ref[9] + n1 * ref[10] + n2 * ref[11]
    b11 = n0 * ref[12] + n1 * ref[13] + n2 * ref[14]
    for i in range(3):
        na[0, i] = -(b00 * gup[0, i] + b01 * gup[1, i])
        na[1, i] = -(b01 * gup[0, i] + b11 * gup[1, i])
    # d g^b / d theta^a = d(Mi)_a g + Mi R_{.a},  d(Mi)_a = -Mi dM_a Mi,
    # dM_a[c, d] = R_ca . g_d + g_c . R_da
    for a in range(2):
        o0 = 6 + 3 * a          # R_{0a}
        o1 = 9 + 3 * a          # R_{1a}
        d00 = 2.0 * (ref[o0] * ref[0] + ref[o0 + 1] * ref[1] + ref[o0 + 2] * ref[2])
        d11 = 2.0 * (ref[o1] * ref[3] + ref[o1 + 1] * ref[4] + ref[o1 + 2] * ref[5])
        d01 = (ref[o0] * ref[3] + ref[o0 + 1] * ref[4] + ref[o0 + 2] * ref[5]
               + ref[0] * ref[o1] + ref[1] * ref[o1 + 1] + ref[2] * ref[o1 + 2])
        # -Mi dM Mi (symmetric)
        t00 = i00 * d00 + i01 * d01
        t01 = i00 * d01 + i01 * d11
        t10 = i01 * d00 + i11 * d01
        t11 = i01 * d01 + i11 * d11
        e00 = -(t00 * i00 + t01 * i01)
        e01 = -(t00 * i01 + t01 * i11)
        e11 = -(t10 * i01 + t11 * i11)
        for i in range(3):
            dgup[a, 0, i] = (e00 * ref[i] + e01 * ref[3 + i]
                             + i00 * ref[o0 + i] + i01 * ref[o1 + i])
            dgup[a, 1, i] = (e01 * ref[i] + e11 * ref[3 + i]
                             + i01 * ref[o0 + i] + i11 * ref[o1 + i])
    for a in range(2):
        for J in range(2):
            Lam[a, J] = gup[a, 0] * E[0, J] + gup[a, 1] * E[1, J] + gup[a, 2] * E[2, J]
    # kappa_{IJ} = sum b_ac Lam[a, I] Lam[c, J]
    for I in range(3):
        for J in range(3):
            kap[I, J] = 0.0
    for I in range(2):
        for J in range(2):
            kap[I, J] = (b00 * Lam[0, I] * Lam[0, J] + b01 * (Lam[0, I] * Lam[1, J] + Lam[1, I] * Lam[0, J])
                         + b11 * Lam[1, I] * Lam[1, J])
    H = 0.5 * (kap[0, 0] + kap[1, 1])
    K = kap[0, 0] * kap[1, 1] - kap[0, 1] * kap[1, 0]
    return H, K, True


@njit(**KERNEL)
def _to_local(X, E, out):
    """out = E^T X E (a reference-reference tensor in the local frame)."""
    for I in range(3):
        for J in range(3):
            s = 0.0
            for p in range(3):
                for q in range(3):
                    s += E[p, I] * X[p, q] * E[q, J]
            out[I, J] = s


@njit(**KERNEL, inline="always")
def _slot(U, C, out):
    """out[3 i + J] = sum_p U[i, p] C[p, J]."""
    for i in range(3):
        for J in range(3):
            s = 0.0
            for p in range(9):
                s = fma(U[i, p], C[p, J], s)
            out[3 * i + J] = s


@njit(**KERNEL, inline="always")
def _add_to_xi(G, C, coef, out):
    """out[3 p + i] += coef sum_J G[3 i + J] C[p, J]  (slot gradient -> xi)."""
    for p in range(9):
        for i in range(3):
            s = 0.0
            for J in range(3):
                s = fma(G[3 * i + J], C[p, J], s)
            out[3 * p + i] = fma(coef, s, out[3 * p + i])


@njit(**KERNEL, inline="always")
def _matvec9(M, x, out):
    for p in range(9):
        s = 0.0
        for q in range(9):
            s = fma(M[p, q], x[q], s)
        out[p] = s


@njit(**KERNEL, inline="always")
def _matvec_block(M, d, k, out):
    """out = M d for a direction d that is zero outside block k (d = e_k (x) w,
    as D0^k and D1a^k)."""
    for p in range(9):
        out[p] = fma(M[p, 3 * k + 2], d[3 * k + 2], fma(M[p, 3 * k + 1], d[3 * k + 1], M[p, 3 * k] * d[3 * k]))


@njit(**KERNEL, inline="always")
def _dot9(a, b):
    s = 0.0
    for p in range(9):
        s = fma(a[p], b[p], s)
    return s


@njit(**KERNEL, inline="always")
def _solve_b(Binv, R, out):
    """out[k, q] = -(B^{-1} R)[k, q] for the NV columns of R (3 x NV)."""
    for k in range(3):
        for q in range(NV):
            out[k, q] = -fma(Binv[k, 2], R[2, q], fma(Binv[k, 1], R[1, q], Binv[k, 0] * R[0, q]))


@njit(**KERNEL, inline="always")
def _slot_jacobian(C, Zv, ncol, out):
    """out[(i,J), q] = d slot / d v_q with y2 fixed (blocks 0..4 direct,
    5..7 via Zv), for the first ncol columns q (the others are zero)."""
    for r in range(9):
        for q in range(ncol):
            out[r, q] = 0.0
    for i in range(3):
        for J in range(3):
            r = 3 * i + J
            for p in range(ncol // 3):
                out[r, 3 * p + i] += C[p, J]
            for p in range(3):
                c = C[Y1_BLOCK + p, J]
                if c != 0.0:
                    for q in range(ncol):
                        out[r, q] = fma(c, Zv[3 * p + i, q], out[r, q])


@njit(**KERNEL, inline="always")
def _h_j(H, Jb, nb, out, transpose=False):
    """out[:, :nb] = H Jb[:, :nb] (9x9 times 9xnb), or H^T Jb[:, :nb]."""
    for p in range(9):
        for q in range(nb):
            s = 0.0
            for r in range(9):
                s = fma(H[r, p] if transpose else H[p, r], Jb[r, q], s)
            out[p, q] = s


@njit(**KERNEL, inline="always")
def _add_jt_upper(Ja, na, T, out):
    """Upper triangle of out[:na, :na] += Ja[:, :na]^T T[:, :na] (a symmetric product)."""
    for a in range(na):
        for q in range(a, na):
            s = 0.0
            for p in range(9):
                s = fma(Ja[p, a], T[p, q], s)
            out[a, q] += s


@njit(**KERNEL, inline="always")
def _add_jt(Ja, na, T, nb, out):
    """out[:na, :nb] += Ja[:, :na]^T T[:, :nb]."""
    for a in range(na):
        for q in range(nb):
            s = 0.0
            for p in range(9):
                s = fma(Ja[p, a], T[p, q], s)
            out[a, q] += s


@njit(**KERNEL, inline="always")
def _right_map(M, Q, out):
    """out[p, (k,L)] = sum_J M[p, (k,J)] Q[L, J]  (M composed with dA -> dA Q)."""
    for p in range(9):
        for k in range(3):
            for L in range(3):
                s = 0.0
                for J in range(3):
                    s = fma(M[p, 3 * k + J], Q[L, J], s)
                out[p, 3 * k + L] = s


# ---------------------------------------------------------------------------
# the kernel
# ---------------------------------------------------------------------------

@njit(**KERNEL)
def point_kernel(mode, level, kind, psi, params, h, v, ref, G0, G1, dG0,
                 qbar, m, dm, y1, y2, grad, hess, sc, pf=0.0, zf=0.0):
    """Energy density L at one point, and grad (15) / hess (15x15) if asked.

    mode: MODE_ENERGY | MODE_GRADIENT | MODE_HESSIAN; level: LEVEL_*.
    kind, psi, params: the law (materials.Law.kind, .psi: its cfunc's address, .params).
    v, ref: (r_1, r_2, r_11, r_12, r_22) current / reference, any coordinates.
    G0, G1: growth G(Z) = G0 + Z G1 (global 3x3); dG0[a] = dG0/dtheta^a.
    qbar, m, dm[a]: load resultants (eq:qm) and dm/dtheta^a.
    y1: in: warm start (zeros: none); out: the director.  y2: out.
    pf, zf: follower pressure pf on the face Z = zf (docs/pressure.md): the
    point's part of -pf V(face), i.e. without the volume of the middle
    surface, which the discretization adds.
    Returns (L, status); status != OK leaves L = nan.

    Internally all vectors are taken to the local frame (spatial components
    included), so that non-objective laws (LinearIsotropic) measure strain
    from the reference; results are rotated back.
    """
    E = sc[1]
    H, K, ok = _reference_geometry(ref, E, sc[2], sc[3], sc[4], sc[5], sc[23])
    if not ok:
        return np.nan, ERR_REFERENCE
    # spatial vectors to the local frame
    vl, loc = sc[21], sc[22]
    for p in range(5):
        _rot_t(E, v[3 * p:3 * p + 3], vl[3 * p:3 * p + 3])
    _rot_t(E, qbar, loc[0])
    _rot_t(E, m, loc[1])
    _rot_t(E, dm[0], loc[2])
    _rot_t(E, dm[1], loc[3])
    _rot_t(E, y1, loc[4])
    # j_{,a} / j = g^b . R_{ba} (j = |R_1 x R_2|), for the face pressure
    gup = sc[23]
    ga0 = ga1 = 0.0
    for i in range(3):
        ga0 += gup[0, i] * ref[6 + i] + gup[1, i] * ref[9 + i]
        ga1 += gup[0, i] * ref[9 + i] + gup[1, i] * ref[12 + i]
    L, status = _kernel_local(mode, level, kind, psi, params, h, vl, H, K, G0, G1, dG0,
                              loc[0], loc[1], loc[2:4], loc[4], loc[5], grad, hess, sc,
                              pf, zf, ga0, ga1)
    if status != OK:
        return L, status
    _rot(E, loc[4], y1)
    _rot(E, loc[5], y2)
    if mode >= MODE_GRADIENT:
        tmp = sc[25][0]
        for p in range(5):
            for i in range(3):
                tmp[i] = grad[3 * p + i]
            _rot(E, tmp, grad[3 * p:3 * p + 3])
    if mode == MODE_HESSIAN:
        blk = sc[26][0]
        for p in range(5):
            for q in range(5):
                for i in range(3):
                    for j in range(3):
                        s = 0.0
                        for k in range(3):
                            s = fma(hess[3 * p + i, 3 * q + k], E[j, k], s)
                        blk[i, j] = s
                for i in range(3):
                    for j in range(3):
                        hess[3 * p + i, 3 * q + j] = fma(E[i, 2], blk[2, j], fma(E[i, 1], blk[1, j],
                                                                                 E[i, 0] * blk[0, j]))
    return L, OK


@njit(**KERNEL, inline="always")
def _rot_t(E, x, out):
    """out = E^T x (global -> local components)."""
    for J in range(3):
        out[J] = E[0, J] * x[0] + E[1, J] * x[1] + E[2, J] * x[2]


@njit(**KERNEL, inline="always")
def _rot(E, x, out):
    """out = E x (local -> global components)."""
    for i in range(3):
        out[i] = E[i, 0] * x[0] + E[i, 1] * x[1] + E[i, 2] * x[2]


@njit(**KERNEL)
def _kernel_local(mode, level, kind, psi, params, h, v, H, K, G0, G1, dG0,
                  qbar, m, dm, y1, y2, grad, hess, sc, pf, zf, ga0, ga1):
    """point_kernel with every vector in the local frame (see point_kernel);
    ga0, ga1: j_{,a}/j of the reference (face pressure).  qbar, m, dm are
    the caller's work copies: the face pressure is added to them."""
    mv, mm, mp = sc[0]
    E, Lam, dgup, na, kap, gr = sc[1], sc[2], sc[3], sc[4], sc[5], sc[6]
    CA, U, S, vec, sv, B3 = sc[7], sc[8], sc[9], sc[10], sc[11], sc[12]
    M9 = sc[13]
    G0L, G1L, Gi, M1, N1, wk = gr[0], gr[1], gr[2], gr[3], gr[4], gr[7]
    B, LB, Binv = B3[0], B3[1], B3[2]
    nan = np.nan
    # growth in the local frame
    _to_local(G0, E, G0L)
    _to_local(G1, E, G1L)
    g0 = inv3(G0L, Gi)
    if not g0 > 0.0:
        return nan, ERR_GROWTH
    mm3(Gi, G1L, M1)
    mm3(G1L, Gi, N1)
    t1 = M1[0, 0] + M1[1, 1] + M1[2, 2]
    t2 = 0.0
    for i in range(3):
        for j in range(3):
            t2 -= M1[i, j] * M1[j, i]
    t2 = 0.5 * (t1 * t1 + t2)
    t1a = sv[5]
    for a in range(2):
        _to_local(dG0[a], E, wk)
        mm3(Gi, wk, gr[5 + a])
        t1a[a] = gr[5 + a][0, 0] + gr[5 + a][1, 1] + gr[5 + a][2, 2]

    bend = level >= LEVEL_BENDING
    cons = level == LEVEL_CONSISTENT
    cB = h ** 3 * g0 / 24.0 if bend else 0.0
    cK = 1.0 if cons else 0.0
    cH = 1.0 if cons else 0.0
    cW = h * g0 * (1.0 + cK * h * h * K / 12.0) + cB * (2.0 * t2 - 4.0 * cH * H * t1)

    # ---- slot coefficient matrices (9 blocks x 3 local columns) ----------
    CF = sc[24]
    for s_ in range(4):
        for p in range(9):
            for J in range(3):
                CF[s_, p, J] = 0.0
    for a in range(2):
        for J in range(2):
            CF[0, a, J] = Lam[a, J]
            lk = Lam[a, 0] * kap[0, J] + Lam[a, 1] * kap[1, J]
            CF[1, a, J] = lk
            CF[1, 6 + a, J] = Lam[a, J]
    CF[0, 5, 2] = 1.0
    CF[1, 8, 2] = 1.0
    for a in range(2):
        Fa = CF[2 + a]
        for bb in range(2):
            blk = 2 + a + bb          # r_{ba}: (0,0)->2, (0,1)->3, (1,1)->4
            for J in range(2):
                Fa[blk, J] += Lam[bb, J]
            for J in range(3):
                Fa[bb, J] = (dgup[a, bb, 0] * E[0, J] + dgup[a, bb, 1] * E[1, J]
                             + dgup[a, bb, 2] * E[2, J])
        for J in range(2):
            Fa[5, J] = na[a, 0] * E[0, J] + na[a, 1] * E[1, J] + na[a, 2] * E[2, J]
        Fa[6 + a, 2] = 1.0
    # A-slots: CA0 = CF0 Gi, CA1 = (CF1 - CF0 M1) Gi, CA1a = (CF1a - CF0 Ma) Gi
    for s in range(4):
        for p in range(9):
            for J in range(3):
                acc = 0.0
                for L in range(3):
                    f = CF[s, p, L]
                    if s == 1:
                        for I in range(3):
                            f -= CF[0, p, I] * M1[I, L]
                    elif s >= 2:
                        for I in range(3):
                            f -= CF[0, p, I] * gr[5 + s - 2][I, L]
                    acc += f * Gi[L, J]
                CA[s, p, J] = acc

    # directions D0^k = e_k (x) Gi[2, :], D1a^k = e_k (x) (v_a^T Gi)
    D0 = vec[0:3]
    D1 = vec[3:9]
    for k in range(3):
        for p in range(9):
            D0[k, p] = 0.0
            for a in range(2):
                D1[3 * a + k, p] = 0.0
        for J in range(3):
            D0[k, 3 * k + J] = Gi[2, J]
    for a in range(2):
        va = sv[a]
        for J in range(3):
            va[J] = na[a, 0] * E[0, J] + na[a, 1] * E[1, J] + na[a, 2] * E[2, J] - gr[5 + a][2, J]
        for k in range(3):
            for L in range(3):
                D1[3 * a + k, 3 * k + L] = va[0] * Gi[0, L] + va[1] * Gi[1, L] + va[2] * Gi[2, L]

    # ---- U: known blocks, then y1 by Newton on the membrane condition -----
    for i in range(3):
        for p in range(5):
            U[i, p] = v[3 * p + i]
        for p in range(5, 9):
            U[i, p] = 0.0
    ff = sv[2]
    cross(v[0:3], v[3:6], ff)   # r_1 x r_2: current normal direction
    nf = np.sqrt(ff[0] ** 2 + ff[1] ** 2 + ff[2] ** 2)
    if not nf > 0.0 or not np.isfinite(nf):
        return nan, ERR_CURRENT
    if y1[0] == 0.0 and y1[1] == 0.0 and y1[2] == 0.0:
        # orient with the reference normal: same sign as (R_1 x R_2).(r_1 x r_2)
        for i in range(3):
            y1[i] = ff[i] / nf * G0L[2, 2]
    iota = Lam[0, 0] * Lam[1, 1] - Lam[0, 1] * Lam[1, 0]     # 1 / |R_1 x R_2|
    if pf != 0.0:
        _pressure_loads(pf, zf, h, iota, ga0, ga1, v, ff, qbar, m, dm)
    status = _solve_y1(kind, psi, params, g0, m, CA[0], U, y1, D0, S[0], mv, mm, mp,
                       B, LB, sc[25], sc[26][1])
    if status != OK:
        return nan, status
    W = mp[S_W]
    P = mv[V_P]
    AA = mm[M_AA]
    chol3_inverse(LB, Binv)      # every later solve with B is a product with Binv

    if not bend:
        L = cW * W - h * (m[0] * y1[0] + m[1] * y1[1] + m[2] * y1[2])
        for k in range(3):
            y2[k] = 0.0
        if mode == MODE_ENERGY:
            return L, OK
        _membrane_derivatives(mode, cW, g0, CA[0], D0, P, AA, Binv, grad, hess, sc,
                              pf, zf, h, iota, ga0, ga1, U)
        return L, OK

    # ---- Y_a (surface derivative of the membrane condition) -------------
    rhs = sv[4]
    tmp = vec[11]
    for a in range(2):
        _slot(U, CA[2 + a], S[2 + a])          # with Y_a = 0
        _matvec9(AA, S[2 + a], tmp)
        for k in range(3):
            rhs[k] = -(g0 * (t1a[a] * _dot9(P, D0[k]) + _dot9(tmp, D0[k])
                             + _dot9(P, D1[3 * a + k])) - dm[a, k])
        mv3(Binv, rhs, rhs)
        for i in range(3):
            U[i, 6 + a] = rhs[i]
        _slot(U, CA[2 + a], S[2 + a])
    # ---- y2 (inner minimum) ---------------------------------------------
    _slot(U, CA[1], S[1])                      # with y2 = 0
    _matvec9(AA, S[1], tmp)
    # D0^k N1 as a direction: e_k (x) (Gi[2,:] N1)
    nGN = sv[0]
    for J in range(3):
        nGN[J] = Gi[2, 0] * N1[0, J] + Gi[2, 1] * N1[1, J] + Gi[2, 2] * N1[2, J]
    cq = 1.0 if cons else 0.0
    for k in range(3):
        pnk = _dot9(P, D0[k])
        pnn = P[3 * k] * nGN[0] + P[3 * k + 1] * nGN[1] + P[3 * k + 2] * nGN[2]
        rhs[k] = -g0 * ((t1 - 2.0 * cH * H) * pnk + _dot9(tmp, D0[k]) - pnn) + cq * qbar[k]
    mv3(Binv, rhs, rhs)
    for i in range(3):
        U[i, 8] = rhs[i]
        y2[i] = rhs[i]
    _slot(U, CA[1], S[1])
    A0, A1 = S[0], S[1]
    if not _thickness_admissible(U, CF, h, vec[11], vec[12]):
        return nan, ERR_THICKNESS

    # X = A1 Q1 + A0 Q0 (all directions along which DW is taken linearly)
    Q1, Q0, Kk = gr[7], gr[8], gr[9]
    mm3(kap, Gi, Kk)             # kappa Gi
    for I in range(3):
        for J in range(3):
            gk = G0L[I, 0] * Kk[0, J] + G0L[I, 1] * Kk[1, J] + G0L[I, 2] * Kk[2, J]
            g1k = G1L[I, 0] * Kk[0, J] + G1L[I, 1] * Kk[1, J] + G1L[I, 2] * Kk[2, J]
            Q1[I, J] = cB * (((2.0 * t1 - 4.0 * cH * H) if I == J else 0.0)
                             - 2.0 * N1[I, J] + 2.0 * cK * gk)
            Q0[I, J] = cB * 2.0 * cK * g1k
    X = vec[9]
    for i in range(3):
        for J in range(3):
            s = 0.0
            for L in range(3):
                s += A1[3 * i + L] * Q1[L, J] + A0[3 * i + L] * Q0[L, J]
            X[3 * i + J] = s
    _matvec9(AA, A1, tmp)
    L = (cW * W + _dot9(P, X) + cB * _dot9(A1, tmp)
         - h * (m[0] * y1[0] + m[1] * y1[1] + m[2] * y1[2])
         - cq * h ** 3 / 12.0 * (qbar[0] * y2[0] + qbar[1] * y2[1] + qbar[2] * y2[2]))
    if pf != 0.0 and cons:
        L += _pressure_face_area_term(pf, zf, iota, U)
    if mode == MODE_ENERGY:
        return L, OK

    # ---- gradient: multipliers of (c0, c1, c2) --------------------------
    Lx, cx, lam = sc[14], sc[15], sc[20]
    for q in range(NXI):
        Lx[q] = 0.0
        for r in range(9):
            cx[r, q] = 0.0
    gA, X2 = vec[10], vec[12]
    # dLtil/dA0 = cW P + AA X + cB D3(A1) A1 + P Q0^T
    _matvec9(AA, X, gA)
    mat_d3_vec(mv, mm, mp, A1, A1, tmp)
    for i in range(3):
        for L_ in range(3):
            pq = P[3 * i] * Q0[L_, 0] + P[3 * i + 1] * Q0[L_, 1] + P[3 * i + 2] * Q0[L_, 2]
            gA[3 * i + L_] += cW * P[3 * i + L_] + cB * tmp[3 * i + L_] + pq
    _add_to_xi(gA, CA[0], 1.0, Lx)
    # dLtil/dA1 = P Q1^T + 2 cB AA A1
    _matvec9(AA, A1, tmp)
    for i in range(3):
        for L_ in range(3):
            pq = P[3 * i] * Q1[L_, 0] + P[3 * i + 1] * Q1[L_, 1] + P[3 * i + 2] * Q1[L_, 2]
            gA[3 * i + L_] = pq + 2.0 * cB * tmp[3 * i + L_]
    _add_to_xi(gA, CA[1], 1.0, Lx)
    for i in range(3):
        Lx[3 * Y1_BLOCK + i] -= h * m[i]
        Lx[3 * 8 + i] -= cq * h ** 3 / 12.0 * qbar[i]
    # constraint Jacobians; D3W[., A1a, D0^k] = D3(A1a) D0^k
    d3a = M9[0:2]
    for a in range(2):
        mat_d3(mv, mm, mp, S[2 + a], d3a[a])
    for k in range(3):
        _matvec_block(AA, D0[k], k, tmp)
        _add_to_xi(tmp, CA[0], g0, cx[k])
        for a in range(2):
            _add_to_xi(tmp, CA[2 + a], g0, cx[3 + 3 * a + k])
            _matvec_block(d3a[a], D0[k], k, gA)
            _matvec_block(AA, D1[3 * a + k], k, X2)
            for p in range(9):
                gA[p] += t1a[a] * tmp[p] + X2[p]
            _add_to_xi(gA, CA[0], g0, cx[3 + 3 * a + k])
    if pf != 0.0:
        _pressure_gradient(pf, zf, h, cq, iota, ga0, ga1, U, Lx, cx, True)
    # c_z = [[B, 0, 0], [K1, B, 0], [K2, 0, B]] (blocks of cx in z = y1, Y1, Y2)
    # lam_a = -B^{-1} dLtil/dY_a ; lam_0 = -B^{-1}(dLtil/dy1 + K1^T lam_1 + K2^T lam_2)
    z0 = 3 * Y1_BLOCK
    for a in range(2):
        for k in range(3):
            rhs[k] = -Lx[z0 + 3 + 3 * a + k]
        mv3(Binv, rhs, rhs)
        for k in range(3):
            lam[3 + 3 * a + k] = rhs[k]
    for l in range(3):
        s = -Lx[z0 + l]
        for a in range(2):
            for k in range(3):
                s -= cx[3 + 3 * a + k, z0 + l] * lam[3 + 3 * a + k]
        rhs[l] = s
    mv3(Binv, rhs, rhs)
    for k in range(3):
        lam[k] = rhs[k]
    for q in range(NV):
        s = Lx[q]
        for r in range(9):
            s = fma(lam[r], cx[r, q], s)
        grad[q] = s
    if mode == MODE_GRADIENT:
        return L, OK

    # ---- Hessian -------------------------------------------------------
    Zv = sc[16]
    # Z_y1 = -B^{-1} c0_v ; Z_Ya = -B^{-1}(ca_v + K_a Z_y1)
    _solve_b(Binv, cx[0:3], Zv[0:3])
    Ra = sc[18][0:3]            # (work) right-hand sides ca_v + K_a Z_y1
    for a in range(2):
        for k in range(3):
            for q in range(NV):
                s = cx[3 + 3 * a + k, q]
                for l in range(3):
                    s = fma(cx[3 + 3 * a + k, z0 + l], Zv[l, q], s)
                Ra[k, q] = s
        _solve_b(Binv, Ra, Zv[3 + 3 * a:6 + 3 * a])
    # lambda-weighted directions: Xtot = X + g0 (Dl0 + sum_a (t1a Dla + D1la))
    Xt = vec[11]
    for p in range(9):
        Xt[p] = X[p]
    for k in range(3):
        for p in range(9):
            Xt[p] += g0 * lam[k] * D0[k, p]
            for a in range(2):
                la = lam[3 + 3 * a + k]
                Xt[p] += g0 * la * (t1a[a] * D0[k, p] + D1[3 * a + k, p])
    H00, H01, H0a, work = M9[2], M9[3], M9[4:6], M9[6]
    # H00 = cW AA + D3(Xt) + cB D4(A1, A1) + g0 sum_a D4(A1a, Dla)
    pc, pd, pw = sc[27][0], sc[27][1], sc[28]
    for p in range(9):
        pc[0, p] = A1[p]
        pd[0, p] = A1[p]
        for a in range(2):
            pc[1 + a, p] = S[2 + a][p]
            s = 0.0
            for k in range(3):
                s += lam[3 + 3 * a + k] * D0[k, p]
            pd[1 + a, p] = s                      # Dla = lam_a (x) Gi[2, :]
    pw[0] = cB
    pw[1] = g0
    pw[2] = g0
    mat_combination(mv, mm, mp, cW, Xt, pc, pd, pw, H00)
    mat_d3(mv, mm, mp, A1, H01)
    for a in range(2):
        mat_d3(mv, mm, mp, pd[1 + a], H0a[a])
    for p in range(9):
        for q in range(9):
            H01[p, q] *= 2.0 * cB
            H0a[0][p, q] *= g0
            H0a[1][p, q] *= g0
    if cK != 0.0:   # AA R0 + R0^T AA (X depends on A0 through Q0)
        _right_map(AA, Q0, work)
        for p in range(9):
            for q in range(9):
                H00[p, q] += work[p, q] + work[q, p]
    _right_map(AA, Q1, work)
    for p in range(9):
        for q in range(9):
            H01[p, q] += work[p, q]
    # slot Jacobians with y2 fixed, then P^T Hess P with y2 condensed.
    # A0 depends on r_1, r_2 and y1(r_1, r_2) only: J0 has NX non-zero columns.
    Js = sc[17]
    _slot_jacobian(CA[0], Zv, NX, Js[0])
    for s in range(1, 4):
        _slot_jacobian(CA[s], Zv, NV, Js[s])
    T, W01, Wa = sc[18], sc[29][0], sc[29][1]
    # the upper triangle of hess is accumulated, then mirrored
    for a in range(NV):
        for b in range(NV):
            hess[a, b] = 0.0
    _h_j(H00, Js[0], NX, T)
    _add_jt_upper(Js[0], NX, T, hess)
    # cross blocks: M = J1^T (H01^T J0) + sum_a Ja^T (H0a J0) (H0a symmetric),
    # added as M and M^T
    _h_j(H01, Js[0], NX, W01, True)
    Mx = sc[30]
    for a in range(NV):
        for q in range(NX):
            Mx[a, q] = 0.0
    _add_jt(Js[1], NV, W01, NX, Mx)
    for a in range(2):
        _h_j(H0a[a], Js[0], NX, Wa)
        _add_jt(Js[2 + a], NV, Wa, NX, Mx)
    for i in range(NX):
        for j in range(i, NV):
            hess[i, j] += Mx[j, i] + (Mx[i, j] if j < NX else 0.0)
    for p in range(9):
        for q in range(9):
            work[p, q] = 2.0 * cB * AA[p, q]
    _h_j(work, Js[1], NV, T)
    _add_jt_upper(Js[1], NV, T, hess)
    # d2/dy2 dv = D0^k . (H10 J0 + H11 J1) = D0^k . (W01 + T); d2/dy2^2 = 2 cB B / g0
    Ly = sc[19]
    for k in range(3):
        for q in range(NV):
            s = 0.0
            for J in range(3):
                p = 3 * k + J
                s = fma(D0[k, p], T[p, q] + (W01[p, q] if q < NX else 0.0), s)
            Ly[k, q] = s
    if pf != 0.0:
        _pressure_hessian(pf, zf, h, cq, iota, ga0, ga1, U, lam, Zv, 9, sc[31], sc[32], hess)
        # d2/dy2 dv of -cq (pf h^2/12) y2 . n_c
        _add_cross_jacobian(Ly, 0, 0, 3, U[:, 0], U[:, 1], -cq * pf * h * h / 12.0 * iota)
    # minus Ly^T (2 cB B / g0)^{-1} Ly
    BLy = sc[18][0:3]            # (work, T is done) B^{-1} Ly
    f = g0 / (2.0 * cB)
    for k in range(3):
        for q in range(NV):
            BLy[k, q] = f * fma(Binv[k, 2], Ly[2, q], fma(Binv[k, 1], Ly[1, q], Binv[k, 0] * Ly[0, q]))
    for i in range(NV):
        for j in range(i, NV):
            hess[i, j] -= fma(Ly[2, i], BLy[2, j], fma(Ly[1, i], BLy[1, j], Ly[0, i] * BLy[0, j]))
        for j in range(i):
            hess[i, j] = hess[j, i]
    return L, OK


@njit(**KERNEL)
def _thickness_admissible(U, CF, h, f0, f1):
    """det(F0 + Z F1) > 0 for |Z| <= h/2: the through-thickness Jacobian of the
    model's deformation x = r + Z y1 + (Z^2 - h^2/12) y2 / 2 stays positive
    (with F1 = rho + y2 (x) n this includes 1 + kappa_i Z > 0, offset surfaces
    that do not fold).  det(F0 + Z F1) = d0 + d1 Z + d2 Z^2 + d3 Z^3, d0 > 0
    (checked with the material); tested at Z = +-h/2 and at the roots of its
    derivative inside."""
    _slot(U, CF[0], f0)
    _slot(U, CF[1], f1)
    a = f0.reshape(3, 3)
    b = f1.reshape(3, 3)
    d0 = det3(a)
    d3 = det3(b)
    d1 = 0.0
    d2 = 0.0
    for i in range(3):
        i1, i2 = (i + 1) % 3, (i + 2) % 3
        for j in range(3):
            j1, j2 = (j + 1) % 3, (j + 2) % 3
            d1 += b[i, j] * (a[i1, j1] * a[i2, j2] - a[i1, j2] * a[i2, j1])
            d2 += a[i, j] * (b[i1, j1] * b[i2, j2] - b[i1, j2] * b[i2, j1])
    z = 0.5 * h
    for zz in (-z, z):
        if not d0 + zz * (d1 + zz * (d2 + zz * d3)) > 0.0:
            return False
    # p'(Z) = d1 + 2 d2 Z + 3 d3 Z^2
    qa, qb, qc = 3.0 * d3, 2.0 * d2, d1
    if qa != 0.0:
        disc = qb * qb - 4.0 * qa * qc
        if disc > 0.0:
            sq = np.sqrt(disc)
            for zz in ((-qb - sq) / (2.0 * qa), (-qb + sq) / (2.0 * qa)):
                if -z < zz < z and not d0 + zz * (d1 + zz * (d2 + zz * d3)) > 0.0:
                    return False
    elif qb != 0.0:
        zz = -qc / qb
        if -z < zz < z and not d0 + zz * (d1 + zz * (d2 + zz * d3)) > 0.0:
            return False
    return True


@njit(**KERNEL)
def _y1_residual(g0, m, y, D0, W, P, AA, res, B):
    """Residual c0 = P n - m, its Jacobian B (acoustic tensor), and the merit
    phi = g0 W - m.y whose minimizer over y is the root."""
    rn = 0.0
    for k in range(3):
        res[k] = g0 * _dot9(P, D0[k]) - m[k]
        rn += res[k] * res[k]
        for l in range(3):
            s = 0.0
            for p in range(9):
                if D0[k, p] != 0.0:
                    s += D0[k, p] * (AA[p, 3 * l] * D0[l, 3 * l] + AA[p, 3 * l + 1] * D0[l, 3 * l + 1]
                                     + AA[p, 3 * l + 2] * D0[l, 3 * l + 2])
            B[k, l] = g0 * s
    return g0 * W - (m[0] * y[0] + m[1] * y[1] + m[2] * y[2]), rn


@njit(**KERNEL)
def _solve_y1(kind, psi, params, g0, m, CA0, U, y1, D0, A0, mv, mm, mp, B, LB, work, Bs):
    """Newton with backtracking for P(F0) n = m, i.e. the minimum over y1 of
    g0 W(A0) - m.y1 (convex along the rank-one family F_t + y1 (x) n).
    On return (OK) the material state, B and chol(B) belong to the root."""
    for i in range(3):
        U[i, Y1_BLOCK] = y1[i]
    _slot(U, CA0, A0)
    st = mat_prepare(kind, psi, params, A0.reshape(3, 3), mv, mm, mp)
    if st != 0:
        return ERR_INVERTED if st == 1 else ERR_LAW
    res, ytry, step = work[0], work[1], work[2]
    phi, rn = _y1_residual(g0, m, y1, D0, mp[S_W], mv[V_P], mm[M_AA], res, B)
    for it in range(_Y1_MAXIT):
        shifted = not chol3(B, LB)
        if shifted:
            # away from the root a non-convex law may have an indefinite B:
            # modified Newton step (B + sigma I), energy decrease enforced below
            sigma = 1e-8 * (abs(B[0, 0]) + abs(B[1, 1]) + abs(B[2, 2]) + 1e-300)
            for _ in range(60):
                for k in range(3):
                    for l in range(3):
                        Bs[k, l] = B[k, l] + (sigma if k == l else 0.0)
                if chol3(Bs, LB):
                    break
                sigma *= 10.0
        chol3_solve(LB, res, step)
        slope = 0.0
        ynorm = 0.0
        snorm = 0.0
        for k in range(3):
            step[k] = -step[k]
            slope += res[k] * step[k]
            ynorm += y1[k] * y1[k]
            snorm += step[k] * step[k]
        if not shifted and snorm <= 1e-28 * ynorm:
            return OK         # already the root to round-off (warm start)
        # quadratic convergence: this step is the last
        polish = not shifted and snorm <= 1e-20 * ynorm
        alpha = 1.0
        accepted = False
        for _ in range(40):
            for i in range(3):
                ytry[i] = y1[i] + alpha * step[i]
                U[i, Y1_BLOCK] = ytry[i]
            _slot(U, CA0, A0)
            st = mat_prepare(kind, psi, params, A0.reshape(3, 3), mv, mm, mp)
            if st == 2:
                return ERR_LAW
            if st == 0:
                phin, rnn = _y1_residual(g0, m, ytry, D0, mp[S_W], mv[V_P], mm[M_AA], res, B)
                if polish or phin <= phi + 1e-4 * alpha * slope or rnn < rn:
                    accepted = True
                    break
            alpha *= 0.5
        if not accepted:
            return ERR_Y1_NEWTON if st == 0 else ERR_INVERTED
        for i in range(3):
            y1[i] = ytry[i]
        phi, rn = phin, rnn
        if polish:
            return OK if chol3(B, LB) else ERR_ELLIPTICITY
    return ERR_Y1_NEWTON


@njit(**KERNEL)
def _membrane_derivatives(mode, cW, g0, CA0, D0, P, AA, Binv, grad, hess, sc,
                          pf, zf, h, iota, ga0, ga1, U):
    """Membrane level: L = cW W(A0) - h m.y1, envelope in y1 (multiplier 0);
    a face pressure makes m depend on v (m_p, docs/pressure.md)."""
    Lx, cx = sc[14], sc[15]
    for q in range(NXI):
        Lx[q] = 0.0
        for k in range(3):
            cx[k, q] = 0.0
    g = sc[10][10]
    for p in range(9):
        g[p] = cW * P[p]
    _add_to_xi(g, CA0, 1.0, Lx)
    if pf != 0.0:
        _pressure_gradient(pf, zf, h, 0.0, iota, ga0, ga1, U, Lx, cx, False)
    for q in range(NV):
        grad[q] = Lx[q]
    if mode < MODE_HESSIAN:
        return
    # dy1/dv = -B^{-1} dc0/dv, dc0_k/dA0 = g0 AA D0^k
    tmp = sc[10][11]
    for k in range(3):
        _matvec_block(AA, D0[k], k, tmp)
        _add_to_xi(tmp, CA0, g0, cx[k])
    Zv = sc[16]
    _solve_b(Binv, cx[0:3], Zv[0:3])
    Js = sc[17]
    _slot_jacobian(CA0, Zv, NX, Js[0])
    H = sc[13][2]
    for p in range(9):
        for q in range(9):
            H[p, q] = cW * AA[p, q]
    for a in range(NV):
        for b in range(NV):
            hess[a, b] = 0.0
    _h_j(H, Js[0], NX, sc[18])
    _add_jt(Js[0], NX, sc[18], NX, hess)
    if pf != 0.0:
        lam = sc[20]
        for r in range(9):
            lam[r] = 0.0
        _pressure_hessian(pf, zf, h, 0.0, iota, ga0, ga1, U, lam, Zv, 3, sc[31], sc[32], hess)
        for i in range(NV):
            for j in range(i):
                hess[i, j] = hess[j, i]


# ---------------------------------------------------------------------------
# follower pressure on a face (docs/pressure.md)
# ---------------------------------------------------------------------------
# With n_c = iota r_1 x r_2 (iota = 1/|R_1 x R_2|) the pressure pf on the face
# Z = zf is, per reference area and to the order of the model,
#   -pf [V(r) density + zf y1.n_c + (h^2/12) y2.n_c + (zf^2/2) iota y1.(Y_1 x r_2 + r_1 x Y_2)]
# = face tractions m_p = (pf zf/h) n_c, qbar_p = (pf/h) n_c, dm_p = (pf zf/h) n_c,a
#   that follow the deformation, plus the face-area term; V(r) is the discretization's.

@njit(**KERNEL, inline="always")
def _eps(k, i, j):
    """Levi-Civita symbol."""
    return 0.5 * (i - j) * (j - k) * (k - i)


@njit(**KERNEL)
def _cross_into(x, y, c, out, o):
    """out[o:o+3] += c x cross y."""
    out[o] += c * (x[1] * y[2] - x[2] * y[1])
    out[o + 1] += c * (x[2] * y[0] - x[0] * y[2])
    out[o + 2] += c * (x[0] * y[1] - x[1] * y[0])


@njit(**KERNEL)
def _add_cross_jacobian(M, row, cx_, cy, x, y, c):
    """M[row:row+3, cx_:cx_+3] += c d(x cross y)/dx, M[row:row+3, cy:cy+3] += c d(x cross y)/dy."""
    for k in range(3):
        for i in range(3):
            for j in range(3):
                e = c * _eps(k, i, j)
                if e != 0.0:
                    M[row + k, cx_ + i] += e * y[j]
                    M[row + k, cy + j] += e * x[i]


@njit(**KERNEL)
def _add_cross_pair(M, bx, by, w, c):
    """Second derivatives of c w.(x cross y) between the blocks x (at bx) and y (at by)."""
    for k in range(3):
        for i in range(3):
            for j in range(3):
                e = c * _eps(k, i, j) * w[k]
                if e != 0.0:
                    M[bx + i, by + j] += e
                    M[by + j, bx + i] += e


@njit(**KERNEL)
def _pressure_loads(pf, zf, h, iota, ga0, ga1, v, ff, qbar, m, dm):
    """Add m_p, qbar_p, dm_p to the point's loads (v local, ff = r_1 x r_2)."""
    cm = pf * zf / h * iota
    for k in range(3):
        m[k] += cm * ff[k]
        qbar[k] += pf / h * iota * ff[k]
        dm[0, k] -= cm * ga0 * ff[k]
        dm[1, k] -= cm * ga1 * ff[k]
    # n_c,a = iota (r_1a x r_2 + r_1 x r_2a) - (j_a/j) n_c; r_11, r_12, r_22 = v[6:9], v[9:12], v[12:15]
    _cross_into(v[6:9], v[3:6], cm, dm[0], 0)
    _cross_into(v[0:3], v[9:12], cm, dm[0], 0)
    _cross_into(v[9:12], v[3:6], cm, dm[1], 0)
    _cross_into(v[0:3], v[12:15], cm, dm[1], 0)


@njit(**KERNEL)
def _pressure_face_area_term(pf, zf, iota, U):
    """-pf (zf^2/2) iota y1.(Y_1 x r_2 + r_1 x Y_2) (consistent level)."""
    r1, r2, y1, Y1, Y2 = U[:, 0], U[:, 1], U[:, 5], U[:, 6], U[:, 7]
    s = 0.0
    for k in range(3):
        for i in range(3):
            for j in range(3):
                e = _eps(k, i, j)
                if e != 0.0:
                    s += e * y1[k] * (Y1[i] * r2[j] + r1[i] * Y2[j])
    return -pf * 0.5 * zf * zf * iota * s


@njit(**KERNEL)
def _pressure_gradient(pf, zf, h, cq, iota, ga0, ga1, U, Lx, cx, bend):
    """Face pressure: v- and z-derivatives of -h m_p.y1 - cq h^3/12 qbar_p.y2 +
    face-area term into Lx, and -d(m_p, dm_p)/dv into the constraint rows of cx
    (dm_p only if bend)."""
    r1, r2, y1, Y1, Y2, y2 = U[:, 0], U[:, 1], U[:, 5], U[:, 6], U[:, 7], U[:, 8]
    cz = cq * pf * 0.5 * zf * zf * iota            # face-area term: -cz y1.(Y_1 x r_2 + r_1 x Y_2)
    for k in range(3):
        w = pf * zf * y1[k] + cq * pf * h * h / 12.0 * y2[k]   # -iota w.(r_1 x r_2)
        for i in range(3):
            for j in range(3):
                e = _eps(k, i, j)
                if e == 0.0:
                    continue
                Lx[i] -= iota * e * w * r2[j]          # d/dr_1
                Lx[3 + j] -= iota * e * w * r1[i]      # d/dr_2
                if cz != 0.0:
                    # y1_k (Y1_i r2_j + r1_i Y2_j)
                    Lx[i] -= cz * e * y1[k] * Y2[j]
                    Lx[3 + j] -= cz * e * y1[k] * Y1[i]
                    Lx[3 * Y1_BLOCK + k] -= cz * e * (Y1[i] * r2[j] + r1[i] * Y2[j])
                    Lx[3 * Y1_BLOCK + 3 + i] -= cz * e * y1[k] * r2[j]
                    Lx[3 * Y1_BLOCK + 6 + j] -= cz * e * y1[k] * r1[i]
    cm = pf * zf / h * iota
    _add_cross_jacobian(cx, 0, 0, 3, r1, r2, -cm)
    if bend:
        for a_ in range(2):
            row = 3 + 3 * a_
            ga = ga0 if a_ == 0 else ga1
            b1a, b2a = (6, 9) if a_ == 0 else (9, 12)      # columns of r_1a, r_2a
            _add_cross_jacobian(cx, row, b1a, 3, U[:, 2 + a_], r2, -cm)
            _add_cross_jacobian(cx, row, 0, b2a, r1, U[:, 3 + a_], -cm)
            _add_cross_jacobian(cx, row, 0, 3, r1, r2, cm * ga)


@njit(**KERNEL)
def _pressure_hessian(pf, zf, h, cq, iota, ga0, ga1, U, lam, Zv, nz, M, T, hess):
    """Face pressure: the Hessian of (-h m_p.y1 + face-area term + lam.c_p) in
    (v, y1, Y1, Y2) (c_p = -(m_p, dm_p)), mapped by [I; Zv[:nz]] and added to
    the upper triangle of hess.  The y2 part is the caller's (condensed)."""
    n = NV + 9
    for p in range(n):
        for q in range(n):
            M[p, q] = 0.0
    r1, r2, y1, Y1, Y2 = U[:, 0], U[:, 1], U[:, 5], U[:, 6], U[:, 7]
    z = NV                                   # y1 at z, Y1 at z + 3, Y2 at z + 6
    cm = pf * zf / h * iota
    w = T[0, 0:3]                            # (scratch) -iota (pf zf y1 + cq pf h^2/12 y2) - cm lam0 + ...
    for k in range(3):
        w[k] = (-iota * (pf * zf * y1[k] + cq * pf * h * h / 12.0 * U[k, 8]) - cm * lam[k]
                + cm * (ga0 * lam[3 + k] + ga1 * lam[6 + k]))
    _add_cross_pair(M, 0, 3, w, 1.0)                     # r_1 - r_2
    _add_cross_pair(M, z, 0, r2, -iota * pf * zf)        # y1 - r_1  (y1.(r_1 x r_2) = r_2.(y1 x r_1))
    _add_cross_pair(M, 3, z, r1, -iota * pf * zf)        # r_2 - y1  (= r_1.(r_2 x y1))
    for a_ in range(2):
        la = lam[3 + 3 * a_:6 + 3 * a_]
        b1a, b2a = (6, 9) if a_ == 0 else (9, 12)
        _add_cross_pair(M, b1a, 3, la, -cm)              # r_1a - r_2
        _add_cross_pair(M, 0, b2a, la, -cm)              # r_1 - r_2a
    cz = cq * pf * 0.5 * zf * zf * iota
    if cz != 0.0:
        # -cz [y1.(Y1 x r_2) + y1.(r_1 x Y2)]
        _add_cross_pair(M, z + 3, 3, y1, -cz)            # Y1 - r_2
        _add_cross_pair(M, z, z + 3, r2, -cz)            # y1 - Y1
        _add_cross_pair(M, 3, z, Y1, -cz)                # r_2 - y1
        _add_cross_pair(M, 0, z + 6, y1, -cz)            # r_1 - Y2
        _add_cross_pair(M, z, 0, Y2, -cz)                # y1 - r_1
        _add_cross_pair(M, z + 6, z, r1, -cz)            # Y2 - y1
    # [I; Zv]^T M [I; Zv]: T = M[:, :NV] + M[:, z:z+nz] Zv[:nz]
    for p in range(n):
        for q in range(NV):
            s = M[p, q]
            for r in range(nz):
                s += M[p, z + r] * Zv[r, q]
            T[p, q] = s
    for i in range(NV):
        for j in range(i, NV):
            s = T[i, j]
            for r in range(nz):
                s += Zv[r, i] * T[z + r, j]
            hess[i, j] += s


def evaluate_points(mode, level, kind, psi, params, h, V, REF, G0, G1, dG0, QBAR, M, DM,
                    Y1, Y2, L, GRAD, HESS, STATUS):
    """point_kernel over N independent points (rows of the arrays), in
    parallel chunks (kernels/parallel.py).

    Y1 is the warm start (rows of zeros: none) and receives the directors.
    """
    run_chunks(_evaluate_point_range, 0, V.shape[0], mode, level, kind, psi, params, h, V, REF,
               G0, G1, dG0, QBAR, M, DM, Y1, Y2, L, GRAD, HESS, STATUS, min_chunk=64)


@njit(cache=True, nogil=True)
def _evaluate_point_range(lo, hi, mode, level, kind, psi, params, h, V, REF, G0, G1, dG0, QBAR,
                          M, DM, Y1, Y2, L, GRAD, HESS, STATUS):
    """The points lo .. hi - 1 of evaluate_points."""
    sc = new_scratch()
    for i in range(lo, hi):
        L[i], STATUS[i] = point_kernel(mode, level, kind, psi, params, h, V[i], REF[i],
                                       G0[i], G1[i], dG0[i], QBAR[i], M[i], DM[i],
                                       Y1[i], Y2[i], GRAD[i], HESS[i], sc)
