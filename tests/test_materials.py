"""Material laws: derivatives of W up to order 4 against finite differences,
parameter validation, user-defined laws.

Observed (central differences, step 3e-6, relative to the largest entry):
P, AA, D3 and D4 agree to 2e-9 or better for every law (the differences
shrink as step^2: truncation error; with step 1e-5 the power-law solid's D4
at a state with det A = 1.5 was off by 2e-8).
"""

import math


import numpy as np
import pytest

from shellritz.materials import (CubicStretch, InvariantLaw, LinearIsotropic,
                                 NeoHookean, PowerLawHardening, StVenantKirchhoff,
                                 _acosh2_derivatives, invariant_law_from_sympy)

LAWS = {
    "neo-hookean": lambda: NeoHookean(1.3, nu=0.35),
    "svk": lambda: StVenantKirchhoff(1.2, 0.8),
    "cubic-stretch": lambda: CubicStretch(1.0),
    "linear": lambda: LinearIsotropic(1.0, 0.5),
    "power-law": lambda: PowerLawHardening(1.0, 0.2, 0.05, nu=0.3),
}


def _fd(f, x, d, eps=3e-6):
    return (f(x + eps * d) - f(x - eps * d)) / (2 * eps)


@pytest.mark.parametrize("name", sorted(LAWS))
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_derivatives_against_finite_differences(name, seed):
    law = LAWS[name]()
    rng = np.random.default_rng(seed)
    A = np.eye(3) + 0.25 * rng.standard_normal((3, 3))
    assert np.linalg.det(A) > 0
    c, d, e = (rng.standard_normal((3, 3)) for _ in range(3))
    W, P, AA, D3, D4 = law.evaluate(A, 4, c, d)
    dW = _fd(lambda X: law.evaluate(X)[0], A, e)
    assert dW == pytest.approx(np.sum(P * e), rel=1e-8, abs=1e-12)
    dP = _fd(lambda X: law.evaluate(X)[1].ravel(), A, e)
    assert np.abs(dP - AA @ e.ravel()).max() <= 1e-8 * np.abs(AA).max()
    assert np.abs(AA - AA.T).max() <= 1e-13 * np.abs(AA).max()
    dAA = _fd(lambda X: law.evaluate(X)[2], A, c)
    tol3 = 1e-8 * max(np.abs(D3).max(), np.abs(AA).max())
    assert np.abs(dAA - D3).max() <= tol3
    dD3 = _fd(lambda X: law.evaluate(X, 3, c)[3], A, d)
    tol4 = 1e-8 * max(np.abs(D4).max(), np.abs(AA).max())
    assert np.abs(dD3 - D4).max() <= tol4
    if name == "linear":
        assert np.all(D3 == 0) and np.all(D4 == 0)
    else:
        assert np.abs(D4).max() > 0


@pytest.mark.parametrize("name", sorted(LAWS))
def test_reference_state_is_stress_free_and_small_strain_moduli(name):
    law = LAWS[name]()
    W, P, AA = law.evaluate(np.eye(3))
    assert W == pytest.approx(0, abs=1e-14)
    assert np.abs(P).max() <= 1e-13
    # all laws share the linear isotropic response at A = I
    lam = AA[0, 4]
    mu = AA[1, 1]
    assert AA[0, 0] == pytest.approx(lam + 2 * mu)
    assert AA[1, 3] == pytest.approx(mu)


def test_neo_hookean_from_poisson_ratio_and_small_strain():
    law = NeoHookean(2.0, nu=0.3)
    assert law.D == pytest.approx(2 * 2.0 * 0.3 / 0.4)
    assert law.nu == pytest.approx(0.3)
    AA = law.evaluate(np.eye(3))[2]
    # Lame constants of the linearization: mu = C, lambda = D
    assert AA[1, 1] == pytest.approx(2.0)
    assert AA[0, 4] == pytest.approx(law.D)


