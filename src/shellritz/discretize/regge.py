"""Locking-free membrane metric of the DKT triangle (``Shell(membrane="regge")``).

Why the DKT field locks
-----------------------
The membrane metric of the DKT element, ``C = Theta^T Theta`` at the
quadrature points (dkt.py), is only second-order accurate for an
*inextensional* (isometric) motion given exactly at the nodes: the element
mean of Theta is the gradient of the linear interpolation of the positions,
whose chords shorten when a curved surface bends (relative change
``l^2 kappa dkappa / 12``), and its fluctuation has the linear normal-derivative
interpolation error of the mid-edge values.  A thin shell then pays membrane
energy ``~ h (l^2 kappa dkappa)^2`` for pure bending (``~ h^3 dkappa^2``): the
element is accurate only for ``l < sqrt(h R)`` (README, Membrane locking).

The assumed metric
------------------
Built only from quantities that an isometry leaves (almost) unchanged, in the
spirit of the Regge interpolation of the membrane strain of Neunteufel &
Schoeberl (CMAME 373, 2021, 113524: edge tangential-tangential moments of the
metric, Christiansen 2011, Li 2018):

* the *nodal* metrics ``C_i = d_i^T d_i`` of the nodal gradients (exactly
  invariant under an isometry);
* along each edge k (nodes i -> j, chart tangent t, length l) the cubic
  Hermite curve of the DKT edge (positions r_i, r_j, end derivatives
  ``d_i t``, ``d_j t``), ``r_s = c psi_c + m0 psi_0 + m1 psi_1`` with
  ``c = (r_j - r_i)/l``: its mean stretch ``E_k = mean |r_s|^2`` (invariant to
  O(l^4): the Hermite curve follows the arc, not the chord) and its mid-point
  stretch ``p_k = |r_s(1/2)|^2 = |3/2 c - (m0 + m1)/4|^2``.

Then ``A(U) = C_R + F - mean(F)`` at each quadrature point, where
``C_R`` is the constant (lowest-order Regge) metric with the edge
tangential components ``t_k^T C_R t_k = E_k``, and ``F`` the quadratic
tensor field with the vertex values ``C_i`` and mid-edge values
``M_k = (C_i + C_j)/2 + (p_k - t^T (C_i + C_j)/2 t) t t^T`` (tangential
component from the Hermite curve, the others the vertex average); ``mean`` is
the rule's weighted mean.  As the DKT shift (README, Design) makes the
positions control the element mean of Theta, here the edge curves control
the element mean of the metric (``C_R``), which is what keeps the in-plane
patch test; the nodal gradients shape the fluctuation only, and the
mid-edge ``p_k`` tie their tangential components to the positions.

The metric handed to the point kernel is A mapped onto the reference metric,
blended with the DKT metric ``C`` (README, Membrane locking):

    Chat = (1 - beta) K^T A(U) K + beta C,   beta = min(1, BLEND h / l_e),

with the constant 2x2 ``K = L_Aref^{-T} L_Cref^T`` (Cholesky factors of
A(U_ref) and C(U_ref)), so that ``K^T A(U_ref) K = C_ref``: the reference is
exactly stress free, and Chat is homogeneous of degree 2 in U (uniform growth
``r = lambda X`` stays exactly stress free; an additive ``C_ref + A(U) -
A(U_ref)`` would not).

(l_e the longest edge).  The blend is what controls the in-plane rotation of
the nodal gradients about the normal ("drilling"), which no metric sees to
first order: its stiffness is beta^2 ~ (h/l)^2 of the membrane one, the
scale of bending, while the DKT metric's parasitic strain enters only as
beta (l^2 kappa dkappa) ~ h l kappa dkappa -- no locking.  The weighting is
the membrane analogue of the t^2 / (t^2 + alpha l^2) of stabilized
shear-locking-free plate elements (Lyly, Stenberg & Vihinen, CMAME 110, 1993).
For l_e <= BLEND h the element is the DKT element.  BLEND = 2 was chosen on the
obstacle course (README, Membrane locking): 1 to 4 all cure the locking
panel; larger values move the thin pinched hemisphere back towards locking
(0.979 at 16 x 16 with 8), smaller ones make Scordelis-Lo slightly stiffer.

Tangent vectors with that metric: ``rhat_a = r_b M_ba`` with ``M`` upper
triangular, ``M^T C M = Chat`` (``M = L_C^{-T} L_hat^T`` from the Cholesky
factors: rhat is the Gram-Schmidt frame of (r_1, r_2) times the Cholesky
factor of Chat), so the point kernel gets a well-defined ``F0`` with the
assumed metric and the same tangent plane:

    m11 = sigma,  m22 = rho / sigma,  m12 = (chat12 - c12 rho) / (sigma c11),
    sigma = sqrt(chat11 / c11),  rho = sqrt(det Chat / det C).

Derivatives of M (to second order) by forward-mode jets in the 9 variables
(r_1, r_2, Ahat).
"""

