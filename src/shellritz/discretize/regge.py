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
The first-order Regge interpolant of the metric of a conforming position
field, as the membrane strain of the HHJ/TDNNS shells is (Neunteufel &
Schoeberl, CMAME 373, 2021, 113524: the Regge interpolant of the metric,
Christiansen 2011, Li 2018), with the DKT element's own degrees of freedom:

* the position field is the reduced cubic (BCIZ: Bazeley, Cheung, Irons &
  Zienkiewicz 1965) of the nodal positions and gradients, cubic_gradient:
  its edge traces are the cubic Hermite curves of the DKT edges, so it is
  continuous between elements, and it reproduces quadratic fields;
* its metric g = Bc^T Bc is represented by the degrees of freedom of the
  first-order Regge element (data_forms): on each edge k the moments
  ``int_0^1 g_tt (1, 2s - 1) ds`` of the tangential stretch of the Hermite
  curve (which follows the arc, not the chord: invariant under an isometry
  to O(l^4)), and the element mean of g;
* R(U), the linear symmetric tensor field with those degrees of freedom
  (metric_coefficients), is the membrane metric.

An isometric bending of a panel given exactly at the nodes changes R by
O(l^4) (DKT: O(l^2)), tested; the second-order Regge interpolant (edge
moments to degree 2, interior moments against linear functions) sees the
O(l^2) pointwise error of the reduced cubic and changes by O(l^2) (tried:
a third of the DKT change), so it would lock.

Since the element mean of R is that of a conforming field's metric, a
uniform stress S does on R the work it does on g: ``int S : dR = int S : dg``
and ``int S : d2R = int S : d2g``.  So the uniform state of the in-plane
patch test is an exact equilibrium when the boundary data of the element
(positions and nodal gradients) are exact, and the geometric stiffness of a
uniform tension is that of the conforming field, positive: no spurious
instability under finite strain (the lowest-order Regge interpolant of the
edge arcs alone, an earlier version, had them: README, Membrane locking).
With the positions alone prescribed on a boundary, its Hermite edge curves
bow between the nodes under a tension, as a membrane pinned at points does
(README).  The element mean is also three constraints per element on top of
the six edge moments: on elements long across the bending they are too many
for the discrete near-isometric motions and the metric locks (README,
Membrane locking: without them the patch test fails).

Neither R's edge moments nor its mean see a uniform in-plane rotation of the
nodal gradients about the normal ("drilling") to first order; the pointwise
metric g of the reduced cubic does.  The metric handed on is the blend

    A(U) = (1 - beta) R(U) + beta g(U),   beta = min(1, BLEND h / l_e)

(l_e the longest edge), and beta = 1 on triangles thin against the thickness
(height 2 A / l_e below h / 2, the elements that carry the strain-gradient
term: strain_gradient.dkt_active_elements): on such a sliver R is rebuilt
from the data of nearly parallel edges and amplifies their errors (a flap of
height 0.3 h, 0.15 h, 0.01 h on the edge of a grown square added 3.6, 6.3,
12.6 % to its energy with the blend, 0.65, 0.34, 0.024 % with g there;
tests/test_validity.py).  g - R has zero element mean (the 6- and 7-point
rules integrate the quartic g exactly), so the blend leaves the two
identities above, and with them the patch test, alone, whatever beta is in
neighbouring elements.  The drilling stiffness is beta^2 ~ (h/l)^2 of the
membrane one, the scale of bending, while g's O(l^2 kappa dkappa) parasitic
strain enters only as beta l^2 kappa dkappa ~ h l kappa dkappa -- no
locking.  The weighting is the membrane analogue of the t^2 / (t^2 + alpha
l^2) of stabilized shear-locking-free plate elements (Lyly, Stenberg &
Vihinen, CMAME 110, 1993).  BLEND = 2: BLEND = 1, 2, 4 give the obstacle
course and the panels of README, Membrane locking to 0.1 %; on the
gradient-growth strip (h/l_e 0.2 to 0.4) none is best at every mesh: errors
3.7e-4, 2.6e-4, 1.0e-4 (1), 2.8e-3, 8.8e-5, 8.9e-5 (2), 1.3e-2, 3.1e-4,
6.8e-5 (4) at 20, 40, 80 elements; 2 is kept from the earlier version.