def test_cubic_stretch_matches_principal_stretch_formula():
    law = CubicStretch(1.7)
    rng = np.random.default_rng(3)
    for _ in range(5):
        A = np.eye(3) + 0.3 * rng.standard_normal((3, 3))
        if np.linalg.det(A) <= 0:
            continue
        a = np.sqrt(np.linalg.eigvalsh(A.T @ A))
        expected = 1.7 * (2 / 27 * a.sum() ** 3 - (a[0] * a[1] + a[0] * a[2] + a[1] * a[2]) + 1)
        assert law.evaluate(A)[0] == pytest.approx(expected, rel=1e-12)


@pytest.mark.parametrize("bad", [
    lambda: NeoHookean(1.0, nu=0.5),
    lambda: NeoHookean(1.0, nu=-1.0),
    lambda: NeoHookean(-1.0, nu=0.3),
    lambda: NeoHookean(1.0, nu=float("nan")),
    lambda: NeoHookean(1.0),
    lambda: NeoHookean(1.0, nu=0.3, D=1.0),
    lambda: StVenantKirchhoff(1.0, 0.0),
    lambda: StVenantKirchhoff(-2.0, 1.0),
    lambda: LinearIsotropic.from_young(1.0, 0.5),
    lambda: CubicStretch(0.0),
    lambda: CubicStretch(float("inf")),
    lambda: PowerLawHardening(1.0, 0.2, 0.05),
    lambda: PowerLawHardening(1.0, 0.2, 0.05, nu=0.3, K=1.0),
    lambda: PowerLawHardening(0.0, 0.2, 0.05, nu=0.3),
    lambda: PowerLawHardening(1.0, 0.0, 0.05, nu=0.3),
    lambda: PowerLawHardening(1.0, 1.5, 0.05, nu=0.3),
    lambda: PowerLawHardening(1.0, 0.2, 0.0, nu=0.3),
    lambda: PowerLawHardening(1.0, 0.2, 0.05, nu=0.5),
    lambda: PowerLawHardening(1.0, 0.2, 0.05, K=-1.0),
    lambda: PowerLawHardening(1.0, float("nan"), 0.05, nu=0.3),
])
def test_invalid_parameters_raise(bad):
    with pytest.raises(ValueError):
        bad()


def _power_law_energy(law, A):
    """PowerLawHardening's W from its definition, in NumPy (eigenvalue-free
    like the law, but independent code)."""
    J = np.linalg.det(A)
    s = np.trace(A.T @ A) * J ** (-2 / 3) - 3
    e2 = np.arccosh(1 + s / 2) ** 2 / 3
    m = (1 + law.n) / 2
    g = 3 * law.mu * law.eps0 ** 2 / (1 + law.n) * ((1 + e2 / law.eps0 ** 2) ** m - 1)
    return g + law.K / 2 * np.log(J) ** 2


def test_power_law_energy_and_logarithmic_strain():
    law = PowerLawHardening(1.3, 0.15, 0.02, nu=0.3)
    rng = np.random.default_rng(6)
    for _ in range(5):
        A = np.eye(3) + 0.3 * rng.standard_normal((3, 3))
        if np.linalg.det(A) > 0:
            assert law.evaluate(A)[0] == pytest.approx(_power_law_energy(law, A), rel=1e-12)
    # isochoric plane strain: eps_e is the von Mises logarithmic strain (2/sqrt3)|ln lam|
    for lam in (1.001, 1.2, 1.8, 3.0):
        e = 2 / math.sqrt(3) * math.log(lam)
        g = 3 * 1.3 * 0.02 ** 2 / 1.15 * ((1 + e * e / 0.02 ** 2) ** 0.575 - 1)
        assert law.evaluate(np.diag([lam, 1.0, 1.0 / lam]))[0] == pytest.approx(g, rel=1e-12)
    # small strain: shear modulus mu, bulk modulus K = 2 mu (1 + nu) / (3 (1 - 2 nu))
    AA = law.evaluate(np.eye(3))[2]
    assert AA[1, 1] == pytest.approx(1.3) and AA[1, 3] == pytest.approx(1.3)
    assert AA[0, 4] + 2 / 3 * AA[1, 1] == pytest.approx(2 * 1.3 * 1.3 / (3 * 0.4))
    assert law.nu == pytest.approx(0.3)