import numpy as np
from numba import njit

from ..kernels import KERNEL

N_DATA = 15             # data: nodal metrics (3 x 3 components), E_k (3), p_k (3)
BLEND = 2.0             # beta = min(1, BLEND h / l_e)
N_JET = 9               # jet variables: r_1 (3), r_2 (3), K^T A K (3: 11, 12, 22)

# int_0^1 of products of (psi_c, psi_0, psi_1) = (6s - 6s^2, 1 - 4s + 3s^2, -2s + 3s^2)
EDGE_MEAN = np.array([[6.0 / 5.0, -1.0 / 10.0, -1.0 / 10.0],
                      [-1.0 / 10.0, 2.0 / 15.0, -1.0 / 30.0],
                      [-1.0 / 10.0, -1.0 / 30.0, 2.0 / 15.0]])
EDGE_MID = np.array([1.5, -0.25, -0.25])        # (psi_c, psi_0, psi_1) at s = 1/2


# The data are fixed quadratic forms of N_W vectors w, each a combination of at
# most two nodal vectors, w_p = WC[p, 0] u_{WI[p, 0]} + WC[p, 1] u_{WI[p, 1]}:
#   w_{3k}, w_{3k+1}, w_{3k+2} = c, m0 = d_i t, m1 = d_j t of edge k;
#   w_{9+2i+a} = d_i e_a (column a of the nodal gradient of node i in the chart).
N_W = 15


def _data_tables():
    wi = np.zeros((N_W, 2), np.int64)
    sup = -np.ones((N_DATA, 3), np.int64)
    gam = np.zeros((N_DATA, 3, 3))
    for k in range(3):
        i, j = (k + 1) % 3, (k + 2) % 3
        wi[3 * k] = (3 * j, 3 * i)
        wi[3 * k + 1] = (3 * i + 1, 3 * i + 2)
        wi[3 * k + 2] = (3 * j + 1, 3 * j + 2)
        for d, g in ((9 + k, EDGE_MEAN), (12 + k, np.outer(EDGE_MID, EDGE_MID))):
            sup[d] = (3 * k, 3 * k + 1, 3 * k + 2)
            gam[d] = g
    for i in range(3):
        wi[9 + 2 * i] = wi[10 + 2 * i] = (3 * i + 1, 3 * i + 2)
        for c, (a, b) in enumerate(((0, 0), (0, 1), (1, 1))):
            sup[3 * i + c, :2] = (9 + 2 * i, 10 + 2 * i)
            gam[3 * i + c, a, b] += 0.5
            gam[3 * i + c, b, a] += 0.5
    return wi, sup, gam


WI, DATA_SUPPORT, DATA_FORM = _data_tables()


@njit(**KERNEL)
def data_maps(Q, et, el, WC):
    """WC (N_W, 2): the element's coefficients of the w vectors (above).
    Data j = 3 i + (0, 1, 2): components (11, 12, 22) of C_i in the chart;
    9 + k: E_k; 12 + k: p_k (edge k = node (k+1)%3 -> (k+2)%3)."""
    for k in range(3):
        i = (k + 1) % 3
        j = (k + 2) % 3
        WC[3 * k, 0] = 1.0 / el[k]
        WC[3 * k, 1] = -1.0 / el[k]
        for s in range(2):
            WC[3 * k + 1, s] = Q[i, s, 0] * et[k, 0] + Q[i, s, 1] * et[k, 1]
            WC[3 * k + 2, s] = Q[j, s, 0] * et[k, 0] + Q[j, s, 1] * et[k, 1]
    for i in range(3):
        for a in range(2):
            for s in range(2):
                WC[9 + 2 * i + a, s] = Q[i, s, a]


