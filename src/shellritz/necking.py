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

Past the onset, follow_neck traces the path of an imperfect block with the
solver's arc-length continuation (through the fold where the neck snaps
back); path_landmarks locates the force maximum, the folds and the loss of
strong ellipticity (ellipticity_stretch) in the neck.
"""

from dataclasses import dataclass

import numpy as np
from scipy.interpolate import CubicSpline
from scipy.optimize import brentq, minimize_scalar

from .discretize.line import hermite
from .discretize.planestrain import PlaneStrainShell
from .linalg import negative_eigenvalues
from .materials import Law, PowerLawHardening
from .solve import SolveError, SolverOptions, continuation

__all__ = ["PlaneStrainTension", "plane_strain_tension", "e1d_energy", "considere_stretch",
           "onset_stretch", "in_plane_ellipticity", "ellipticity_stretch", "NeckingStrip",
           "necking_strip", "homogeneous_state", "engine_inertia", "engine_onset", "end_force",
           "follow_neck", "path_landmarks", "default_law"]


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
    z1 = 1.0 / lam if z1_guess is None else float(z1_guess)     # J = 1
    for _ in range(60):
        W, P, AA = law.evaluate(np.diag([lam, 1.0, z1]))
        dz = -P[2, 2] / AA[8, 8]
        z1 = min(max(z1 + dz, 0.5 * z1), 2.0 * z1)
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


def in_plane_ellipticity(law, A, n_dir=180):
    """Smallest eigenvalue, over in-plane unit vectors N (X-Z plane), of the
    in-plane acoustic tensor Q_ik(N) = AA_iJkL N_J N_L at the 3x3 state A
    (i, k in X, Z): negative where strong ellipticity is lost (shear bands
    in the plane)."""
    AA = law.evaluate(np.asarray(A, float))[2].reshape(3, 3, 3, 3)[np.ix_([0, 2], [0, 2], [0, 2], [0, 2])]

    def lowest(theta):
        N = np.array([np.cos(theta), np.sin(theta)])
        return np.linalg.eigvalsh(np.einsum("iJkL,J,L->ik", AA, N, N))[0]
    th = np.linspace(0, np.pi, n_dir, endpoint=False)
    k = int(np.argmin([lowest(t) for t in th]))
    best = minimize_scalar(lowest, bracket=(th[k] - np.pi / n_dir, th[k], th[k] + np.pi / n_dir))
    return min(best.fun, lowest(th[k]))


def ellipticity_stretch(law, step=0.01, limit=5.0):
    """First stretch of plane-strain tension (faces traction free) where the
    law loses strong ellipticity in the plane (in_plane_ellipticity = 0):
    scanned from 1 by step, then brentq."""
    f = lambda lam: in_plane_ellipticity(law, np.diag([lam, 1.0, plane_strain_tension(law, lam).z1]))
    lam = 1.0
    while f(lam + step) > 0:
        lam += step
        if lam > limit:
            raise ValueError(f"ellipticity_stretch: {law!r} is strongly elliptic in plane-strain "
                             f"tension up to a stretch of {limit:g}")
    return brentq(f, lam, lam + step, xtol=1e-10)


# ---------------------------------------------------------------- engine side
class NeckingStrip(PlaneStrainShell):
    """The plane-strain engine of the block (built by necking_strip).  Along
    an arc-length path (solve(path="arclength")) it records as its monitor
    the end force and, at the quadrature points, the current position, the
    thickness h |y1| and the axial stretch x' of the middle surface
    (unpacked by path_rows)."""

    end_stretch = None      # x(l) / l at t = 1 (set by necking_strip)

    def _quadrature_interpolation(self):
        """Matrices (nq, 4 n_nodes) giving x and x' at the quadrature points
        from the nodal DOFs (the engine's Hermite interpolation)."""
        if getattr(self, "_interp", None) is None:
            nq = len(self.sq)
            Hx, Hd = np.zeros((nq, 4 * self.n_nodes)), np.zeros((nq, 4 * self.n_nodes))
            e = self.qelem
            ell = self.s[e + 1] - self.s[e]
            H, dH, _ = hermite((self.sq - self.s[e]) / ell, ell)
            cols = self.elem_dofs[e][:, [0, 1, 4, 5]]          # a, a' of the element's two nodes
            rows = np.arange(nq)[:, None]
            Hx[rows, cols], Hd[rows, cols] = H.T, dH.T
            self._interp = (Hx, Hd)
        return self._interp

    def monitor(self):
        Hx, Hd = self._quadrature_interpolation()
        return np.r_[end_force(self), Hx @ self.U, self.h * np.linalg.norm(self.Y1, axis=1), Hd @ self.U]

    def end_stretch_at(self, t):
        """End stretch x(l) / l at the continuation parameter t."""
        return 1.0 + t * (self.end_stretch - 1.0)

    def path_rows(self, history):
        """The recorded arc-length path as dicts: lam (end stretch), force
        (per unit width), t_min (thinnest section), stretch_max (largest
        axial stretch x', in the neck), negative (Hessian eigenvalues),
        energy, x and thickness (at the quadrature points)."""
        nq = len(self.sq)
        rows = []
        for p in history.path:
            m = np.asarray(p["monitor"])
            x, th, lam = m[1:1 + nq], m[1 + nq:1 + 2 * nq], m[1 + 2 * nq:]
            rows.append(dict(lam=self.end_stretch_at(p["t"]), force=float(m[0]), t_min=float(th.min()),
                             stretch_max=float(lam.max()), negative=p["negative"], energy=p["energy"],
                             x=x.tolist(), thickness=th.tolist()))
        return rows


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
    eng = NeckingStrip.strip(n, length, h, law, level)
    # the block is the paper's one-dimensional gradient model E_1d exactly:
    # without the h^5 strain-gradient term that keeps compressed bending
    # levels bounded below on meshes finer than the thickness
    # (docs/validity.md; in tension it shifts the onset by 1.5e-5 only)
    eng.strain_gradient = None
    eng.end_stretch = float(stretch)
    eng.fix_coordinate(0, "a").fix_coordinate(0, "b")
    eng.fix_coordinate(-1, "a", stretch * length).fix_coordinate(-1, "b")
    if symmetric:
        for i in range(eng.n_nodes):
            eng.fix_node(i, ["b", "b'"])
    if imperfection:
        eng.set_growth(function=lambda t, s: _thickness_growth(imperfection, s, length))
    return eng


def _thickness_growth(imperfection, s, length):
    """(G0, G1) of the thickness imperfection G = diag(1, 1, gamma_n(s)), the
    same at every t (not ramped: along an arc-length path t goes back and
    forth with the end stretch, the imperfection stays)."""
    G0 = np.zeros((len(s), 3, 3))
    G0[:, 0, 0] = G0[:, 1, 1] = 1.0
    G0[:, 2, 2] = 1.0 - imperfection * np.cos(np.pi * s / length)
    return G0, np.zeros((len(s), 3, 3))


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
    """Axial force per unit width on the end X = length of a solved engine
    (the support's reaction, LineShell.end_reaction)."""
    return float(engine.end_reaction(-1)[0])


def follow_neck(engine, steps=30, max_steps=400, max_ds=None):
    """Follow the equilibrium path of a necking_strip from the reference to
    the end stretch engine.end_stretch by the solver's pseudo-arc-length
    continuation (solve.continuation, path "arclength": it passes the force
    maximum and the folds where the neck snaps back; first step 1/steps in
    t, at most max_steps steps, none longer than max_ds: default 4/steps).  Returns (rows of path_rows, why it
    stopped): the path ends at t = 1, or where the continuation stops (its
    message; the path up to there is kept, the engine holds its last
    converged state)."""
    engine._setup()                   # the solver protocol's set-up (as solve() does)
    opts = SolverOptions(path="arclength", verbose=False, arc_max_steps=max_steps, arc_max_ds=max_ds)
    try:
        history = continuation(engine, steps=steps, opts=opts)
        stop = f"reached the end stretch {engine.end_stretch:g}"
    except SolveError as exc:
        history, stop = exc.history, str(exc)
    return engine.path_rows(history), stop


def path_landmarks(lam, force, t_min, margin):
    """Landmarks of a necking path given as sequences along it (end stretch,
    force, thinnest section -- decreasing along the path --, and a
    strong-ellipticity margin that turns negative where the neck loses
    ellipticity): the force maximum, the fold (largest end stretch: there the
    neck snaps back), the loss of ellipticity and the second fold (smallest
    end stretch after the first).  Each a dict (lam, force, t_min, index:
    the sampled extreme, or the first point past the loss of ellipticity),
    or None where the path does not reach it.  The extrema are those of
    cubic splines in t_min through the path points (the path is sampled
    coarsely near the folds); the loss of ellipticity is interpolated
    linearly in the margin."""
    lam, force, t_min, margin = (np.asarray(v, float) for v in (lam, force, t_min, margin))
    if not np.all(np.diff(t_min) < 0):
        raise ValueError("path_landmarks: the thinnest section must decrease along the path")

    def extremum(y, k):
        """(lam, force, t_min) at the extremum of the cubic spline of y(t_min)
        between the neighbours of the sampled extreme k (the sample itself
        at an end of the path)."""
        at = dict(lam=float(lam[k]), force=float(force[k]), t_min=float(t_min[k]), index=int(k))
        if k == 0 or k == len(y) - 1:
            return at
        splines = {key: CubicSpline(t_min[::-1], v[::-1]) for key, v in (("y", y), ("lam", lam),
                                                                            ("force", force))}
        roots = splines["y"].derivative().roots(extrapolate=False)
        roots = roots[(roots >= t_min[k + 1]) & (roots <= t_min[k - 1])]
        if len(roots):
            ts = float(roots[np.argmax(splines["y"](roots))])
            at.update(lam=float(splines["lam"](ts)), force=float(splines["force"](ts)), t_min=ts)
        return at
    out = dict(force_max=extremum(force, int(np.argmax(force))), fold=None, ellipticity_loss=None,
               second_fold=None)
    turn = np.nonzero(np.diff(lam) < 0)[0]
    if len(turn):
        k = int(turn[0])
        out["fold"] = extremum(lam, k)
        back = np.nonzero(np.diff(lam[k:]) > 0)[0]
        if len(back):
            out["second_fold"] = extremum(-lam, k + int(back[0]))
    lost = np.nonzero(margin <= 0)[0]
    if len(lost) and lost[0] > 0:
        k = int(lost[0])
        w = margin[k - 1] / (margin[k - 1] - margin[k])
        mix = lambda v: float(v[k - 1] + w * (v[k] - v[k - 1]))
        out["ellipticity_loss"] = dict(lam=mix(lam), force=mix(force), t_min=mix(t_min), index=k)
    return out
