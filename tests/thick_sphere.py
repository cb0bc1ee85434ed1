"""Radially symmetric 3D reference for a growing thick spherical shell.

Compressible neo-Hookean (C, D); reference shell A = 1 - h/2 <= R <= B = 1 + h/2
(middle surface radius 1); growth G = gamma_n e_R (x) e_R + gamma_t(Z) (I - e_R (x) e_R),
gamma_t(Z) = gamma0 + gamma1 Z, Z = R - 1.  Deformation x = r(R) e_R:

    alpha_1 = r'/gamma_n,  alpha_2 = r/(R gamma_t),  J = alpha_1 alpha_2^2
    P_RR = gamma_t^2 W_1,  P_tt = gamma_n gamma_t W_2
    dP_RR/dR + 2 (P_RR - P_tt)/R = 0,   P_RR(B) = 0,

loaded on the inner face either by a dead radial traction q per reference
area (P_RR(A) = -q) or by a follower pressure p (P_RR(A) = -p (r(A)/A)^2).
Shooting on r(A) with an 8th-order Runge-Kutta (relative tolerance 1e-13);
returns the thickness average r0 = (1/h) int r dR (MODEL.md: uniform weight).
"""

import numpy as np
from scipy.integrate import solve_ivp
from scipy.optimize import brentq


def _alpha1(P, alpha2, gt, C, D):
    """Solve gamma_t^2 W_1(alpha_1, alpha_2) = P for alpha_1 (W_1 increasing)."""
    a = 1.0
    for _ in range(100):
        J = a * alpha2 ** 2
        W1 = C * (a - 1 / a) + D * (J - 1) * J / a
        dW1 = C * (1 + 1 / a ** 2) + D * alpha2 ** 4
        da = (gt * gt * W1 - P) / (gt * gt * dW1)
        a_new = a - da
        a = a_new if a_new > 0 else 0.5 * a
        if abs(da) < 1e-15 * a:
            break
    return a


def thick_sphere_r0(h, C, D, gamma_n, gamma0, gamma1, q=0.0, p=0.0):
    A, B = 1 - h / 2, 1 + h / 2

    def rhs(R, y):
        r, P, _ = y
        gt = gamma0 + gamma1 * (R - 1)
        a2 = r / (R * gt)
        a1 = _alpha1(P, a2, gt, C, D)
        J = a1 * a2 * a2
        W2 = C * (a2 - 1 / a2) + D * (J - 1) * J / a2
        Pt = gamma_n * gt * W2
        return [gamma_n * a1, -2 * (P - Pt) / R, r]

    def shoot(rA, full=False):
        PA = -q - p * (rA / A) ** 2
        sol = solve_ivp(rhs, (A, B), [rA, PA, 0.0], method="DOP853", rtol=1e-13, atol=1e-15)
        return sol if full else sol.y[1, -1]

    guess = gamma0 * A
    lo, hi = 0.5 * guess, 2.0 * guess
    rA = brentq(shoot, lo, hi, xtol=1e-15, rtol=4 * np.finfo(float).eps)
    sol = shoot(rA, full=True)
    return sol.y[2, -1] / h