@njit(**KERNEL)
def data_values(WC, blocks, w, D):
    """w (N_W, 3) of the nodal vectors blocks (9, 3) and the data D (N_DATA)."""
    for p in range(N_W):
        k, l = WI[p, 0], WI[p, 1]
        for c in range(3):
            w[p, c] = WC[p, 0] * blocks[k, c] + WC[p, 1] * blocks[l, c]
    for j in range(N_DATA):
        s = 0.0
        for a in range(3):
            pa = DATA_SUPPORT[j, a]
            if pa < 0:
                continue
            for b in range(3):
                pb = DATA_SUPPORT[j, b]
                if pb < 0:
                    continue
                s += DATA_FORM[j, a, b] * (w[pa, 0] * w[pb, 0] + w[pa, 1] * w[pb, 1]
                                           + w[pa, 2] * w[pb, 2])
        D[j] = s


@njit(**KERNEL)
def data_gradients(WC, w, dD):
    """dD (N_DATA, 27): derivatives of the data by the nodal vectors (9 x 3)."""
    for j in range(N_DATA):
        for q in range(27):
            dD[j, q] = 0.0
        for a in range(3):
            pa = DATA_SUPPORT[j, a]
            if pa < 0:
                continue
            for c in range(3):
                g = 0.0
                for b in range(3):
                    pb = DATA_SUPPORT[j, b]
                    if pb >= 0:
                        g += 2.0 * DATA_FORM[j, a, b] * w[pb, c]
                for l in range(2):
                    dD[j, 3 * WI[pa, l] + c] += WC[pa, l] * g


@njit(**KERNEL)
def add_data_hessian(WC, gamma, ke):
    """Upper triangle of ke (27, 27) += sum_j gamma_j d2 D_j / du2 (= a 9 x 9
    matrix (x) I3)."""
    for j in range(N_DATA):
        if gamma[j] == 0.0:
            continue
        for a in range(3):
            pa = DATA_SUPPORT[j, a]
            if pa < 0:
                continue
            for b in range(3):
                pb = DATA_SUPPORT[j, b]
                if pb < 0 or DATA_FORM[j, a, b] == 0.0:
                    continue
                f = 2.0 * gamma[j] * DATA_FORM[j, a, b]
                for l in range(2):
                    k1 = WI[pa, l]
                    for l2 in range(2):
                        k2 = WI[pb, l2]
                        if k1 <= k2:
                            v = f * WC[pa, l] * WC[pb, l2]
                            for c in range(3):
                                ke[3 * k1 + c, 3 * k2 + c] += v


