"""Point kernel (MODEL.md section 4): exact derivatives, conventions, invariance.

Observed: gradients agree with central differences (step 1e-6) to 6e-9 and
Hessians to 4e-10 relative (the finite-difference error) for every law x
level x surface, with and without a through-thickness growth gradient G1, in
skew coordinates; the Hessian is symmetric to 3e-16 relative.
"""

import zlib

import numpy as np
import pytest

from pointdata import (SURFACES, cylinder, random_rotation, random_state,
                       reparametrize, reparametrize_field, rotate, sphere)
from shellritz.materials import (CubicStretch, LinearIsotropic, NeoHookean,
                                 StVenantKirchhoff)
from shellritz.model import (ShellError, evaluate_point, reference_geometry,
                             thickness_jacobian)

LAWS = {
    "neo-hookean": lambda: NeoHookean(1.0, nu=0.3),
    "svk": lambda: StVenantKirchhoff(1.2, 0.8),
    "cubic-stretch": lambda: CubicStretch(1.0),
    "linear": lambda: LinearIsotropic(1.0, 0.5),
}
LEVELS = ["membrane", "bending", "consistent"]
H_THICK = 0.2


def fd_derivatives(law, v, ref, level, kw, eps=1e-6):
    g = np.zeros(15)
    hs = np.zeros((15, 15))
    for i in range(15):
        e = np.zeros(15)
        e[i] = eps
        rp = evaluate_point(law, v + e, ref, H_THICK, level, **kw)
        rm = evaluate_point(law, v - e, ref, H_THICK, level, **kw)
        g[i] = (rp.L - rm.L) / (2 * eps)
        hs[:, i] = (rp.grad - rm.grad) / (2 * eps)
    return g, hs


@pytest.mark.parametrize("law_name", sorted(LAWS))
@pytest.mark.parametrize("level", LEVELS)
@pytest.mark.parametrize("surface", sorted(SURFACES))
@pytest.mark.parametrize("with_g1", [False, True])
def test_gradient_and_hessian_against_finite_differences(law_name, level, surface, with_g1):
    law = LAWS[law_name]()
    rng = np.random.default_rng(zlib.crc32(f"{law_name}{level}{surface}{with_g1}".encode()))
    ref, v, kw = random_state(rng, surface, with_g1=with_g1)
    r = evaluate_point(law, v, ref, H_THICK, level, **kw)
    g, hs = fd_derivatives(law, v, ref, level, kw)
    gscale = np.abs(r.grad).max()
    hscale = np.abs(r.hess).max()
    assert np.abs(g - r.grad).max() <= 1e-7 * gscale
    assert np.abs(hs - r.hess).max() <= 1e-7 * hscale
    assert np.abs(r.hess - r.hess.T).max() <= 1e-13 * hscale


def test_sign_conventions_sphere_and_cylinder():
    for rad in [1.0, 2.5]:
        H, K, n = reference_geometry(reparametrize(sphere(rad)))
        assert H == pytest.approx(-1 / rad) and K == pytest.approx(1 / rad ** 2)
        R = sphere(rad)
        # outward normal: parallel to the position (R_11 = -R for theta curves... )
        pos = rad * np.array([np.sin(0.9) * np.cos(0.3), np.sin(0.9) * np.sin(0.3), np.cos(0.9)])
        np.testing.assert_allclose(n, pos / rad, atol=1e-14)
        assert thickness_jacobian(H, K, 0.1) == pytest.approx((1 + 0.1 / rad) ** 2)
        H, K, n = reference_geometry(reparametrize(cylinder(rad)))
        assert H == pytest.approx(-0.5 / rad) and K == pytest.approx(0, abs=1e-14)
        np.testing.assert_allclose(n, [np.cos(0.4), np.sin(0.4), 0], atol=1e-14)
        assert thickness_jacobian(H, K, 0.1) == pytest.approx(1 + 0.1 / rad)
    assert R is not None


@pytest.mark.parametrize("law_name", ["neo-hookean", "svk", "cubic-stretch"])
@pytest.mark.parametrize("level", LEVELS)
def test_frame_indifference(law_name, level):
    law = LAWS[law_name]()
    rng = np.random.default_rng(7)
    ref, v, kw = random_state(rng, "sphere")
    Q = random_rotation(rng)
    kwq = dict(kw)
    # dead loads rotate with the state for the energy to be invariant
    for key in ("qbar", "m"):
        kwq[key] = Q @ kw[key]
    kwq["dm"] = kw["dm"] @ Q.T
    r = evaluate_point(law, v, ref, H_THICK, level, **kw)
    rq = evaluate_point(law, rotate(v, Q), ref, H_THICK, level, **kwq)
    assert rq.L == pytest.approx(r.L, rel=1e-12, abs=1e-15)
    np.testing.assert_allclose(rq.grad, rotate(r.grad, Q), atol=1e-12 * np.abs(r.grad).max())
    np.testing.assert_allclose(rq.y1, Q @ r.y1, atol=1e-13)
    np.testing.assert_allclose(rq.y2, Q @ r.y2, atol=1e-12)


