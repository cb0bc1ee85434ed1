"""Hyperelastic laws (MODEL.md section 6).

A law is the strain energy ``W(A)`` per unit volume of the grown (stress-free)
state, as a function of the elastic deformation ``A = F G^{-1}``.  Units are
the user's: moduli in stress units (e.g. Pa or kPa), ``W`` in energy per
volume, consistently with lengths and loads given to the solver.

Built-in laws
-------------
* :class:`NeoHookean` -- compressible neo-Hookean (paper eq:neo-Hookean),
  ``W = C/2 (I1 - 3 - 2 ln J) + D/2 (J - 1)^2``, from ``(C, nu)`` or ``(C, D)``.
* :class:`CubicStretch` -- the law of the paper's cylinder example (eq:WO),
  ``W = nu [(2/27) i1^3 - i2 + 1]`` in the invariants ``i1 = tr U``,
  ``i2 = (i1^2 - I1)/2`` of the right stretch ``U``; ``i1`` is the largest root
  of ``t^4 - 2 I1 t^2 - 8 J t + I1^2 - 4 I2 = 0``, a smooth function of the
  invariants of ``C``.  Its constant ``nu`` is a stiffness (the paper's symbol),
  not a Poisson ratio.
* :class:`StVenantKirchhoff` -- ``W = mu tr E^2 + lambda/2 (tr E)^2``,
  ``E = (C - I)/2``.
* :class:`LinearIsotropic` -- the linear law of eq:Ww,
  ``W = lambda/2 (tr H)^2 + mu |sym H|^2``, ``H = A - I``, for small-strain
  checks against classical plate and shell theory.
* :class:`PowerLawHardening` -- a compressible J2 deformation-theory solid
  with power-law hardening (the material class of Audoly & Hutchinson's
  necking analysis): effective stress ``~ eps_e^n`` beyond a yield-like strain
  ``eps0``, logarithmic effective strain (exact for isochoric plane strain),
  bulk energy ``K/2 (ln J)^2``.  Its uniaxial force-stretch curves have a
  maximum (Considere), at a log strain of about ``n``.

User laws
---------
Any isotropic law ``W = psi(I1, I2, J)`` can be added without touching the
engine: give :class:`InvariantLaw` a Numba ``cfunc`` with signature
``PSI_SIGNATURE`` that writes the 35 partial derivatives of ``psi`` of order 0
to 4 in the compact order ``COMPACT_INDEX`` (see :func:`invariant_law_from_sympy`
to generate it from a SymPy expression).  The engine compiles once for all laws
(the callback is a run-time function pointer), so adding a law costs no
recompilation of the shell kernels.
"""

import functools
import math

import numba as nb
import numpy as np
from numba.core.ccallback import CFunc

from .kernels.material import (COMPACT_INDEX, KIND_INVARIANT, KIND_LINEAR, KIND_SVK,
                               M_AA, N_PSI, PSI_SIGNATURE, S_W, V_P, mat_d3,
                               mat_d4, mat_prepare, new_state)

__all__ = ["Law", "InvariantLaw", "NeoHookean", "CubicStretch",
           "StVenantKirchhoff", "LinearIsotropic", "PowerLawHardening",
           "invariant_law_from_sympy",
           "PSI_SIGNATURE", "COMPACT_INDEX"]


def _check_finite(name, **values):
    for key, val in values.items():
        if not (isinstance(val, (int, float, np.floating, np.integer)) and math.isfinite(val)):
            raise ValueError(f"{name}: parameter {key}={val!r} must be a finite number")


def _check_poisson(name, nu):
    _check_finite(name, nu=nu)
    if not -1.0 < nu < 0.5:
        raise ValueError(f"{name}: Poisson ratio nu={nu!r} must satisfy -1 < nu < 0.5"
                         " (nu -> 0.5 is incompressible, not representable)")