@njit(**KERNEL)
def metric_coefficients(bary, wts, et, alpha, F):
    """alpha (nq, 3, N_DATA): A(U) at point q, components (11, 12, 22), is
    sum_j alpha[q, c, j] datum_j (module docstring).  F (nq, 3, N_DATA) work."""
    nq = bary.shape[0]
    # C_R = A^{-1} E, rows of A: (t0^2, 2 t0 t1, t1^2) (t^T C t = E)
    a00, a01, a02 = et[0, 0] ** 2, 2 * et[0, 0] * et[0, 1], et[0, 1] ** 2
    a10, a11, a12 = et[1, 0] ** 2, 2 * et[1, 0] * et[1, 1], et[1, 1] ** 2
    a20, a21, a22 = et[2, 0] ** 2, 2 * et[2, 0] * et[2, 1], et[2, 1] ** 2
    det = (a00 * (a11 * a22 - a12 * a21) - a01 * (a10 * a22 - a12 * a20)
           + a02 * (a10 * a21 - a11 * a20))
    inv = ((a11 * a22 - a12 * a21, a02 * a21 - a01 * a22, a01 * a12 - a02 * a11),
           (a12 * a20 - a10 * a22, a00 * a22 - a02 * a20, a02 * a10 - a00 * a12),
           (a10 * a21 - a11 * a20, a01 * a20 - a00 * a21, a00 * a11 - a01 * a10))
    for q in range(nq):
        lam = bary[q]
        for c in range(3):
            for j in range(N_DATA):
                F[q, c, j] = 0.0
        for i in range(3):
            N = lam[i] * (2.0 * lam[i] - 1.0)
            for c in range(3):
                F[q, c, 3 * i + c] += N
        for k in range(3):
            i = (k + 1) % 3
            j = (k + 2) % 3
            N = 4.0 * lam[i] * lam[j]
            t0, t1 = et[k, 0], et[k, 1]
            T = (t0 * t0, t0 * t1, t1 * t1)         # t t^T
            w = (t0 * t0, 2.0 * t0 * t1, t1 * t1)   # t^T X t = w . X
            # M_k = (C_i + C_j)/2 + (p_k - w.(C_i + C_j)/2) T
            for c in range(3):
                for m in (i, j):
                    F[q, c, 3 * m + c] += 0.5 * N
                    for c2 in range(3):
                        F[q, c, 3 * m + c2] -= 0.5 * N * T[c] * w[c2]
                F[q, c, 12 + k] += N * T[c]
    for q in range(nq):
        for c in range(3):
            for j in range(N_DATA):
                s = 0.0
                for q2 in range(nq):
                    s += wts[q2] * F[q2, c, j]
                alpha[q, c, j] = F[q, c, j] - s
            for k in range(3):
                alpha[q, c, 9 + k] += inv[c][k] / det


@njit(**KERNEL)
def match_reference(alpha, Dref, R):
    """alpha (3, N_DATA) of a point -> coefficients of K^T A K (module
    docstring), K from A(U_ref) = alpha Dref and the reference tangents R
    (R_1 = R[0:3], R_2 = R[3:6]).  Returns False if A(U_ref) is not positive
    definite."""
    a0 = a1 = a2 = 0.0
    for j in range(N_DATA):
        a0 += alpha[0, j] * Dref[j]
        a1 += alpha[1, j] * Dref[j]
        a2 += alpha[2, j] * Dref[j]
    if not (a0 > 0.0 and a0 * a2 - a1 * a1 > 0.0):
        return False
    g0 = R[0] * R[0] + R[1] * R[1] + R[2] * R[2]
    g1 = R[0] * R[3] + R[1] * R[4] + R[2] * R[5]
    g2 = R[3] * R[3] + R[4] * R[4] + R[5] * R[5]
    l11, l21 = np.sqrt(a0), a1 / np.sqrt(a0)
    l22 = np.sqrt(a2 - l21 * l21)
    m11, m21 = np.sqrt(g0), g1 / np.sqrt(g0)
    m22 = np.sqrt(g2 - m21 * m21)
    # K = [[k00, k01], [0, k11]]; K^T A K in components (11, 12, 22)
    k00 = m11 / l11
    k01 = m21 / l11 - l21 * m22 / (l11 * l22)
    k11 = m22 / l22
    for j in range(N_DATA):
        c0, c1, c2 = alpha[0, j], alpha[1, j], alpha[2, j]
        alpha[0, j] = k00 * k00 * c0
        alpha[1, j] = k00 * k01 * c0 + k00 * k11 * c1
        alpha[2, j] = k01 * k01 * c0 + 2.0 * k01 * k11 * c1 + k11 * k11 * c2
    return True


# ---------------------------------------------------------------------------
# forward-mode jets (value, gradient, Hessian) in the N_JET variables
# ---------------------------------------------------------------------------

# order: 0 values, 1 and gradients, 2 and Hessians.  Inlined: called with literal
# slot numbers, each call would otherwise compile a specialization of its own.

@njit(**KERNEL, inline="always")
def _jet_zero(jv, jg, jh, o, order):
    jv[o] = 0.0
    if order >= 1:
        for a in range(N_JET):
            jg[o, a] = 0.0
    if order >= 2:
        for a in range(N_JET):
            for b in range(N_JET):
                jh[o, a, b] = 0.0


