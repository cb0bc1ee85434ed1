"""Necking of a block in plane strain: the paper's reduction to the
one-dimensional gradient model of Audoly & Hutchinson (2016) (section 4.3)
and the onset of necking (derivation in docs/necking.md).

A block of length l and thickness h (reference X in [0, l], Z in [-h/2, h/2])
is pulled along X in plane strain, its faces Z = +-h/2 traction free.  For
the symmetric kinematics x(X, Z) even and z(X, Z) odd in Z the shell energy
of the plane-strain engine (G = I, level "bending" or "consistent") is, per
unit width,

    E_1d[x0] = h int_0^l ( w(x0') + (h^2/24) C(x0') x0''^2 - N x0' ) dX,
    w(lam) = W(diag(lam, 1, z1(lam))),   W_3(lam, 1, z1) = 0,
    C(lam) = W_1 p^2 / lam,   p = dz1/dlam,   W_1 = w'(lam),

the paper's E_1d with N the force per unit reference cross-section (the
printed formula lacks the factor h on W and N x0').  ``w`` is the plane-strain
uniaxial energy, ``w'`` the nominal stress; with a power-law hardening solid
``w'`` has a maximum (Considere).  Under end displacement control the
homogeneous state lam = const loses stability, with the mode
x0 = lam X + sin(pi X / l), where

    w''(lam) + (pi h / l)^2 / 12 C(lam) = 0        (onset_stretch).

The analysis here uses the material law alone (its own z1 Newton solve on
law.evaluate); the engine is only set up (necking_strip) and asked for its
Hessian inertia (engine_inertia), so the two are independent.
"""

from dataclasses import dataclass

import numpy as np
from scipy.optimize import brentq

from .discretize.planestrain import PlaneStrainShell
from .materials import Law, PowerLawHardening
from .linalg import negative_eigenvalues

__all__ = ["PlaneStrainTension", "plane_strain_tension", "e1d_energy", "considere_stretch",
           "onset_stretch", "necking_strip", "homogeneous_state", "engine_inertia",
           "engine_onset", "end_force", "default_law"]


def default_law():
    """The material of the necking studies: shear modulus 1, Poisson ratio
    0.3, hardening exponent 0.2 beyond a yield strain 0.02 (Considere at a
    plane-strain stretch of 1.2422; strongly elliptic in plane-strain tension
    up to 1.60)."""
    return PowerLawHardening(mu=1.0, n=0.2, eps0=0.02, nu=0.3)


@dataclass
class PlaneStrainTension:
    """Homogeneous plane-strain tension at stretch lam, faces traction free."""

    lam: float
    z1: float      # thickness stretch, W_3(lam, 1, z1) = 0
    w: float       # energy per reference volume
    w1: float      # w'(lam) = W_1: nominal stress (force per reference cross-section)
    w2: float      # w''(lam) = W_11 - W_13^2 / W_33
    p: float       # dz1/dlam = -W_13 / W_33

    @property
    def C(self):
        """Coefficient of the gradient term, W_1 p^2 / lam."""
        return self.w1 * self.p ** 2 / self.lam


def plane_strain_tension(law, lam, z1_guess=None, tol=2e-15):
    """Solve W_3(lam, 1, z1) = 0 for z1 by Newton (law.evaluate; A =
    diag(lam, 1, z1), axes X, Y (out of plane), Z) and return the state."""
    if not isinstance(law, Law):
        raise TypeError("law must be a shellritz material law")
    if not (np.isfinite(lam) and lam > 0):
        raise ValueError(f"stretch lam={lam!r} must be positive")
    z1 = 1.0 / np.sqrt(lam) if z1_guess is None else float(z1_guess)
    for _ in range(60):
        W, P, AA = law.evaluate(np.diag([lam, 1.0, z1]))
        dz = -P[2, 2] / AA[8, 8]
        z1 = max(z1 + dz, 0.5 * z1)
        if abs(dz) <= tol * z1:
            break
    else:
        raise RuntimeError(f"plane_strain_tension: no traction-free thickness stretch at lam={lam:g}")
    W, P, AA = law.evaluate(np.diag([lam, 1.0, z1]))
    return PlaneStrainTension(lam, z1, W, P[0, 0], AA[0, 0] - AA[0, 8] ** 2 / AA[8, 8],
                              -AA[0, 8] / AA[8, 8])


def e1d_energy(law, h, dx0, ddx0, weights, N=0.0):
    """E_1d by a quadrature: x0' and x0'' at the points, weights (dX)."""
    E = 0.0
    z1 = None
    for lam, dlam, wq in zip(dx0, ddx0, weights):
        st = plane_strain_tension(law, lam, z1)
        z1 = st.z1
        E += wq * h * (st.w + h * h / 24.0 * st.C * dlam ** 2 - N * lam)
    return E


def considere_stretch(law, bracket=(1.0005, 3.0)):
    """Stretch of the maximum nominal stress, w''(lam) = 0, in bracket."""
    f = lambda lam: plane_strain_tension(law, lam).w2
    if not (f(bracket[0]) > 0 > f(bracket[1])):
        raise ValueError(f"considere_stretch: the plane-strain nominal stress of {law!r} has no "
                         f"maximum between the stretches {bracket[0]:g} and {bracket[1]:g}")
    return brentq(f, *bracket, xtol=1e-14)