class Law:
    """Base class: a law kind, a parameter vector and (for invariant laws) psi."""

    kind = KIND_INVARIANT
    name = "law"

    def __init__(self, params, psi):
        if not isinstance(psi, CFunc) or psi._sig != PSI_SIGNATURE:
            raise TypeError(f"{type(self).__name__}: psi must be a numba.cfunc of signature "
                            f"{PSI_SIGNATURE}, got {psi!r}")
        self.params = np.ascontiguousarray(params, dtype=np.float64)
        self.cfunc = psi              # kept alive: the kernels call it at its address
        self.psi = psi.address

    def __repr__(self):
        return f"{type(self).__name__}({', '.join(f'{v:g}' for v in self.params)})"

    # -- convenience evaluation (tests, post-processing); not used by engines --
    def evaluate(self, A, order=2, c=None, d=None):
        """Return W, P (3x3), AA (9x9) at A, plus D3(c) and D4(c, d) if asked.

        ``AA[3*i+J, 3*k+L] = d2W/dA_iJ dA_kL``; D3(c) = D3W[., ., c] and
        D4(c, d) = D4W[., ., c, d] as 9x9 matrices (c, d: 3x3 directions).
        """
        A = np.ascontiguousarray(A, dtype=np.float64)
        st = new_state()
        status = mat_prepare(self.kind, self.psi, self.params, A, *st)
        if status == 1:
            raise ValueError(f"{self!r}: det A = {np.linalg.det(A):g} <= 0 (inverted)")
        if status == 2:
            raise ValueError(f"{self!r}: non-finite energy derivatives at A")
        mv, mm, mp = st
        out = [mp[S_W], mv[V_P].reshape(3, 3).copy(), mm[M_AA].copy()]
        if order >= 3:
            m3 = np.zeros((9, 9))
            mat_d3(*st, np.ascontiguousarray(c, dtype=np.float64).reshape(9), m3)
            out.append(m3)
        if order >= 4:
            m4 = np.zeros((9, 9))
            mat_d4(*st, np.ascontiguousarray(c, dtype=np.float64).reshape(9),
                   np.ascontiguousarray(d, dtype=np.float64).reshape(9), 1.0, m4)
            out.append(m4)
        return tuple(out)


class InvariantLaw(Law):
    """A user law ``W = psi(I1, I2, J)`` given by a cfunc of PSI_SIGNATURE."""

    kind = KIND_INVARIANT

    def __init__(self, psi_cfunc, params=(), name="custom"):
        params = tuple(float(p) for p in params)
        for i, p in enumerate(params):
            _check_finite(name, **{f"params[{i}]": p})
        super().__init__(params if params else (0.0,), psi_cfunc)
        self.name = name
        # the stress-free state must be stress free: P(I) = 0
        W0, P0, AA0 = self.evaluate(np.eye(3))
        scale = max(1e-300, np.abs(AA0).max())
        if abs(W0) > 1e-10 * scale or np.abs(P0).max() > 1e-10 * scale:
            raise ValueError(f"law {name!r}: W(I) = {W0:g}, |P(I)| = {np.abs(P0).max():g};"
                             " the energy must vanish with zero stress at A = I")


# ---------------------------------------------------------------------------
# built-in psi callbacks: plain functions made Numba cfuncs on first use of
# their law (each compiled cfunc costs ~1 s on a fresh install, so a scene
# compiles only the laws it uses)
# ---------------------------------------------------------------------------

@functools.cache
def _cfunc(psi):
    return nb.cfunc(PSI_SIGNATURE, cache=True)(psi)


def _psi_neo_hookean(I1, I2, J, par, out):
    C = par[0]
    D = par[1]
    for n in range(35):
        out[n] = 0.0
    lnJ = math.log(J)
    out[0] = 0.5 * C * (I1 - 3.0 - 2.0 * lnJ) + 0.5 * D * (J - 1.0) ** 2
    out[1] = 0.5 * C                          # d/dI1
    out[3] = -C / J + D * (J - 1.0)           # d/dJ
    out[9] = C / (J * J) + D                  # d2/dJ2
    out[19] = -2.0 * C / J ** 3               # d3/dJ3
    out[34] = 6.0 * C / J ** 4                # d4/dJ4


def _psi_zero(I1, I2, J, par, out):
    for n in range(35):
        out[n] = 0.0