@njit(**KERNEL, inline="always")
def _jet_dot(x, ia, ib, jv, jg, jh, o, order):
    """o = x[ia:ia+3] . x[ib:ib+3] for variable blocks of x."""
    _jet_zero(jv, jg, jh, o, order)
    for i in range(3):
        jv[o] += x[ia + i] * x[ib + i]
        if order >= 1:
            jg[o, ia + i] += x[ib + i]
            jg[o, ib + i] += x[ia + i]
        if order >= 2:
            jh[o, ia + i, ib + i] += 1.0
            jh[o, ib + i, ia + i] += 1.0


@njit(**KERNEL, inline="always")
def _jet_axpy(a, x, b, y, jv, jg, jh, o, order):
    """o = a x + b y (slots x, y; a, b numbers)."""
    jv[o] = a * jv[x] + b * jv[y]
    if order >= 1:
        for p in range(N_JET):
            jg[o, p] = a * jg[x, p] + b * jg[y, p]
    if order >= 2:
        for p in range(N_JET):
            for q in range(N_JET):
                jh[o, p, q] = a * jh[x, p, q] + b * jh[y, p, q]


@njit(**KERNEL, inline="always")
def _jet_mul(x, y, jv, jg, jh, o, order):
    vx, vy = jv[x], jv[y]
    jv[o] = vx * vy
    if order >= 1:
        for p in range(N_JET):
            jg[o, p] = vx * jg[y, p] + vy * jg[x, p]
    if order >= 2:
        for p in range(N_JET):
            for q in range(N_JET):
                jh[o, p, q] = (vx * jh[y, p, q] + vy * jh[x, p, q]
                               + jg[x, p] * jg[y, q] + jg[y, p] * jg[x, q])


@njit(**KERNEL, inline="always")
def _jet_unary(x, f0, f1, f2, jv, jg, jh, o, order):
    """o = f(x) with f(x) = f0, f'(x) = f1, f''(x) = f2."""
    jv[o] = f0
    if order >= 1:
        for p in range(N_JET):
            jg[o, p] = f1 * jg[x, p]
    if order >= 2:
        for p in range(N_JET):
            for q in range(N_JET):
                jh[o, p, q] = f1 * jh[x, p, q] + f2 * jg[x, p] * jg[x, q]


@njit(**KERNEL, inline="always")
def _jet_sqrt(x, jv, jg, jh, o, order):
    s = np.sqrt(jv[x])
    _jet_unary(x, s, 0.5 / s, -0.25 / (s * jv[x]), jv, jg, jh, o, order)


@njit(**KERNEL, inline="always")
def _jet_inv(x, jv, jg, jh, o, order):
    v = jv[x]
    _jet_unary(x, 1.0 / v, -1.0 / (v * v), 2.0 / (v * v * v), jv, jg, jh, o, order)


# jet slots
_C11, _C12, _C22, _H11, _H12, _H22, _DC, _DH = 0, 1, 2, 3, 4, 5, 6, 7
_SIG, _RHO, _ISIG, _IC11, _T1, _T2, _M11, _M12, _M22 = 8, 9, 10, 11, 12, 13, 14, 15, 16
N_SLOTS = 17


