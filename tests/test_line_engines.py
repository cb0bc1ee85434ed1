"""One-dimensional engines: axisymmetric meridians and plane-strain sections
(same point kernel, levels and solver as the triangle engine).

Observed: the plane-strain strip rolls into the exact circle (eq:x0z0asy) with
max error 2.3e-3, 1.0e-4, 6.2e-6, 3.9e-7 for 5, 10, 20, 40 elements (fourth
order); uniform growth of a sphere and a ring is exact to 1e-13; the
axisymmetric growing cylinder equals the closed-form 1D solution of the same
energy to round-off, so its error against eq:r0ex is the model error (ratio
16 per halving of h).
"""

import sys
from pathlib import Path

import numpy as np
import pytest

from shellritz import CubicStretch, NeoHookean
from shellritz.discretize.axisym import AxisymmetricShell
from shellritz.discretize.planestrain import PlaneStrainShell

sys.path.insert(0, str(Path(__file__).parent))
from test_closed_forms import exact_cylinder_r0, shell_cylinder_r0  # noqa: E402

G0S, G1S, HS, DS = 1.2, 2.0, 0.02, 2.0


def strip_error(n, level="consistent"):
    ps = PlaneStrainShell.strip(n, np.pi / G1S, HS, NeoHookean(1.0, D=DS), level=level)
    ps.set_growth(G0=np.diag([G0S, 1, 1]), G1=np.diag([G1S, 0, 0]))
    ps.symmetry(0, "a").fix_coordinate(0, "b")
    r = ps.solve(steps=8, verbose=False)
    x0 = G0S / G1S * np.sin(G1S * ps.s)
    z0 = G0S / G1S * (np.cos(G1S * ps.s) - 1)
    return np.hypot(r.a - x0, r.b - z0).max()


def test_plane_strain_strip_rolls_into_the_exact_circle():
    err = [strip_error(n) for n in (5, 10, 20, 40)]
    assert err[-1] < 1e-6, err
    assert all(err[k] / err[k + 1] > 12 for k in range(3)), err


@pytest.mark.parametrize("level", ["bending", "consistent"])
def test_strip_levels_agree_on_the_stress_free_circle(level):
    assert strip_error(20, level) < 1e-5


def test_uniform_growth_of_sphere_and_ring_is_exact():
    law = NeoHookean(1.0, nu=0.3)
    sph = AxisymmetricShell.sphere(16, 1.0, 0.05, law).set_growth(G0=1.3 * np.eye(3))
    sph.fix_coordinate(0, "b")
    r = sph.solve(steps=2, verbose=False)
    np.testing.assert_allclose(r.a, 1.3 * np.sin(sph.s), atol=1e-13)
    np.testing.assert_allclose(r.b, 1.3 * (1 - np.cos(sph.s)), atol=1e-13)
    ring = PlaneStrainShell.ring(16, 1.0, 0.05, law).set_growth(G0=np.diag([1.3, 1.0, 1.3]))
    r = ring.solve(steps=2, verbose=False)
    np.testing.assert_allclose(np.hypot(r.a, r.b), 1.3, atol=1e-12)


def test_axisymmetric_cylinder_equals_the_1d_solution():
    gamma, q = 1.2, 0.3
    ez = np.array([0, 0, 1.0])
    errors = []
    for h in (0.2, 0.1, 0.05, 0.025):
        c = AxisymmetricShell.cylinder(2, 1.0, 0.1, h, CubicStretch(1.0))
        c.set_growth(G0=gamma * (np.eye(3) - np.outer(ez, ez)) + np.outer(ez, ez))
        c.face_tractions(q_plus=[q * h, 0, 0])
        c.symmetry(0, "b").symmetry(-1, "b")
        r = c.solve(verbose=False, rtol=1e-12)
        assert np.abs(r.a - shell_cylinder_r0(gamma, q * h, h)).max() < 1e-12
        errors.append(abs(r.a.mean() - exact_cylinder_r0(gamma, q * h, h)[2]))
    assert all(15 < errors[k] / errors[k + 1] < 17 for k in range(3)), errors