# -- truncated Taylor arithmetic in (I1, I2, J), total degree 4 -------------
# monomial n <-> exponents of COMPACT_INDEX[n]; derivative = coef * prod(e!)

def _taylor_tables():
    expo = np.array([[t.count(k) for k in range(3)] for t in COMPACT_INDEX], np.int64)
    where = {tuple(e): n for n, e in enumerate(expo.tolist())}
    prod = []
    for a in range(N_PSI):
        for b in range(N_PSI):
            e = tuple(expo[a] + expo[b])
            if sum(e) <= 4:
                prod.append((a, b, where[e]))
    fact = np.array([math.factorial(e[0]) * math.factorial(e[1]) * math.factorial(e[2])
                     for e in expo], np.float64)
    return np.array(prod, np.int64), fact


_TPROD, _TFACT = _taylor_tables()


@nb.njit(cache=True)
def _tmul(a, b, out):
    for n in range(out.shape[0]):
        out[n] = 0.0
    for r in range(_TPROD.shape[0]):
        out[_TPROD[r, 2]] += a[_TPROD[r, 0]] * b[_TPROD[r, 1]]


@nb.njit(cache=True)
def _tvar(value, k):
    """Taylor series of the k-th variable (0: I1, 1: I2, 2: J) at value."""
    x = np.zeros(35)
    x[0] = value
    x[1 + k] = 1.0
    return x


@nb.njit(cache=True)
def _cubic_stretch_psi(I1, I2, J, nu, out):
    # largest root t0 of q(t) = t^4 - 2 I1 t^2 - 8 J t + I1^2 - 4 I2 (= tr U)
    t = math.sqrt(3.0 * I1)
    for _ in range(100):
        q = t ** 4 - 2.0 * I1 * t * t - 8.0 * J * t + I1 * I1 - 4.0 * I2
        dq = 4.0 * t ** 3 - 4.0 * I1 * t - 8.0 * J
        dt = q / dq
        t -= dt
        if abs(dt) <= 1e-15 * t:
            break
    dq0 = 4.0 * t ** 3 - 4.0 * I1 * t - 8.0 * J
    # Taylor variables: I1 + e1, I2 + e2, J + e3; unknown T = t + tau
    x1 = _tvar(I1, 0)
    x2 = _tvar(I2, 1)
    x3 = _tvar(J, 2)
    T = np.zeros(35)
    T[0] = t
    T2 = np.zeros(35)
    T4 = np.zeros(35)
    tmp = np.zeros(35)
    q = np.zeros(35)
    x11 = np.zeros(35)
    _tmul(x1, x1, x11)
    for _ in range(5):  # simplified Newton gains one order per sweep
        _tmul(T, T, T2)
        _tmul(T2, T2, T4)
        for n in range(35):
            q[n] = T4[n] + x11[n] - 4.0 * x2[n]
        _tmul(x1, T2, tmp)
        for n in range(35):
            q[n] -= 2.0 * tmp[n]
        _tmul(x3, T, tmp)
        for n in range(35):
            q[n] -= 8.0 * tmp[n]
        for n in range(35):
            T[n] -= q[n] / dq0
    # psi = nu [(2/27) T^3 - (T^2 - I1)/2 + 1]
    _tmul(T, T, T2)
    _tmul(T2, T, tmp)
    for n in range(35):
        out[n] = nu * ((2.0 / 27.0) * tmp[n] - 0.5 * (T2[n] - x1[n])) * _TFACT[n]
    out[0] += nu


def _psi_cubic_stretch(I1, I2, J, par, out):
    res = np.zeros(35)
    _cubic_stretch_psi(I1, I2, J, par[0], res)
    for n in range(35):
        out[n] = res[n]


@nb.njit(cache=True)
def _tcompose(d, x, out):
    """Taylor series of f(x): out = sum_k d[k]/k! (x - x[0])^k, with d (5) the
    derivatives of order 0..4 of a univariate f at x[0] (Horner)."""
    dx = x.copy()
    dx[0] = 0.0
    tmp = np.zeros(35)
    for n in range(35):
        out[n] = 0.0
    out[0] = d[4] / 24.0
    for k, fact in ((3, 6.0), (2, 2.0), (1, 1.0), (0, 1.0)):
        _tmul(out, dx, tmp)
        for n in range(35):
            out[n] = tmp[n]
        out[0] += d[k] / fact