A is mapped onto the reference metric,

    Chat = K^T A(U) K,

with the constant 2x2 ``K = L_Aref^{-T} L_Cref^T`` (Cholesky factors of
A(U_ref) and of the DKT metric C(U_ref)), so that ``Chat(U_ref) = C_ref``:
the reference is exactly stress free, and Chat is homogeneous of degree 2
in U (uniform growth ``r = lambda X`` stays exactly stress free; an additive
``C_ref + A(U) - A(U_ref)`` would not).

Tangent vectors with that metric: ``rhat_a = r_b M_ba`` (r_a those of the DKT
field) with ``M`` upper triangular, ``M^T C M = Chat`` (``M = L_C^{-T} L_hat^T`` from the Cholesky
factors: rhat is the Gram-Schmidt frame of (r_1, r_2) times the Cholesky
factor of Chat), so the point kernel gets a well-defined ``F0`` with the
assumed metric and the same tangent plane:

    m11 = sigma,  m22 = rho / sigma,  m12 = (chat12 - c12 rho) / (sigma c11),
    sigma = sqrt(chat11 / c11),  rho = sqrt(det Chat / det C).

Derivatives of M (to second order) by forward-mode jets in the 9 variables
(r_1, r_2, Chat).
"""

import numpy as np
from numba import njit

from ..kernels import KERNEL
from .dkt import RULES

N_REGGE = 9             # the first-order Regge dofs: edge moments (3 x 2), element mean (3)
MAX_POINTS = max(len(w) for _, w in RULES.values())   # largest rule of the element
N_DATA = N_REGGE + 3 * MAX_POINTS   # + the metric of the reduced cubic at each point
BLEND = 2.0             # beta = min(1, BLEND h / l_e)
N_JET = 9               # jet variables: r_1 (3), r_2 (3), K^T A K (3: 11, 12, 22)

# 3-point Gauss-Legendre rule on [0, 1]: exact to degree 5 (g_tt quartic x linear)
EDGE_S = np.array([0.5 - 0.5 * np.sqrt(0.6), 0.5, 0.5 + 0.5 * np.sqrt(0.6)])
EDGE_W = np.array([5.0 / 18.0, 8.0 / 18.0, 5.0 / 18.0])


@njit(**KERNEL)
def cubic_gradient(lam, Q, gl, P, Bc):
    """Bc (2, 9): chart gradient of the reduced cubic (BCIZ) position field at
    barycentric lam, dr/dxi_a = sum_k Bc[a, k] u_k over the nodal vectors
    (r_0, a_01, a_02, r_1, ...).  The field is
        r = sum_i r_i N_i + sum_i sum_{j != i} delta_ij P_ij,
        N_i = 3 lam_i^2 - 2 lam_i^3 + 2 b,  P_ij = lam_i^2 lam_j + b / 2,
    b = lam_0 lam_1 lam_2, delta_ij = d_i (p_j - p_i) the nodal gradient along
    the edge (P chart vertex positions (3, 2)): the cubic Hermite triangle with
    its centroid value set to (1/3) sum_i (r_i + d_i (p_c - p_i) / 2), which
    reproduces quadratic fields.  Its edge traces are the cubic Hermite curves
    of the DKT edges (b = 0 there): the field is continuous between elements."""
    l0, l1, l2 = lam[0], lam[1], lam[2]
    for a in range(2):
        db = l1 * l2 * gl[0, a] + l0 * l2 * gl[1, a] + l0 * l1 * gl[2, a]
        for i in range(3):
            li = lam[i]
            Bc[a, 3 * i] = (6.0 * li - 6.0 * li * li) * gl[i, a] + 2.0 * db
            Bc[a, 3 * i + 1] = 0.0
            Bc[a, 3 * i + 2] = 0.0
            for j in range(3):
                if j == i:
                    continue
                dP = 2.0 * li * lam[j] * gl[i, a] + li * li * gl[j, a] + 0.5 * db
                for s in range(2):
                    f = (Q[i, s, 0] * (P[j, 0] - P[i, 0]) + Q[i, s, 1] * (P[j, 1] - P[i, 1]))
                    Bc[a, 3 * i + 1 + s] += f * dP


@njit(**KERNEL)
def data_forms(Q, gl, et, el, bary, wts, G, P, Bc, lam):
    """G (N_DATA, 9, 9): the data as quadratic forms of the element's nodal
    vectors, datum_j = sum_pq G[j, p, q] u_p . u_q, of the reduced cubic's
    metric g = Bc^T Bc (cubic_gradient):
      j = 2 k + m: the moments int_0^1 g_tt (1, 2s - 1) ds along edge k
        (node (k+1)%3 -> (k+2)%3, s from 0 to 1, t its chart unit tangent);
      j = 6 + c: the element mean of g, components c = (11, 12, 22)
    (the degrees of freedom of the first-order Regge element);
      j = N_REGGE + 3 q + c: g at the element's quadrature point q (bary).
    The element mean is the rule's (bary, wts) weighted mean of the point
    values: the 6- and 7-point rules that membrane="regge" needs integrate
    the quartic g exactly.  P (3, 2), Bc (2, 9), lam (3) work."""
    # chart vertex positions (p_0 = 0; edge k runs from node k+1 to node k+2)
    P[0, 0] = 0.0
    P[0, 1] = 0.0
    P[1, 0] = el[2] * et[2, 0]
    P[1, 1] = el[2] * et[2, 1]
    P[2, 0] = -el[1] * et[1, 0]
    P[2, 1] = -el[1] * et[1, 1]
    # upper triangles (p <= q), mirrored at the end
    for j in range(N_REGGE):
        for p in range(9):
            for q in range(p, 9):
                G[j, p, q] = 0.0
    for k in range(3):
        i = (k + 1) % 3
        jn = (k + 2) % 3
        t0, t1 = et[k, 0], et[k, 1]
        for g in range(3):
            s = EDGE_S[g]
            lam[k] = 0.0
            lam[i] = 1.0 - s
            lam[jn] = s
            cubic_gradient(lam, Q, gl, P, Bc)
            for p in range(9):          # Bc[0] now holds the tangential derivative t . Bc
                Bc[0, p] = t0 * Bc[0, p] + t1 * Bc[1, p]
            w0 = EDGE_W[g]
            w1 = EDGE_W[g] * (2.0 * s - 1.0)
            for p in range(9):
                for q in range(p, 9):
                    v = Bc[0, p] * Bc[0, q]
                    G[2 * k, p, q] += w0 * v
                    G[2 * k + 1, p, q] += w1 * v
    for g in range(bary.shape[0]):
        cubic_gradient(bary[g], Q, gl, P, Bc)
        j = N_REGGE + 3 * g
        for p in range(9):
            for q in range(p, 9):
                G[j, p, q] = Bc[0, p] * Bc[0, q]
                G[j + 1, p, q] = 0.5 * (Bc[0, p] * Bc[1, q] + Bc[1, p] * Bc[0, q])
                G[j + 2, p, q] = Bc[1, p] * Bc[1, q]
                for c in range(3):
                    G[6 + c, p, q] += wts[g] * G[j + c, p, q]
    for j in range(N_REGGE + 3 * bary.shape[0]):
        for p in range(9):
            for q in range(p + 1, 9):
                G[j, q, p] = G[j, p, q]


@njit(**KERNEL)
def data_values(G, nd, blocks, gram, D):
    """The data D[:nd] of the nodal vectors blocks (9, 3) (nd = N_REGGE + 3
    points: the others are not used); gram (9, 9) work."""
    for p in range(9):
        for q in range(p, 9):
            v = blocks[p, 0] * blocks[q, 0] + blocks[p, 1] * blocks[q, 1] + blocks[p, 2] * blocks[q, 2]
            gram[p, q] = v
            gram[q, p] = v
    for j in range(nd):
        s = 0.0
        for p in range(9):
            s += 0.5 * G[j, p, p] * gram[p, p]
            for q in range(p + 1, 9):
                s += G[j, p, q] * gram[p, q]
        D[j] = 2.0 * s          # G and gram symmetric


@njit(**KERNEL)
def data_gradients(G, nd, blocks, dD):
    """dD[:nd] (27 each): derivatives of the data by the nodal vectors blocks (9 x 3)."""
    for j in range(nd):
        for p in range(9):
            for c in range(3):
                s = 0.0
                for q in range(9):
                    s += G[j, p, q] * blocks[q, c]
                dD[j, 3 * p + c] = 2.0 * s


@njit(**KERNEL)
def add_data_hessian(G, nd, gamma, ke):
    """Upper triangle of ke (27, 27) += sum_{j < nd} gamma_j d2 D_j / du2 (= 2
    sum_j gamma_j G_j (x) I3)."""
    for p in range(9):
        for q in range(p, 9):
            s = 0.0
            for j in range(nd):
                s += gamma[j] * G[j, p, q]
            for c in range(3):
                ke[3 * p + c, 3 * q + c] += 2.0 * s


@njit(**KERNEL)
def metric_coefficients(bary, et, beta, alpha, M):
    """alpha (nq, 3, N_DATA): A(U) at point q, components (11, 12, 22), is
    sum_j alpha[q, c, j] datum_j (data_forms):
        A = (1 - beta) R + beta g,
    R the first-order Regge field (linear, R = sum_m lam_m R_m) with the
    degrees of freedom of the reduced cubic's metric g, and g itself at the
    point.  M (N_REGGE, 2 N_REGGE) work: the dofs of the basis fields
    lam_m e_c (column 3 m + c), inverted by Gauss-Jordan elimination
    (written out: the kernels run without Numba's runtime, which np.linalg
    needs)."""
    n = N_REGGE
    for r in range(n):
        for c in range(2 * n):
            M[r, c] = 0.0
        M[r, n + r] = 1.0
    # int_0^1 lam (1, 2s - 1) ds along edge k for its start (lam = 1 - s) and end (s) node
    for k in range(3):
        i = (k + 1) % 3
        j = (k + 2) % 3
        w = (et[k, 0] * et[k, 0], 2.0 * et[k, 0] * et[k, 1], et[k, 1] * et[k, 1])
        for c in range(3):
            M[2 * k, 3 * i + c] = 0.5 * w[c]
            M[2 * k, 3 * j + c] = 0.5 * w[c]
            M[2 * k + 1, 3 * i + c] = -w[c] / 6.0
            M[2 * k + 1, 3 * j + c] = w[c] / 6.0
    for m in range(3):
        for c in range(3):
            M[6 + c, 3 * m + c] = 1.0 / 3.0
    for col in range(n):
        piv = col
        for r in range(col + 1, n):
            if abs(M[r, col]) > abs(M[piv, col]):
                piv = r
        if piv != col:
            for c in range(2 * n):
                M[col, c], M[piv, c] = M[piv, c], M[col, c]
        d = 1.0 / M[col, col]
        for c in range(2 * n):
            M[col, c] *= d
        for r in range(n):
            if r != col and M[r, col] != 0.0:
                f = M[r, col]
                for c in range(2 * n):
                    M[r, c] -= f * M[col, c]
    # M[:, n:] is the inverse: field coefficient 3 m + c = sum_j M[3 m + c, n + j] datum_j
    for q in range(bary.shape[0]):
        for c in range(3):
            for j in range(N_DATA):
                alpha[q, c, j] = 0.0
            for j in range(n):
                s = 0.0
                for m in range(3):
                    s += bary[q, m] * M[3 * m + c, n + j]
                alpha[q, c, j] = (1.0 - beta) * s
            alpha[q, c, N_REGGE + 3 * q + c] = beta


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
def tangent_map(x, jv, jg, jh, order):
    """Jets of (m11, m12, m22) (module docstring) at x = (r_1, r_2, Chat),
    Chat = K^T A K.  Returns False if C or Chat is not positive definite.  order: 0 values, 1 and gradients, 2 and Hessians."""
    _jet_dot(x, 0, 0, jv, jg, jh, _C11, order)
    _jet_dot(x, 0, 3, jv, jg, jh, _C12, order)
    _jet_dot(x, 3, 3, jv, jg, jh, _C22, order)
    for c in range(3):
        o = _H11 + c
        _jet_zero(jv, jg, jh, o, order)
        jv[o] = x[6 + c]
        if order >= 1:
            jg[o, 6 + c] = 1.0
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
