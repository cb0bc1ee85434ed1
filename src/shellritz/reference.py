"""Radially symmetric 3D solutions of growing thick tubes and spheres: the
references the shell engines are measured against (tests, benchmarks).

Compressible neo-Hookean (C, D); reference body A = 1 - h/2 <= R <= B = 1 + h/2
(middle surface radius 1, Z = R - 1); growth
G = gamma_n e_R (x) e_R + gamma_t(Z) (tangential directions), gamma_t = gamma0 +
gamma1 Z; a tube is in plane strain (no axial stretch or growth).  With
x = r(R) e_R and k = 1 (tube) or 2 (sphere) tangential directions:

    alpha_1 = r'/gamma_n,  alpha_2 = r/(R gamma_t),  J = alpha_1 alpha_2^k
    P_RR = gamma_t^k W_1,  P_tt = gamma_n gamma_t^(k-1) W_2
    dP_RR/dR + k (P_RR - P_tt)/R = 0

Faces: dead radial tractions per reference area, q_inner on R = A and
q_outer on R = B (positive outward: P_RR(A) = -q_inner, P_RR(B) = q_outer),
or a follower pressure p on the inner face (P_RR(A) = -p (r(A)/A)^k).
Shooting on r(A) with an 8th-order Runge-Kutta (relative tolerance 1e-13).
"""

import numpy as np
from scipy.integrate import solve_ivp
from scipy.optimize import brentq

__all__ = ["thick_shell_r0"]


def _alpha1(P, alpha2, k, gt, C, D):
    """Solve gamma_t^k W_1(alpha_1, alpha_2) = P for alpha_1 (W_1 increasing)."""
    a = 1.0
    for _ in range(100):
        J = a * alpha2 ** k
        W1 = C * (a - 1 / a) + D * (J - 1) * J / a
        dW1 = C * (1 + 1 / a ** 2) + D * alpha2 ** (2 * k)
        da = (gt ** k * W1 - P) / (gt ** k * dW1)
        a_new = a - da
        a = a_new if a_new > 0 else 0.5 * a
        if abs(da) < 1e-15 * a:
            return a
    raise RuntimeError(f"radial stretch did not converge (P = {P:g})")


def thick_shell_r0(kind, h, C, D, gamma_n, gamma0, gamma1=0.0, q_inner=0.0, q_outer=0.0, p=0.0):
    """Thickness average r0 = (1/h) int_A^B r dR of the exact 3D solution;
    kind is "tube" or "sphere"."""
    k = {"tube": 1, "sphere": 2}[kind]
    A, B = 1 - h / 2, 1 + h / 2

    def rhs(R, y):
        r, P, _ = y
        gt = gamma0 + gamma1 * (R - 1)
        a2 = r / (R * gt)
        a1 = _alpha1(P, a2, k, gt, C, D)
        J = a1 * a2 ** k
        W2 = C * (a2 - 1 / a2) + D * (J - 1) * J / a2
        Pt = gamma_n * gt ** (k - 1) * W2
        return [gamma_n * a1, -k * (P - Pt) / R, r]

    def shoot(rA, full=False):
        PA = -q_inner - p * (rA / A) ** k
        sol = solve_ivp(rhs, (A, B), [rA, PA, 0.0], method="DOP853", rtol=1e-13, atol=1e-15)
        return sol if full else sol.y[1, -1] - q_outer

    guess = gamma0 * A
    rA = brentq(shoot, 0.5 * guess, 2.0 * guess, xtol=1e-15, rtol=4 * np.finfo(float).eps)
    return shoot(rA, full=True).y[2, -1] / h