@nb.njit(cache=True)
def _acosh2_derivatives(y, d):
    """F(y) = acosh(y)^2 and its derivatives of order 1..4 into d (5), y >= 1
    (an analytic function of y; acosh alone has a square-root branch at 1).
    F solves (y^2 - 1) F'' + y F' = 2, and differentiating k times,
    (y^2 - 1) F^(k+2) + (2k+1) y F^(k+1) + k^2 F^(k) = 0.  Near y = 1 this
    recurrence (at y = 1) gives the Taylor series F = sum c_k (y - 1)^k,
    c_1 = 2, c_(k+1) = -k^2 c_k / ((2k+1)(k+1)) (radius of convergence 2);
    away from 1 the closed form F' = 2 acosh(y) / sqrt(y^2 - 1) and the
    recurrence solved for F^(k+2) (no cancellation once y^2 - 1 >= 1.25)."""
    x = y - 1.0
    if x < 0.5:
        for m in range(5):
            d[m] = 0.0
        c = 2.0
        for k in range(1, 60):
            for m in range(min(k, 4), -1, -1):
                ff = 1.0       # k! / (k - m)!
                for j in range(m):
                    ff *= k - j
                d[m] += c * ff * x ** (k - m)
            c *= -k * k / ((2.0 * k + 1.0) * (k + 1.0))
        return
    a = math.acosh(y)
    r2 = y * y - 1.0
    d[0] = a * a
    d[1] = 2.0 * a / math.sqrt(r2)
    d[2] = (2.0 - y * d[1]) / r2
    for k in (1, 2):
        d[k + 2] = -((2 * k + 1) * y * d[k + 1] + k * k * d[k]) / r2


@nb.njit(cache=True)
def _power_law_psi(I1, J, mu, n, eps0, K, out):
    """psi(I1, J) of PowerLawHardening as compact Taylor coefficients x
    factorials (see the class docstring for the formulas)."""
    x1 = _tvar(I1, 0)
    x3 = _tvar(J, 2)
    d = np.zeros(5)
    # J^(-2/3)
    p = -2.0 / 3.0
    c = 1.0
    for k in range(5):
        d[k] = c * J ** (p - k)
        c *= p - k
    jm = np.zeros(35)
    _tcompose(d, x3, jm)
    s = np.zeros(35)                     # s = I1 J^(-2/3) - 3 >= 0
    _tmul(x1, jm, s)
    s[0] -= 3.0
    # e2 = eps_e^2 = acosh(1 + s/2)^2 / 3
    _acosh2_derivatives(1.0 + 0.5 * s[0], d)
    for k in range(5):
        d[k] /= 3.0 * 2.0 ** k
    e2 = np.zeros(35)
    _tcompose(d, s, e2)
    # g(e2) = 3 mu eps0^2/(1+n) [(1 + e2/eps0^2)^((1+n)/2) - 1]
    m = 0.5 * (1.0 + n)
    base = 1.0 + e2[0] / (eps0 * eps0)
    c = 3.0 * mu * eps0 * eps0 / (1.0 + n)
    d[0] = c * (base ** m - 1.0)
    for k in range(1, 5):
        c *= (m - k + 1.0) / (eps0 * eps0)
        d[k] = c * base ** (m - k)
    g = np.zeros(35)
    _tcompose(d, e2, g)
    for i in range(35):
        out[i] = g[i] * _TFACT[i]
    # K/2 (ln J)^2: entries d/dJ ... d4/dJ4 (compact 3, 9, 19, 34)
    L = math.log(J)
    out[0] += 0.5 * K * L * L
    out[3] += K * L / J
    out[9] += K * (1.0 - L) / J ** 2
    out[19] += K * (2.0 * L - 3.0) / J ** 3
    out[34] += K * (11.0 - 6.0 * L) / J ** 4


def _psi_power_law(I1, I2, J, par, out):
    res = np.zeros(35)
    _power_law_psi(I1, J, par[0], par[1], par[2], par[3], res)
    for n in range(35):
        out[n] = res[n]