def test_acosh_squared_derivatives_series_and_closed_form():
    """F = acosh(y)^2 to order 4: the series branch (y < 1.5) and the closed
    form branch agree at the switch, and both match finite differences."""
    lo, hi = np.zeros(5), np.zeros(5)
    _acosh2_derivatives(1.5 - 1e-12, lo)
    _acosh2_derivatives(1.5 + 1e-12, hi)
    np.testing.assert_allclose(lo, hi, rtol=1e-10)
    for y in (1.0 + 1e-9, 1.2, 1.7, 4.0):
        d = np.zeros(5)
        _acosh2_derivatives(y, d)
        assert d[0] == pytest.approx(math.acosh(y) ** 2, rel=1e-13, abs=1e-15)
        for k in range(1, 5):
            dp, dm = np.zeros(5), np.zeros(5)
            eps = 1e-5
            _acosh2_derivatives(y + eps, dp)
            _acosh2_derivatives(y - eps, dm)      # y < 1: the analytic continuation
            fd = (dp[k - 1] - dm[k - 1]) / (2 * eps)
            assert fd == pytest.approx(d[k], rel=1e-6, abs=1e-8)
    d = np.zeros(5)
    _acosh2_derivatives(1.0, d)       # Taylor coefficients 2, -1/3, 4/45, -4/105 at y = 1
    np.testing.assert_allclose(d, [0, 2, -2 / 3, 8 / 15, -24 / 35], rtol=1e-14, atol=1e-16)


def test_inverted_state_raises():
    with pytest.raises(ValueError, match="inverted"):
        NeoHookean(1.0, nu=0.3).evaluate(np.diag([1.0, 1.0, -1.0]))


def test_user_law_from_sympy_reproduces_neo_hookean():
    sp = pytest.importorskip("sympy")
    I1, I2, J, C, D = sp.symbols("I1 I2 J C D", positive=True)
    expr = C / 2 * (I1 - 3 - 2 * sp.log(J)) + D / 2 * (J - 1) ** 2
    user = invariant_law_from_sympy(expr, I1, I2, J, params=(C, D), values=(1.3, 0.7))
    ref = NeoHookean(1.3, D=0.7)
    rng = np.random.default_rng(4)
    A = np.eye(3) + 0.2 * rng.standard_normal((3, 3))
    c, d = rng.standard_normal((3, 3)), rng.standard_normal((3, 3))
    for a, b in zip(user.evaluate(A, 4, c, d), ref.evaluate(A, 4, c, d)):
        np.testing.assert_allclose(a, b, rtol=1e-12, atol=1e-12)


def test_svk_closed_form_matches_its_invariant_form():
    """StVenantKirchhoff is evaluated in closed form (KIND_SVK); the same W
    written as psi(I1, I2) = mu/4 (I1^2 - 2 I2 - 2 I1 + 3) + lam/8 (I1 - 3)^2
    through the invariant (Faa di Bruno) path gives the same derivatives.
    Observed: agreement to 4e-16 of the largest entry (seed 6, four states)."""
    sp = pytest.importorskip("sympy")
    I1, I2, J, lam, mu = sp.symbols("I1 I2 J lam mu", positive=True)
    expr = mu / 4 * (I1 ** 2 - 2 * I2 - 2 * I1 + 3) + lam / 8 * (I1 - 3) ** 2
    ref = invariant_law_from_sympy(expr, I1, I2, J, params=(lam, mu), values=(1.2, 0.8))
    law = StVenantKirchhoff(1.2, 0.8)
    rng = np.random.default_rng(6)
    for _ in range(4):
        A = np.eye(3) + 0.4 * rng.standard_normal((3, 3))
        if np.linalg.det(A) <= 0:
            continue
        c, d = rng.standard_normal((3, 3)), rng.standard_normal((3, 3))
        for a, b in zip(law.evaluate(A, 4, c, d), ref.evaluate(A, 4, c, d)):
            assert np.abs(a - b).max() <= 1e-13 * max(1.0, np.abs(b).max())