def test_line_engine_rejects_bad_input():
    law = NeoHookean(1.0, nu=0.3)
    with pytest.raises(ValueError, match="increasing"):
        AxisymmetricShell(np.array([0.0, 0.0]), lambda s: (s, s, s, s), 0.1, law)
    with pytest.raises(ValueError, match="does not close"):
        PlaneStrainShell(np.linspace(0, 1, 5), lambda s: (s, 0 * s, 1 + 0 * s, 0 * s), 0.1, law,
                         closed=True)
    sph = AxisymmetricShell.sphere(8, 1.0, 0.05, law)
    assert list(sph.poles) == [0, 8]
    with pytest.raises(ValueError, match="det G0"):
        sph.set_growth(G0=-np.eye(3))


def test_growth_given_as_nodal_arrays_equals_the_function():
    """Nodal arrays are interpolated by a cubic spline: for a smooth growth the
    result converges to that of the function (spline error O(ds^4))."""
    law = NeoHookean(1.0, nu=0.4)
    g1 = lambda s: 1 - 0.2 * np.sin(s) ** 2
    results = []
    for how in ("function", "array"):
        sph = AxisymmetricShell.sphere(32, 1.0, 0.1, law)
        sph.set_stretch_growth(g1 if how == "function" else g1(sph.s), 1.0)
        sph.fix_coordinate(0, "b")
        results.append(sph.solve(steps=2, verbose=False))
    assert np.abs(results[0].a - results[1].a).max() < 1e-6
    assert np.abs(results[0].a - np.sin(results[0].s)).max() > 1e-2     # it did deform
    with pytest.raises(ValueError, match="nodal values of shape"):
        sph.set_stretch_growth(np.ones(5), 1.0)
    with pytest.raises(ValueError, match="non-finite nodal values at nodes \\[3\\]"):
        sph.set_stretch_growth(np.where(np.arange(33) == 3, np.nan, 1.0), 1.0)


@pytest.mark.parametrize("face", [None, "inner", "outer", "middle"])
@pytest.mark.parametrize("engine", ["planestrain", "axisym"])
def test_assembled_gradient_and_hessian_match_finite_differences(engine, face):
    """Observed: gradient 1e-10, Hessian 7e-11 relative (central differences,
    step 1e-6, random state near the reference, growth with G1, poles), also
    with a follower pressure on a face."""
    law = NeoHookean(1.0, D=2.0)
    eng = (PlaneStrainShell.strip(6, np.pi / 2, 0.02, law) if engine == "planestrain"
           else AxisymmetricShell.sphere(6, 1.0, 0.1, law))
    eng.set_growth(G0=np.diag([1.2, 1.0, 1.1]), G1=np.diag([2.0, 0.5, 0.0]))
    eng.face_tractions(q_plus=[0.01, 0.0, 0.02])
    if face is not None:
        eng.pressure(0.03, face=face)
    eng.fix_coordinate(0, "b")
    eng._setup()
    eng.set_parameter(0.7)
    x = eng.free_state() + 0.01 * np.random.default_rng(0).standard_normal(len(eng.free))
    _, g, K = eng.evaluate(x, 2)
    K = K.toarray()
    K = K + np.tril(K, -1).T
    eps, I = 1e-6, np.eye(len(x))
    g_fd = np.array([(eng.evaluate(x + eps * e, 0)[0] - eng.evaluate(x - eps * e, 0)[0]) / (2 * eps) for e in I])
    K_fd = np.array([(eng.evaluate(x + eps * e, 1)[1] - eng.evaluate(x - eps * e, 1)[1]) / (2 * eps) for e in I])
    assert np.abs(g_fd - g).max() < 1e-8 * np.abs(g).max()
    assert np.abs(K_fd - K).max() < 1e-8 * np.abs(K).max()