# ---------------------------------------------------------------------------
# built-in laws
# ---------------------------------------------------------------------------

class NeoHookean(Law):
    """Compressible neo-Hookean, ``W = C/2 (I1 - 3 - 2 ln J) + D/2 (J - 1)^2``.

    Give the shear modulus ``C`` and either Poisson's ratio ``nu``
    (``D = 2 C nu / (1 - 2 nu)``, -1 < nu < 1/2) or ``D`` directly.
    """

    name = "neo-Hookean"

    def __init__(self, C, nu=None, D=None):
        if (nu is None) == (D is None):
            raise ValueError("NeoHookean: give exactly one of nu or D")
        _check_finite("NeoHookean", C=C)
        if C <= 0:
            raise ValueError(f"NeoHookean: shear modulus C={C!r} must be > 0")
        if nu is not None:
            _check_poisson("NeoHookean", nu)
            D = 2.0 * C * nu / (1.0 - 2.0 * nu)
        _check_finite("NeoHookean", D=D)
        if D <= -2.0 * C / 3.0:
            raise ValueError(f"NeoHookean: D={D!r} gives a non-positive bulk modulus (need D > -2C/3)")
        self.C, self.D = float(C), float(D)
        super().__init__((C, D), _cfunc(_psi_neo_hookean))

    @property
    def nu(self):
        return self.D / (2.0 * (self.C + self.D))


class CubicStretch(Law):
    """The cylinder example's law (paper eq:WO), stiffness constant ``nu`` > 0."""

    name = "cubic-stretch"

    def __init__(self, nu=1.0):
        _check_finite("CubicStretch", nu=nu)
        if nu <= 0:
            raise ValueError(f"CubicStretch: nu={nu!r} must be > 0")
        super().__init__((nu,), _cfunc(_psi_cubic_stretch))


def _lame(name, lam, mu):
    _check_finite(name, lam=lam, mu=mu)
    if mu <= 0:
        raise ValueError(f"{name}: shear modulus mu={mu!r} must be > 0")
    if lam + 2.0 * mu / 3.0 <= 0:
        raise ValueError(f"{name}: bulk modulus lam + 2 mu/3 = {lam + 2 * mu / 3:g} must be > 0")


def _young_to_lame(name, E, nu):
    _check_finite(name, E=E)
    if E <= 0:
        raise ValueError(f"{name}: Young's modulus E={E!r} must be > 0")
    _check_poisson(name, nu)
    return E * nu / ((1 + nu) * (1 - 2 * nu)), E / (2 * (1 + nu))


class StVenantKirchhoff(Law):
    """``W = mu tr E^2 + lambda/2 (tr E)^2`` with Lame constants (lam, mu),
    ``E = (A^T A - I)/2``; evaluated in closed form (kernels/material.py,
    KIND_SVK), not through psi(I1, I2)."""

    name = "Saint Venant-Kirchhoff"
    kind = KIND_SVK

    def __init__(self, lam, mu):
        _lame("StVenantKirchhoff", lam, mu)
        super().__init__((lam, mu), _cfunc(_psi_zero))

    @classmethod
    def from_young(cls, E, nu):
        return cls(*_young_to_lame("StVenantKirchhoff", E, nu))


class LinearIsotropic(Law):
    """Linear isotropic law eq:Ww with Lame constants (lam, mu); small strain only."""

    name = "linear isotropic"
    kind = KIND_LINEAR

    def __init__(self, lam, mu):
        _lame("LinearIsotropic", lam, mu)
        super().__init__((lam, mu), _cfunc(_psi_zero))

    @classmethod
    def from_young(cls, E, nu):
        return cls(*_young_to_lame("LinearIsotropic", E, nu))