@pytest.mark.parametrize("law_name", sorted(LAWS))
@pytest.mark.parametrize("level", LEVELS)
@pytest.mark.parametrize("surface", sorted(SURFACES))
def test_reference_state_is_stress_free(law_name, level, surface):
    law = LAWS[law_name]()
    ref = reparametrize(SURFACES[surface]())
    r = evaluate_point(law, ref, ref, H_THICK, level)
    assert abs(r.L) <= 1e-15
    assert np.abs(r.grad).max() <= 1e-14
    H, K, n = reference_geometry(ref)
    np.testing.assert_allclose(r.y1, n, atol=1e-14)
    np.testing.assert_allclose(r.y2, 0, atol=1e-13)


@pytest.mark.parametrize("level", LEVELS)
@pytest.mark.parametrize("surface", ["cylinder", "sphere"])
def test_uniform_isotropic_growth_scales_stress_free(level, surface):
    """r = gamma R with G = gamma I is an exact stress-free state."""
    law = NeoHookean(1.0, nu=0.4)
    gam = 1.37
    ref = reparametrize(SURFACES[surface]())
    r = evaluate_point(law, gam * ref, ref, H_THICK, level, G0=gam * np.eye(3))
    assert abs(r.L) <= 1e-14
    assert np.abs(r.grad).max() <= 1e-13
    H, K, n = reference_geometry(ref)
    np.testing.assert_allclose(r.y1, gam * n, atol=1e-13)


def test_rigid_rotation_of_curved_reference_costs_nothing():
    law = NeoHookean(1.0, nu=0.3)
    rng = np.random.default_rng(11)
    ref = reparametrize(sphere(1.4))
    Q = random_rotation(rng)
    for level in LEVELS:
        r = evaluate_point(law, rotate(ref, Q), ref, H_THICK, level)
        assert abs(r.L) <= 1e-14 and np.abs(r.grad).max() <= 1e-13


def test_growth_derivatives_are_coordinate_covariant():
    """Energy is independent of the coordinates used for the same geometry."""
    law = NeoHookean(1.0, nu=0.3)
    rng = np.random.default_rng(5)
    base = sphere()
    v = base + 0.05 * rng.standard_normal(15)
    dG0 = 0.2 * rng.standard_normal((2, 3, 3))
    dm = 0.05 * rng.standard_normal((2, 3))
    kw = dict(G0=np.eye(3) + 0.1 * rng.standard_normal((3, 3)), G1=0.2 * rng.standard_normal((3, 3)),
              qbar=0.1 * rng.standard_normal(3), m=0.05 * rng.standard_normal(3))
    r1 = evaluate_point(law, v, base, H_THICK, "consistent", dG0=dG0, dm=dm, **kw)
    r2 = evaluate_point(law, reparametrize(v), reparametrize(base), H_THICK, "consistent",
                        dG0=reparametrize_field(dG0), dm=reparametrize_field(dm), **kw)
    assert r2.L == pytest.approx(r1.L, rel=1e-12)
    np.testing.assert_allclose(r2.y2, r1.y2, rtol=1e-11, atol=1e-13)


def test_errors_are_reported_not_nan():
    law = NeoHookean(1.0, nu=0.3)
    ref = reparametrize(sphere())
    with pytest.raises(ShellError, match="degenerate reference"):
        evaluate_point(law, ref, np.zeros(15), H_THICK)
    with pytest.raises(ShellError, match="degenerate current"):
        evaluate_point(law, np.zeros(15), ref, H_THICK)
    with pytest.raises(ShellError, match="det G0"):
        evaluate_point(law, ref, ref, H_THICK, G0=np.diag([1.0, 1.0, -1.0]))
    # mirrored tangent plane with the director continued from the reference
    # side (warm start) is an inverted material element (without history the
    # director would simply flip: a half-turn of the membrane state)
    flipped = ref.copy()
    flipped[3:6] *= -1
    n = reference_geometry(ref)[2]
    with pytest.raises(ShellError, match="inverted"):
        evaluate_point(law, flipped, ref, H_THICK, y1=n)
    with pytest.raises(ValueError, match="non-finite"):
        evaluate_point(law, np.full(15, np.nan), ref, H_THICK)
    with pytest.raises(ValueError, match="thickness"):
        evaluate_point(law, ref, ref, -1.0)
    with pytest.raises(ValueError, match="level"):
        evaluate_point(law, ref, ref, H_THICK, level="shell")