@pytest.mark.parametrize("name", sorted(LAWS))
def test_third_derivative_vector_is_the_contracted_matrix(name):
    """mat_d3_vec (the point kernel's D3W[., c, d]) is D3W[., ., c] d, to
    round-off: the two sum different products in different orders, the
    power law's terms cancel (largest entry 14, terms larger), and the
    kernels fuse products into sums (kernels/small.py, fma).  Measured
    differences, of the largest entry: 2.0e-13 for the power law with the
    fused products (2.1e-13 with reassociated sums, branch
    fastmath-kernels), below 1e-13 in IEEE order; an error in the algebra
    is of order one."""
    from shellritz.kernels.material import mat_d3, mat_d3_vec, mat_prepare, new_state
    law = LAWS[name]()
    rng = np.random.default_rng(7)
    A = np.eye(3) + 0.25 * rng.standard_normal((3, 3))
    c, d = rng.standard_normal(9), rng.standard_normal(9)
    st = new_state()
    assert mat_prepare(law.kind, law.psi, law.params, A, *st) == 0
    m3, v3 = np.zeros((9, 9)), np.zeros(9)
    mat_d3(*st, c, m3)
    mat_d3_vec(*st, c, d, v3)
    assert np.abs(v3 - m3 @ d).max() <= 1e-12 * max(1.0, np.abs(m3).max())


def test_user_law_must_be_stress_free_at_identity():
    sp = pytest.importorskip("sympy")
    I1, I2, J = sp.symbols("I1 I2 J", positive=True)
    with pytest.raises(ValueError, match="must vanish"):
        invariant_law_from_sympy(I1 + J, I1, I2, J)


def test_user_law_must_be_a_cfunc_of_the_callback_signature():
    """The kernels call the law at its address: anything but a cfunc of
    PSI_SIGNATURE is refused before it can be called."""
    import numba as nb
    from numba import types

    def psi(I1, I2, J, par, out):
        out[0] = 0.0
    with pytest.raises(TypeError, match="numba.cfunc of signature"):
        InvariantLaw(psi)
    wrong = nb.cfunc(types.void(types.float64, types.float64, types.float64,
                                types.CPointer(types.float64)))(lambda a, b, c, o: None)
    with pytest.raises(TypeError, match="numba.cfunc of signature"):
        InvariantLaw(wrong)


def test_user_law_with_i2_dependence():
    """A Mooney-Rivlin-type law exercises the I2 algebra through a user callback."""
    sp = pytest.importorskip("sympy")
    I1, I2, J = sp.symbols("I1 I2 J", positive=True)
    expr = 0.3 * (I1 - 3) + 0.2 * (I2 - 3) - 1.4 * sp.log(J) + 0.5 * (J - 1) ** 2
    law = invariant_law_from_sympy(expr, I1, I2, J)
    assert isinstance(law, InvariantLaw)
    rng = np.random.default_rng(5)
    A = np.eye(3) + 0.2 * rng.standard_normal((3, 3))
    c, d = rng.standard_normal((3, 3)), rng.standard_normal((3, 3))
    W, P, AA, D3, D4 = law.evaluate(A, 4, c, d)
    dD3 = _fd(lambda X: law.evaluate(X, 3, c)[3], A, d)
    assert np.abs(dD3 - D4).max() <= 1e-8 * np.abs(D4).max()