class PowerLawHardening(Law):
    """Compressible J2 deformation-theory solid with power-law hardening.

        W = g(eps_e^2) + K/2 (ln J)^2,
        g(e2) = 3 mu eps0^2 / (1 + n) [(1 + e2/eps0^2)^((1 + n)/2) - 1],
        eps_e^2 = acosh(1 + s/2)^2 / 3,   s = I1 J^(-2/3) - 3 >= 0.

    The effective stress-strain curve ``sigma_e = dg/deps_e = 3 mu eps_e
    (1 + eps_e^2/eps0^2)^((n-1)/2)`` is linear (shear modulus ``mu``) for
    ``eps_e << eps0`` and the power law ``3 mu eps0^(1-n) eps_e^n`` for
    ``eps_e >> eps0``: a smoothed version of the power-law solid of Audoly &
    Hutchinson (2016) (hyperelastic: loading and unloading follow the same
    curve).  ``eps_e`` is the von Mises equivalent logarithmic strain
    ``sqrt(2/3) |dev ln U|`` exactly for isochoric plane strain (stretches
    ``(e^u, 1, e^-u)`` give ``s = 2 cosh 2u - 2``) and at small strain, and a
    smooth function of the invariants everywhere (no eigenvalues).  Small
    strain: shear modulus ``mu``, bulk modulus ``K``.

    Parameters: ``mu`` > 0, hardening exponent ``0 < n <= 1`` (``n = 1``:
    no hardening transition), yield-like strain ``eps0`` > 0, and exactly one
    of the bulk modulus ``K`` > 0 or the small-strain Poisson ratio ``nu``
    (-1 < nu < 1/2, ``K = 2 mu (1 + nu) / (3 (1 - 2 nu))``).
    """

    name = "power-law hardening"

    def __init__(self, mu, n, eps0, K=None, nu=None):
        if (nu is None) == (K is None):
            raise ValueError("PowerLawHardening: give exactly one of K (bulk modulus) or nu")
        _check_finite("PowerLawHardening", mu=mu, n=n, eps0=eps0)
        if mu <= 0:
            raise ValueError(f"PowerLawHardening: shear modulus mu={mu!r} must be > 0")
        if not 0 < n <= 1:
            raise ValueError(f"PowerLawHardening: hardening exponent n={n!r} must satisfy 0 < n <= 1")
        if eps0 <= 0:
            raise ValueError(f"PowerLawHardening: yield strain eps0={eps0!r} must be > 0")
        if nu is not None:
            _check_poisson("PowerLawHardening", nu)
            K = 2.0 * mu * (1.0 + nu) / (3.0 * (1.0 - 2.0 * nu))
        _check_finite("PowerLawHardening", K=K)
        if K <= 0:
            raise ValueError(f"PowerLawHardening: bulk modulus K={K!r} must be > 0")
        self.mu, self.n, self.eps0, self.K = float(mu), float(n), float(eps0), float(K)
        super().__init__((mu, n, eps0, K), _cfunc(_psi_power_law))

    @property
    def nu(self):
        """Small-strain Poisson ratio."""
        return (3.0 * self.K - 2.0 * self.mu) / (2.0 * (3.0 * self.K + self.mu))


def invariant_law_from_sympy(expr, I1, I2, J, params=(), values=(), name="custom"):
    """Build an :class:`InvariantLaw` from a SymPy expression of (I1, I2, J).

    ``params`` are SymPy symbols of material constants and ``values`` their
    numbers.  SymPy (not a runtime dependency) must be installed.  The
    derivatives of order 0..4 are generated symbolically and compiled into a
    cfunc once per call.
    """
    import sympy as sp

    xs = sp.symbols("I1 I2 J", positive=True)
    expr = expr.subs(dict(zip((I1, I2, J), xs)))
    lines = []
    names = {}
    for i, p in enumerate(params):
        names[p] = sp.Symbol(f"_p{i}")
        lines.append(f"    _p{i} = par[{i}]")
    for n, tup in enumerate(COMPACT_INDEX):
        e = expr
        for k in tup:
            e = sp.diff(e, xs[k])
        e = sp.simplify(e.subs(names))
        lines.append(f"    out[{n}] = {sp.pycode(e)}")
    src = "def _psi(I1, I2, J, par, out):\n" + "\n".join(lines) + "\n"
    scope = {"math": math}
    exec(src, scope)
    cf = nb.cfunc(PSI_SIGNATURE)(scope["_psi"])
    return InvariantLaw(cf, values, name=name)
