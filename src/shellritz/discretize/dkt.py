"""Discrete Kirchhoff triangle with position-gradient degrees of freedom (DESIGN.md).

Per node i: position r_i and the derivatives a_i1, a_i2 of r along the nodal
reference tangent unit vectors T_i1, T_i2 (9 DOFs; reference state
r_i = X_i, a_ia = T_ia).  In a triangle, with orthonormal coordinates xi of
the flat facet (frame E_1, E_2), the nodal gradient in facet coordinates is
d_i = [a_i1 a_i2] Q_i, Q_i[a, b] = T_ia . E_b.  The gradient field
Theta(xi) (3x2) is quadratic over the 6 vertex and mid-edge points, with the
discrete Kirchhoff rule on each edge i-j (length l, unit tangent t):

    Theta_mid t = 3/(2 l) (r_j - r_i) - (d_i t + d_j t)/4     (cubic along the edge)
    Theta_mid nu = (d_i nu + d_j nu)/2                          (linear along the edge)

so Theta_mid = 3/(2l) (r_j - r_i) t^T + (d_i + d_j)(I - 3/2 t t^T)/2.  Then
r_a = Theta e_a and r_ab = sym(d Theta / d xi).  At each quadrature point this
is a fixed linear map b (5 x 9) from the 9 nodal 3-vectors of the element to
v = (r_1, r_2, r_11, r_12, r_22) (the map acts on each spatial component
alike: B = b (x) I_3).  The same map applied to the reference DOFs gives the
reference derivatives, so the discrete reference is exactly stress free.
"""

import numpy as np
from numba import njit

from ..kernels import KERNEL

# A triangle is thin against the thickness h when its height (twice its area
# over its longest edge) is below THIN_HEIGHT * h: it carries the strain-gradient
# term (strain_gradient.dkt_active_elements) and the regge metric takes the
# conforming field's own metric there (kernels/assembly._element_regge).
THIN_HEIGHT = 0.5


# Symmetric quadrature rules on the triangle: barycentric points, weights
# (summing to 1).  Dunavant (1985).
def _sym_rule(entries):
    pts, wts = [], []
    for kind, a, w in entries:
        if kind == 1:
            pts.append((1 / 3, 1 / 3, 1 / 3))
            wts.append(w)
        elif kind == 3:
            b = 1.0 - 2.0 * a
            for p in [(a, a, b), (a, b, a), (b, a, a)]:
                pts.append(p)
                wts.append(w)
    return np.array(pts), np.array(wts)


RULES = {
    1: _sym_rule([(1, 0, 1.0)]),
    3: _sym_rule([(3, 1 / 6, 1 / 3)]),
    6: _sym_rule([(3, 0.445948490915965, 0.223381589678011),
                  (3, 0.091576213509771, 0.109951743655322)]),
    7: _sym_rule([(1, 0, 0.225),
                  (3, 0.470142064105115, 0.132394152788506),
                  (3, 0.101286507323456, 0.125939180544827)]),
}


def rule(npoints):
    """(barycentric points (nq, 3), weights (nq,)) of a symmetric rule."""
    try:
        return RULES[npoints]
    except KeyError:
        raise ValueError(f"no {npoints!r}-point triangle rule; choose one of {sorted(RULES)}") from None


@njit(**KERNEL)
def gather_element(e, tri, X, T, U, Xe, Te, bref, bcur):
    """Element e's reference vertices Xe (3, 3) and nodal tangent frames Te
    (3, 3, 2), and its nodal blocks (9, 3): bref = (X, T_1, T_2) of the
    reference, bcur = (r, a_1, a_2) of the state U, node by node."""
    for i in range(3):
        nd = tri[e, i]
        for c in range(3):
            Xe[i, c] = X[nd, c]
            Te[i, c, 0] = T[nd, c, 0]
            Te[i, c, 1] = T[nd, c, 1]
            bref[3 * i, c] = X[nd, c]
            bref[3 * i + 1, c] = T[nd, c, 0]
            bref[3 * i + 2, c] = T[nd, c, 1]
            for s in range(3):
                bcur[3 * i + s, c] = U[nd, s, c]


