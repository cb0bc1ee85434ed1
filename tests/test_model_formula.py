"""The kernel evaluates MODEL.md section 4 literally.

An independent, slow reference implementation of the section-4 formula is
written here in plain NumPy: global Cartesian tensors, y1 by its own Newton
solve, grad y1 by central differences of y1 along the surface, the
thickness derivatives Wbar_Z, Wbar_ZZ, P_Z by 5-point stencils, y2 from its
closed form.  The kernel (local frame, slots, exact algebra) must reproduce
L, y1 and y2 at random points.

Observed: y1 agrees to 4e-15, y2 to 7e-10, L to 9e-9 relative to the
bending part of the energy (the reference's finite differences limit these).
"""

import zlib

import numpy as np
import pytest

from pointdata import SURFACES, random_state
from shellritz.materials import CubicStretch, NeoHookean, StVenantKirchhoff
from shellritz.model import evaluate_point

H_THICK = 0.2


def _ref_frame(R1, R2):
    M = np.array([[R1 @ R1, R1 @ R2], [R1 @ R2, R2 @ R2]])
    gup = np.linalg.inv(M) @ np.array([R1, R2])
    n = np.cross(R1, R2)
    return gup, n / np.linalg.norm(n), M


def _wbar(law, F, G):
    Gi = np.linalg.inv(G)
    W, PA, AAA = law.evaluate(F @ Gi)
    g = np.linalg.det(G)
    P = g * PA @ Gi.T
    AA = g * np.einsum("iMkN,JM,LN->iJkL", AAA.reshape(3, 3, 3, 3), Gi, Gi)
    return g * W, P, AA


def _solve_y1(law, Ft, n, G, m, y):
    for _ in range(100):
        _, P, AA = _wbar(law, Ft + np.outer(y, n), G)
        res = P @ n - m
        B = np.einsum("iJkL,J,L->ik", AA, n, n)
        dy = -np.linalg.solve(B, res)
        y = y + dy
        if np.linalg.norm(dy) < 1e-15 * np.linalg.norm(y):
            break
    return y


def model_formula(law, v, ref, h, level, G0, G1, dG0, qbar, m, dm, y1_guess):
    def at(t):
        R1 = ref[0:3] + t[0] * ref[6:9] + t[1] * ref[9:12]
        R2 = ref[3:6] + t[0] * ref[9:12] + t[1] * ref[12:15]
        r1 = v[0:3] + t[0] * v[6:9] + t[1] * v[9:12]
        r2 = v[3:6] + t[0] * v[9:12] + t[1] * v[12:15]
        gup, n, M = _ref_frame(R1, R2)
        Ft = np.outer(r1, gup[0]) + np.outer(r2, gup[1])
        return Ft, n, gup, M, G0 + t[0] * dG0[0] + t[1] * dG0[1], m + t[0] * dm[0] + t[1] * dm[1]

    Ft, n, gup, M, G, mm = at((0.0, 0.0))
    y1 = _solve_y1(law, Ft, n, G, mm, y1_guess)
    eps = 1e-5
    dy1 = []
    for a in range(2):
        t = np.zeros(2)
        t[a] = eps
        yp = _solve_y1(law, *[at(t)[i] for i in (0, 1)], at(t)[4], at(t)[5], y1)
        ym = _solve_y1(law, *[at(-t)[i] for i in (0, 1)], at(-t)[4], at(-t)[5], y1)
        dy1.append((yp - ym) / (2 * eps))
    F0 = Ft + np.outer(y1, n)
    b = np.array([[n @ ref[6:9], n @ ref[9:12]], [n @ ref[9:12], n @ ref[12:15]]])
    kappa = np.einsum("ac,ai,cj->ij", b, gup, gup)
    H = 0.5 * np.trace(kappa)
    K = np.linalg.det(b) / np.linalg.det(M)
    rho = Ft @ kappa + np.outer(dy1[0], gup[0]) + np.outer(dy1[1], gup[1])
    Wb, P, AA = _wbar(law, F0, G)
    if level == "membrane":
        return h * Wb - h * mm @ y1, y1, np.zeros(3)
    ez = 1e-3

    def wz(z):
        return _wbar(law, F0, G + z * G1)

    s = [wz(k * ez) for k in (-2, -1, 0, 1, 2)]
    W_Z = (s[0][0] - 8 * s[1][0] + 8 * s[3][0] - s[4][0]) / (12 * ez)
    W_ZZ = (-s[0][0] + 16 * s[1][0] - 30 * s[2][0] + 16 * s[3][0] - s[4][0]) / (12 * ez ** 2)
    P_Z = (s[0][1] - 8 * s[1][1] + 8 * s[3][1] - s[4][1]) / (12 * ez)
    B = np.einsum("iJkL,J,L->ik", AA, n, n)
    w = np.einsum("iJkL,kL,J->i", AA, rho, n)
    rAr = np.einsum("iJ,iJkL,kL->", rho, AA, rho)
    if level == "bending":
        y2 = -np.linalg.solve(B, w + P_Z @ n)
        F1 = rho + np.outer(y2, n)
        phi2 = np.einsum("iJ,iJkL,kL->", F1, AA, F1) + 2 * np.sum(P_Z * F1) + W_ZZ
        return h * Wb - h * mm @ y1 + h ** 3 / 24 * phi2, y1, y2
    y2 = np.linalg.solve(B, 2 * H * P @ n - w - P_Z @ n + qbar)
    kstar = 2 * H * (np.eye(3) - np.outer(n, n)) - kappa
    L = (h * (1 + h * h * K / 12) * Wb
         + h ** 3 / 24 * (rAr - y2 @ B @ y2 - 2 * np.sum(P * (rho @ kstar))
                          + 2 * np.sum(P_Z * rho) - 4 * H * W_Z + W_ZZ)
         - h * mm @ y1)
    return L, y1, y2


LAWS = {"neo-hookean": lambda: NeoHookean(1.0, nu=0.3),
        "svk": lambda: StVenantKirchhoff(1.2, 0.8),
        "cubic-stretch": lambda: CubicStretch(1.0)}


@pytest.mark.parametrize("law_name", sorted(LAWS))
@pytest.mark.parametrize("level", ["membrane", "bending", "consistent"])
@pytest.mark.parametrize("surface", sorted(SURFACES))
def test_kernel_equals_model_formula(law_name, level, surface):
    law = LAWS[law_name]()
    rng = np.random.default_rng(zlib.crc32(f"{law_name}{level}{surface}".encode()))
    ref, v, kw = random_state(rng, surface, amp=0.05)
    r = evaluate_point(law, v, ref, H_THICK, level, **kw)
    L, y1, y2 = model_formula(law, v, ref, H_THICK, level, kw["G0"], kw["G1"], kw["dG0"],
                              kw["qbar"], kw["m"], kw["dm"], r.y1)
    np.testing.assert_allclose(r.y1, y1, atol=1e-12)
    if level == "membrane":
        assert r.L == pytest.approx(L, rel=1e-12)
        return
    np.testing.assert_allclose(r.y2, y2, atol=1e-7 * max(1.0, np.abs(y2).max()))
    membrane = evaluate_point(law, v, ref, H_THICK, "membrane", **kw).L
    bending_part = abs(L - membrane)
    assert abs(r.L - L) <= 1e-8 * bending_part + 1e-15