def test_small_spd_helpers_solve_like_numpy():
    """chol3 / chol3_inverse / mv3 (every solve with the acoustic tensor after
    the y1 Newton) against numpy, on well- and badly-conditioned SPD matrices."""
    from shellritz.kernels.small import chol3, chol3_inverse, chol3_solve, mv3
    rng = np.random.default_rng(3)
    for cond in (1.0, 1e3, 1e8):
        Q, _ = np.linalg.qr(rng.standard_normal((3, 3)))
        B = Q @ np.diag([1.0, np.sqrt(cond), cond]) @ Q.T
        lo, inv = np.zeros((3, 3)), np.zeros((3, 3))
        assert chol3(B, lo)
        chol3_inverse(lo, inv)
        ref = np.linalg.inv(B)
        assert np.abs(inv - ref).max() <= 1e-13 * cond * np.abs(ref).max()
        assert np.array_equal(inv, inv.T)
        x, y = rng.standard_normal(3), np.zeros(3)
        mv3(inv, x, y)
        z = np.zeros(3)
        chol3_solve(lo, x, z)
        assert np.allclose(y, np.linalg.solve(B, x), rtol=1e-13 * cond, atol=0)
        assert np.allclose(y, z, rtol=1e-13 * cond, atol=0)
        mv3(inv, x, x)                    # aliasing in/out
        assert np.array_equal(x, y)
    assert not chol3(-np.eye(3), lo)


@pytest.mark.parametrize("level", LEVELS)
@pytest.mark.parametrize("surface", sorted(SURFACES))
@pytest.mark.parametrize("face", [-0.5, 0.5])
def test_face_pressure_derivatives_against_finite_differences(level, surface, face):
    """Follower pressure p on the face Z = face h (docs/pressure.md): its loads
    m_p, qbar_p, dm_p follow the current normal, so they are differentiated
    through y1, Y_a, y2 too (observed: as the test above)."""
    law = LAWS["neo-hookean"]()
    rng = np.random.default_rng(zlib.crc32(f"pressure{level}{surface}{face}".encode()))
    ref, v, kw = random_state(rng, surface)
    kw["face_pressure"] = (0.3 * H_THICK, face * H_THICK)
    r = evaluate_point(law, v, ref, H_THICK, level, **kw)
    g, hs = fd_derivatives(law, v, ref, level, kw)
    assert np.abs(g - r.grad).max() <= 1e-7 * np.abs(r.grad).max()
    assert np.abs(hs - r.hess).max() <= 1e-7 * np.abs(r.hess).max()
    assert np.abs(r.hess - r.hess.T).max() <= 1e-13 * np.abs(r.hess).max()


def test_face_pressure_at_fixed_geometry_is_the_equivalent_face_traction():
    """At a given state the face pressure acts as the dead tractions it exerts
    there: q- = p n_c on Z = -h/2 gives the same directors y1, y2 and, at the
    bending level (no face-area term), the same energy."""
    law = LAWS["neo-hookean"]()
    rng = np.random.default_rng(3)
    ref, v, kw = random_state(rng, "sphere", with_loads=False)
    p = 0.3 * H_THICK
    nc = np.cross(v[0:3], v[3:6]) / np.linalg.norm(np.cross(ref[0:3], ref[3:6]))
    # d(n_c)/dtheta^a with j_a / j = g^b . R_ba
    j = np.linalg.norm(np.cross(ref[0:3], ref[3:6]))
    M = np.array([[ref[0:3] @ ref[0:3], ref[0:3] @ ref[3:6]], [ref[0:3] @ ref[3:6], ref[3:6] @ ref[3:6]]])
    gup = np.linalg.solve(M, np.array([ref[0:3], ref[3:6]]))
    Rab = {(0, 0): ref[6:9], (0, 1): ref[9:12], (1, 0): ref[9:12], (1, 1): ref[12:15]}
    rab = {(0, 0): v[6:9], (0, 1): v[9:12], (1, 0): v[9:12], (1, 1): v[12:15]}
    dnc = np.array([(np.cross(rab[0, a], v[3:6]) + np.cross(v[0:3], rab[1, a])) / j
                    - nc * (gup[0] @ Rab[0, a] + gup[1] @ Rab[1, a]) for a in range(2)])
    dead = dict(kw, qbar=p * nc / H_THICK, m=-p * nc / 2, dm=-p * dnc / 2)
    follower = dict(kw, face_pressure=(p, -0.5 * H_THICK))
    for level in ("membrane", "bending", "consistent"):
        a = evaluate_point(law, v, ref, H_THICK, level, mode="energy", **dead)
        b = evaluate_point(law, v, ref, H_THICK, level, mode="energy", **follower)
        np.testing.assert_allclose(a.y1, b.y1, rtol=1e-13)
        np.testing.assert_allclose(a.y2, b.y2, rtol=1e-12, atol=1e-14)
        if level != "consistent":
            assert a.L == pytest.approx(b.L, rel=1e-13)


def test_fma_rounds_once_where_the_cpu_fuses():
    """kernels.small.fma is a * b + c in one rounding on CPUs with FMA, and
    a product then a sum elsewhere: with x = 1 + 2^-30, x * x = 1 + 2^-29 +
    2^-60 rounds to 1 + 2^-29, so fma(x, x, -(x * x)) is the lost 2^-60
    where fused and 0 where not."""
    from numba import njit

    from shellritz.kernels.small import FUSED, fma

    @njit
    def residual(x):
        return fma(x, x, -(x * x))

    assert residual(1.0 + 2.0 ** -30) == (2.0 ** -60 if FUSED else 0.0)