def onset_stretch(law, h_over_l, mode=1, bracket=None):
    """First stretch beyond the Considere maximum where the homogeneous state
    of a block with displacement-controlled, shear-free ends loses
    stability: w'' + (mode pi h / l)^2 C / 12 = 0 (mode sin(mode pi X / l))."""
    k2 = (mode * np.pi * h_over_l) ** 2 / 12.0

    def f(lam):
        st = plane_strain_tension(law, lam)
        return st.w2 + k2 * st.C
    lo = considere_stretch(law)
    if bracket is None:
        hi = lo + 0.01
        while f(hi) >= 0:
            hi = lo + 2 * (hi - lo)
            if hi > 10.0:
                raise ValueError(f"onset_stretch: no onset below a stretch of 10 for h/l = {h_over_l:g}")
        bracket = (lo, hi)
    return brentq(f, *bracket, xtol=1e-14)


# ---------------------------------------------------------------- engine side

def necking_strip(law, h, length, n, stretch, level="consistent", imperfection=0.0,
                  symmetric=False):
    """Plane-strain engine for the block: a strip along X in [0, length]
    with n elements, ends at a = 0 and a = stretch * length at t = 1 (ramped
    from the reference), b = 0 at both ends, slopes free (shear-free ends: the
    natural condition x0'' = 0).  imperfection: a thickness growth
    gamma_n = 1 - imperfection cos(pi X / length), thinnest at X = 0.
    symmetric: also b = b' = 0 at every node (the middle surface stays on
    z = 0: the symmetric kinematics of E_1d).  This removes the antisymmetric
    bending modes, whose stiffness turns negative past the force maximum at
    wavelengths below the thickness (docs/necking.md, section 6): in a neck
    stretched past the maximum they make the Hessian indefinite on meshes
    finer than about h/2."""
    eng = PlaneStrainShell.strip(n, length, h, law, level)
    eng.fix_coordinate(0, "a").fix_coordinate(0, "b")
    eng.fix_coordinate(-1, "a", stretch * length).fix_coordinate(-1, "b")
    if symmetric:
        for i in range(eng.n_nodes):
            eng._fix(i, [2, 3])           # b = b' = 0 (no public per-node constraint)
    if imperfection:
        eng.set_stretch_growth(1.0, 1.0, lambda s: 1.0 - imperfection * np.cos(np.pi * s / length))
    return eng


def homogeneous_state(engine, lam):
    """Free DOFs of the homogeneous state x0 = lam X, z0 = 0."""
    U = np.zeros((engine.n_nodes, 4))
    U[:, 0] = lam * engine.s[: engine.n_nodes]
    U[:, 1] = lam
    return U.reshape(-1)[engine.free]


def engine_inertia(law, h, length, n, lam, level="consistent"):
    """Number of negative eigenvalues of the plane-strain engine's Hessian at
    the homogeneous state of mean stretch lam on the displacement-controlled
    path (an exact equilibrium of the discretized energy: its gradient, also
    returned, is round-off), by the engine solver's inertia test (pivot signs
    of its LDL^T factorization, linalg.py)."""
    eng = necking_strip(law, h, length, n, lam, level)
    eng._setup()                      # the solver protocol's set-up (as solve() does)
    eng.set_parameter(1.0)
    _, g, K = eng.evaluate(homogeneous_state(eng, lam), 2)
    negative = negative_eigenvalues(K)
    if negative is None:
        raise ValueError(f"engine_inertia: singular Hessian at lam = {lam!r}")
    return negative, float(np.abs(g).max())


def engine_onset(law, h, length, n, lo, hi, tol=1e-9, level="consistent"):
    """Bisect [lo, hi] (stable at lo, unstable at hi) for the stretch where
    the engine's Hessian along the displacement-controlled homogeneous path
    first gets a negative eigenvalue.  Returns (lam_c, number of negative
    eigenvalues at hi, largest gradient seen)."""
    n_lo, g_lo = engine_inertia(law, h, length, n, lo, level)
    n_hi, g_hi = engine_inertia(law, h, length, n, hi, level)
    if n_lo != 0 or n_hi == 0:
        raise ValueError(f"engine_onset: {n_lo} negative eigenvalues at lo = {lo:g}, {n_hi} at "
                         f"hi = {hi:g}; the bracket must be stable at lo, unstable at hi")
    worst = max(g_lo, g_hi)
    while hi - lo > tol:
        mid = 0.5 * (lo + hi)
        neg, g = engine_inertia(law, h, length, n, mid, level)
        worst = max(worst, g)
        lo, hi = (mid, hi) if neg == 0 else (lo, mid)
    return 0.5 * (lo + hi), n_hi, worst


def end_force(engine):
    """Axial force per unit width on the end X = length of a solved engine:
    the derivative of the energy with respect to the prescribed end position
    a(length) (the engine's per-point gradients, assembled for that DOF)."""
    engine.evaluate(engine.free_state(), 1)
    g = np.zeros(4 * engine.n_nodes)
    np.add.at(g, engine.elem_dofs[engine.qelem], engine._Gq)
    return float(g[4 * (engine.n_nodes - 1)] - engine._f[4 * (engine.n_nodes - 1)])