@njit(**KERNEL)
def element_chart(Xe, Te, Q, gl, et, el):
    """Facet chart of a triangle.

    Xe (3, 3): vertex positions; Te (3, 3, 2): nodal frames.
    Out: Q (3, 2, 2) with Q[i, a, b] = T_ia . E_b; gl (3, 2) barycentric
    gradients; et (3, 2) unit tangents and el (3,) lengths of the edges
    k = (k+1 -> k+2).  Returns the facet area.
    """
    e1x, e1y, e1z = Xe[1, 0] - Xe[0, 0], Xe[1, 1] - Xe[0, 1], Xe[1, 2] - Xe[0, 2]
    e2x, e2y, e2z = Xe[2, 0] - Xe[0, 0], Xe[2, 1] - Xe[0, 1], Xe[2, 2] - Xe[0, 2]
    l1 = np.sqrt(e1x * e1x + e1y * e1y + e1z * e1z)
    E1x, E1y, E1z = e1x / l1, e1y / l1, e1z / l1
    nx = e1y * e2z - e1z * e2y
    ny = e1z * e2x - e1x * e2z
    nz = e1x * e2y - e1y * e2x
    a2 = np.sqrt(nx * nx + ny * ny + nz * nz)
    nx, ny, nz = nx / a2, ny / a2, nz / a2
    E2x = ny * E1z - nz * E1y
    E2y = nz * E1x - nx * E1z
    E2z = nx * E1y - ny * E1x
    px1, py1 = l1, 0.0
    px2 = e2x * E1x + e2y * E1y + e2z * E1z
    py2 = e2x * E2x + e2y * E2y + e2z * E2z
    # barycentric gradients from J = [p1 - p0, p2 - p0] (columns), det = 2 area
    det = px1 * py2 - px2 * py1
    gl[1, 0] = py2 / det
    gl[1, 1] = -px2 / det
    gl[2, 0] = -py1 / det
    gl[2, 1] = px1 / det
    gl[0, 0] = -gl[1, 0] - gl[2, 0]
    gl[0, 1] = -gl[1, 1] - gl[2, 1]
    for i in range(3):
        for a in range(2):
            Q[i, a, 0] = Te[i, 0, a] * E1x + Te[i, 1, a] * E1y + Te[i, 2, a] * E1z
            Q[i, a, 1] = Te[i, 0, a] * E2x + Te[i, 1, a] * E2y + Te[i, 2, a] * E2z
    px = (0.0, px1, px2)
    py = (0.0, py1, py2)
    for k in range(3):
        i = (k + 1) % 3
        j = (k + 2) % 3
        dx = px[j] - px[i]
        dy = py[j] - py[i]
        ll = np.sqrt(dx * dx + dy * dy)
        el[k] = ll
        et[k, 0] = dx / ll
        et[k, 1] = dy / ll
    return 0.5 * det


@njit(**KERNEL)
def point_map(lam, Q, gl, et, el, b, C):
    """b (5, 9): v = (r_1, r_2, r_11, r_12, r_22) = b @ (nodal 3-vectors), the
    nodal blocks ordered (r_0, a_01, a_02, r_1, a_11, a_12, r_2, a_21, a_22).
    lam: barycentric coordinates of the point; C (2, 9) work."""
    for a in range(5):
        for k in range(9):
            b[a, k] = 0.0
    # linear interpolation of the positions minus the mean of Theta
    for i in range(3):
        b[0, 3 * i] = gl[i, 0]
        b[1, 3 * i] = gl[i, 1]
    for node in range(6):
        for a in range(2):
            for k in range(9):
                C[a, k] = 0.0
        if node < 3:
            i = node
            N = lam[i] * (2.0 * lam[i] - 1.0)
            dN0 = (4.0 * lam[i] - 1.0) * gl[i, 0]
            dN1 = (4.0 * lam[i] - 1.0) * gl[i, 1]
            for a in range(2):
                for bb in range(2):
                    C[a, 3 * i + 1 + bb] = Q[i, bb, a]
        else:
            k = node - 3
            i = (k + 1) % 3
            j = (k + 2) % 3
            N = 4.0 * lam[i] * lam[j]
            dN0 = 4.0 * (lam[j] * gl[i, 0] + lam[i] * gl[j, 0])
            dN1 = 4.0 * (lam[j] * gl[i, 1] + lam[i] * gl[j, 1])
            t0, t1 = et[k, 0], et[k, 1]
            f = 1.5 / el[k]
            M00 = 1.0 - 1.5 * t0 * t0
            M01 = -1.5 * t0 * t1
            M11 = 1.0 - 1.5 * t1 * t1
            for a in range(2):
                ta = t0 if a == 0 else t1
                C[a, 3 * j] += f * ta
                C[a, 3 * i] -= f * ta
                Ma0 = M00 if a == 0 else M01
                Ma1 = M01 if a == 0 else M11
                for m in (i, j):
                    for bb in range(2):
                        C[a, 3 * m + 1 + bb] += 0.5 * (Q[m, bb, 0] * Ma0 + Q[m, bb, 1] * Ma1)
        Nmean = N - (1.0 / 3.0 if node >= 3 else 0.0)
        for k in range(9):
            b[0, k] += Nmean * C[0, k]
            b[1, k] += Nmean * C[1, k]
            b[2, k] += dN0 * C[0, k]
            b[3, k] += 0.5 * (dN1 * C[0, k] + dN0 * C[1, k])
            b[4, k] += dN1 * C[1, k]


@njit(**KERNEL)
def apply_map(b, blocks, out):
    """out (15) = (b (x) I3) blocks, blocks (9, 3) nodal 3-vectors."""
    for a in range(5):
        for c in range(3):
            s = 0.0
            for k in range(9):
                s += b[a, k] * blocks[k, c]
            out[3 * a + c] = s