@njit(**KERNEL)
def tangent_map(x, beta, jv, jg, jh, order):
    """Jets of (m11, m12, m22) (module docstring) at x = (r_1, r_2, Ahat),
    Ahat = K^T A K, chat = (1 - beta) Ahat + beta c.  Returns False if C or Chat is not
    positive definite.  order: 0 values, 1 and gradients, 2 and Hessians."""
    _jet_dot(x, 0, 0, jv, jg, jh, _C11, order)
    _jet_dot(x, 0, 3, jv, jg, jh, _C12, order)
    _jet_dot(x, 3, 3, jv, jg, jh, _C22, order)
    for c in range(3):
        o = _H11 + c
        _jet_zero(jv, jg, jh, o, order)
        jv[o] = x[6 + c]
        if order >= 1:
            jg[o, 6 + c] = 1.0
        _jet_axpy(1.0 - beta, o, beta, _C11 + c, jv, jg, jh, o, order)
    # det C, det Chat
    _jet_mul(_C11, _C22, jv, jg, jh, _T1, order)
    _jet_mul(_C12, _C12, jv, jg, jh, _T2, order)
    _jet_axpy(1.0, _T1, -1.0, _T2, jv, jg, jh, _DC, order)
    _jet_mul(_H11, _H22, jv, jg, jh, _T1, order)
    _jet_mul(_H12, _H12, jv, jg, jh, _T2, order)
    _jet_axpy(1.0, _T1, -1.0, _T2, jv, jg, jh, _DH, order)
    if not (jv[_C11] > 0.0 and jv[_DC] > 0.0 and jv[_H11] > 0.0 and jv[_DH] > 0.0):
        return False
    # sigma = sqrt(chat11 / c11), rho = sqrt(det Chat / det C)
    _jet_inv(_C11, jv, jg, jh, _IC11, order)
    _jet_mul(_H11, _IC11, jv, jg, jh, _T1, order)
    _jet_sqrt(_T1, jv, jg, jh, _SIG, order)
    _jet_inv(_DC, jv, jg, jh, _T1, order)
    _jet_mul(_DH, _T1, jv, jg, jh, _T2, order)
    _jet_sqrt(_T2, jv, jg, jh, _RHO, order)
    _jet_inv(_SIG, jv, jg, jh, _ISIG, order)
    _jet_axpy(1.0, _SIG, 0.0, _SIG, jv, jg, jh, _M11, order)
    _jet_mul(_RHO, _ISIG, jv, jg, jh, _M22, order)
    # m12 = (chat12 - c12 rho) / (sigma c11)
    _jet_mul(_C12, _RHO, jv, jg, jh, _T1, order)
    _jet_axpy(1.0, _H12, -1.0, _T1, jv, jg, jh, _T2, order)
    _jet_mul(_ISIG, _IC11, jv, jg, jh, _T1, order)
    _jet_mul(_T2, _T1, jv, jg, jh, _M12, order)
    return True


@njit(**KERNEL)
def tangent_vectors(x, jv, jg, rhat, J, order):
    """rhat = (rhat_1, rhat_2) (6) and, for order >= 1, J = d rhat / d x
    (6, N_JET) after tangent_map: rhat_1 = m11 r_1, rhat_2 = m12 r_1 + m22 r_2."""
    m11, m12, m22 = jv[_M11], jv[_M12], jv[_M22]
    for i in range(3):
        r1, r2 = x[i], x[3 + i]
        rhat[i] = m11 * r1
        rhat[3 + i] = m12 * r1 + m22 * r2
        if order == 0:
            continue
        for p in range(N_JET):
            J[i, p] = r1 * jg[_M11, p]
            J[3 + i, p] = r1 * jg[_M12, p] + r2 * jg[_M22, p]
        J[i, i] += m11
        J[3 + i, i] += m12
        J[3 + i, 3 + i] += m22


@njit(**KERNEL)
def tangent_curvature(x, g, jv, jg, jh, H, phi):
    """H (N_JET, N_JET) = d2/dx2 of g . rhat(x) for a fixed g (6):
    g . rhat = m11 (g_1 . r_1) + m12 (g_2 . r_1) + m22 (g_2 . r_2).
    phi (3, N_JET) work: gradients of the three brackets."""
    for k in range(3):
        for p in range(N_JET):
            phi[k, p] = 0.0
    v1 = v2 = v3 = 0.0
    for i in range(3):
        v1 += g[i] * x[i]
        v2 += g[3 + i] * x[i]
        v3 += g[3 + i] * x[3 + i]
        phi[0, i] = g[i]
        phi[1, i] = g[3 + i]
        phi[2, 3 + i] = g[3 + i]
    for p in range(N_JET):
        for q in range(N_JET):
            H[p, q] = (v1 * jh[_M11, p, q] + v2 * jh[_M12, p, q] + v3 * jh[_M22, p, q]
                       + jg[_M11, p] * phi[0, q] + phi[0, p] * jg[_M11, q]
                       + jg[_M12, p] * phi[1, q] + phi[1, p] * jg[_M12, q]
                       + jg[_M22, p] * phi[2, q] + phi[2, p] * jg[_M22, q])
