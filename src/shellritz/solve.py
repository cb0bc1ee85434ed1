"""Equilibria by Newton's method: trust region or line search, continuation
in a load/growth parameter t (adaptive steps or arc length), stability.

The solver works on a *problem* object (the DKT, axisymmetric and
plane-strain engines provide one) with

    problem.set_parameter(t)            growth, loads and prescribed values at t
    problem.evaluate(x, mode)           -> (E, g, K) on the free DOFs x;
                                           mode 0: (E, None, None), 1: (E, g, None),
                                           2: (E, g, K) with K the lower triangle (CSR,
                                           one sparsity pattern per problem)
    problem.free_state() / problem.set_free_state(x)
    problem.save_point() / problem.restore_point(saved)   rollback (warm starts etc.)
    problem.load_scale(), problem.size_scale(), problem.energy_magnitude()
    problem.parameter_derivative(x, t)  optional: dg/dt exactly, or None (then by
                                           central differences)
    problem.block_layout()              optional: nodal blocks and rigid motions (the free
                                           rigid motions are kept out of the steps; AMG)
    problem.monitor()                   optional: numbers recorded along an arc-length path

``evaluate`` raises :class:`EvaluationError` where the energy is undefined
(inverted material, loss of ellipticity, ...); the trust region and the line
search treat that as +inf and step back.

One Newton step = one Hessian assembly and one factorization (or AMG
preconditioner reuse): the step solves the trust-region model by
Steihaug-Toint conjugate gradients preconditioned by the factorization of
the Hessian where it is positive definite (then the step is Newton's, in one
CG iteration) or else by the last positive definite factorization, so that CG
finds the negative curvature directions and the step follows them to the
trust-region boundary (linalg.py).  Once Newton converges fast (a full
step on a positive definite Hessian cut |g| tenfold), the next Hessian
differs little from the factorized one: on large problems (REUSE_MIN_DOFS,
where a factorization costs far more than a CG iteration) the step is then
solved by CG preconditioned by the previous factorization instead of a
new one, as an inexact Newton step (Eisenstat-Walker forcing, no looser
than lets the step end below the tolerance); a solve that needs more than
REUSE_MAX_CG iterations or meets negative curvature falls back to
factorizing.  The line-search variant takes the
truncated Newton-CG direction with Armijo backtracking.  Each load step
after the first starts from the cubic Hermite extrapolation through the
last two equilibria and their tangents dx/dt = -K^-1 dg/dt (_predict).
At every converged
state the inertia of the Hessian is known from its factorization (where
the last step reused an earlier factorization, the lowest eigenvalue by
LOBPCG preconditioned by it, where its residual decides the sign:
assess_stability); an
unstable equilibrium is reported with its lowest eigenvalues and, by
default, left along its most unstable mode to a stable state.
"""

import time
import warnings
from dataclasses import dataclass, field, fields
from typing import NamedTuple

import numpy as np
import scipy.sparse.linalg as spla

from .linalg import (AUTO_DIRECT_MAX_DOFS, PRECISIONS, CGPath,
                     LinearSolverError, free_rigid_modes, jacobi, lower_matvec, make_linear_solver,
                     projector, resolve_method, steihaug_cg)
from .model import checked_float, checked_int

GLOBALIZATIONS = ("auto", "trust-region", "line-search")
PATHS = ("load", "arclength")
PREDICTORS = ("tangent", "secant")
STABILITY = ("auto", "inertia", "eigen", "off")
REUSE = ("auto", "always", "never")


class EvaluationError(RuntimeError):
    """The energy cannot be evaluated at this state (message says where/why)."""


class SolveError(RuntimeError):
    """Continuation failed; ``.last_t`` is the last converged parameter,
    ``.history`` the solver history and ``.result`` (set by the engine) the
    last converged state."""

    def __init__(self, msg, last_t=None, history=None):
        super().__init__(msg)
        self.last_t = last_t
        self.history = history


@dataclass
class SolverOptions:
    """Options of :func:`continuation` (keyword arguments of the engines' solve)."""

    rtol: float = 1e-9          # |g| <= rtol * max(|g| at the step start, |external load|)
    xtol: float = 1e-13         # or a full Newton step below xtol * problem size
    ftol: float = 1e-15         # |g| floor: the force of a relative move ftol on the stiffest DOF
    max_iter: int = 40          # Newton iterations per continuation step (CONVERGING_SPAN)
    verbose: bool = True
    linear: str = "auto"        # linalg.METHODS
    globalization: str = "auto"   # "trust-region" | "line-search"; auto: line search with a
    #                             multilevel AMG hierarchy, else trust region (_uses_trust_region)
    path: str = "load"          # "load": adaptive steps in t; "arclength": passes limit points
    stability: str = "auto"     # "inertia" (direct methods), "eigen" (+ lowest eigenpairs), "off";
    #                             auto: inertia with a direct method, off with AMG
    reuse_factorization: str = "auto"   # solve fast-converging Newton steps with the previous
    #                             factorization: "auto" from REUSE_MIN_DOFS free DOFs on,
    #                             "always", "never" (direct methods)
    factor_precision: str = "double"   # of the direct factorizations; "single" (PARDISO:
    #                             a third less memory per factor, preconditioner of the CG,
    #                             refined solves, the stability inertia in double; linalg.py)
    escape: bool = True         # leave an unstable equilibrium along its most unstable mode
    max_escapes: int = 8        # per continuation step
    armijo: float = 1e-4
    min_alpha: float = 1e-8
    max_cg: int = 300           # conjugate-gradient iterations per Newton step
    watchdog: int = 4           # full Newton steps that may go uphill in energy (0: monotone)
    predictor: str = "tangent"  # load steps: start of each step after the first ("tangent":
    #                             cubic Hermite through the last two points and their tangents,
    #                             with a direct method; "secant"; _predict)
    max_dt: float = None        # load steps: the largest step in t (None: 1; steps=n with
    #                             max_dt=1/n takes n equal steps unless one fails)
    arc_max_steps: int = 400    # arc length: path steps before giving up
    arc_ds: float = None        # arc length: first step (default: 1/steps in t)
    arc_max_ds: float = None    # arc length: largest step (default: 4x the first)
    stop: object = None         # arc length: callable(path point dict) -> reason to stop or None

    def __post_init__(self):
        for name, allowed in (("globalization", GLOBALIZATIONS), ("path", PATHS), ("predictor", PREDICTORS),
                              ("stability", STABILITY), ("reuse_factorization", REUSE),
                              ("factor_precision", PRECISIONS)):
            if getattr(self, name) not in allowed:
                raise ValueError(f"{name}={getattr(self, name)!r}: choose one of {', '.join(allowed)}")
        resolve_method(self.linear, 0)          # checks the name and availability
        if self.factor_precision == "single" and self.path == "arclength":
            raise ValueError("factor_precision='single' with path='arclength': arc length finds "
                             "its folds from the inertia of every factorization; use 'double'")
        for name in ("verbose", "escape"):
            if not isinstance(getattr(self, name), (bool, np.bool_)):
                raise TypeError(f"{name} must be True or False, got {getattr(self, name)!r}")
        for name, low in (("max_iter", 1), ("max_cg", 1), ("arc_max_steps", 1),
                          ("max_escapes", 0), ("watchdog", 0)):
            checked_int(name, getattr(self, name), low)
        for name, low, high, optional in (("rtol", 0, None, False), ("xtol", 0, None, False),
                                          ("ftol", 0, None, False), ("armijo", 0, 1, False),
                                          ("min_alpha", 0, 1, False), ("max_dt", 0, 1, True),
                                          ("arc_ds", 0, None, True), ("arc_max_ds", 0, None, True)):
            value = getattr(self, name)
            if not (optional and value is None):
                checked_float(name, value, low, high, zero_ok=name in ("xtol", "ftol"),
                              high_ok=name == "max_dt")
        if self.stop is not None and not callable(self.stop):
            raise TypeError(f"stop must be a callable(path point) or None, got {self.stop!r}")


@dataclass
class Iteration:
    t: float
    it: int
    energy: float
    grad_norm: float
    step: float                 # line search: alpha; trust region: ||p||_M of the step taken
    radius: float               # trust radius (inf: unlimited), nan for the line search
    accepted: bool
    negative: int               # negative eigenvalues of the Hessian (None: not known)
    krylov_its: int
    krylov_exit: str
    linear: str                 # linear method used
    setup_s: float              # factorization / AMG set-up time
    solve_s: float              # Krylov solve time
    seconds: float              # whole iteration (assembly included)
    uphill: bool = False        # a full Newton step on the watchdog's probation (energy above its start)


@dataclass
class SolveHistory:
    iterations: list = field(default_factory=list)
    steps: list = field(default_factory=list)     # (t, converged)
    predictors: list = field(default_factory=list)   # start of each load step tried (_predict)
    stable: bool = True         # the last converged state is stable (None: not assessed)
    unstable_modes: int = 0     # negative eigenvalues of its Hessian (None: not known)
    lowest_eigenvalues: list = field(default_factory=list)   # unstable states, or stability="eigen"
    modes: object = None        # unstable states: the eigenvectors of the negative eigenvalues
    #                             (columns, free DOFs; set_free_state(x + a * mode) perturbs along one)
    escapes: list = field(default_factory=list)   # dicts: t, negative, eigenvalue, amplitude
    notes: list = field(default_factory=list)     # fallbacks, warnings
    path: list = field(default_factory=list)      # arc length: dicts t, energy, negative, monitor
    linear: str = ""            # linear method
    factorizations: int = 0
    evaluations: list = field(default_factory=lambda: [0, 0, 0])   # energy / +gradient / +Hessian
    nested: list = field(default_factory=list)    # coarse levels of nested.solve_nested (dicts)
    thickness_stages: list = field(default_factory=list)   # solve(thickness_path=...): dicts

    @property
    def assemblies(self):
        """Hessian assemblies (each with the energy and gradient)."""
        return self.evaluations[2]

    def write_path(self, filename):
        """The arc-length path (t, energy, negative eigenvalues, monitored
        values) as CSV."""
        import csv
        if not self.path:
            raise ValueError("no arc-length path recorded (solve with path='arclength')")
        keys = ["t", "energy", "negative"]
        width = len(self.path[0].get("monitor", ()))
        with open(filename, "w", newline="") as fh:
            w = csv.writer(fh)
            w.writerow(keys + [f"monitor_{k}" for k in range(width)])
            for p in self.path:
                w.writerow([p[k] for k in keys] + list(p.get("monitor", ())))


class _Linear:
    """The linear solver of a problem, created at its first Hessian (the
    sparsity pattern is fixed per problem), with the fallback from AMG to a
    direct method."""

    def __init__(self, problem, opts, history):
        self.problem, self.opts, self.history = problem, opts, history
        self.solver = None
        self.amg_failures = 0
        self.rigid = None          # free rigid motions (orthonormal columns) or None
        self.project = None

    def factorize(self, K, exact_inertia=False):
        """Factorize (or prepare the preconditioner for) K; returns the
        number of negative eigenvalues (None: unknown) and the set-up time.
        exact_inertia: in double precision (DirectSolver.factorize)."""
        t0 = time.perf_counter()
        layout = self._rigid_motions()
        if self.solver is None:
            self.solver = self._new_solver(self.opts.linear, K, self.opts.factor_precision, layout)
            self.history.linear = self.solver.name
        builds = getattr(self.solver, "builds", 0)
        try:
            negative = self.solver.factorize(K, exact_inertia)
        except LinearSolverError as exc:
            self.history.notes.append(f"{self.solver.name}: {exc}")
            negative = None
        if getattr(self.solver, "builds", 0) > builds:
            self.note_hierarchy()
        self.history.factorizations += 1
        return negative, time.perf_counter() - t0

    def _rigid_motions(self):
        """Set the free rigid motions of the current state (rotations turn
        with it) and their projector; returns the problem's block layout."""
        layout = self.problem.block_layout() if hasattr(self.problem, "block_layout") else None
        self.rigid = free_rigid_modes(layout)
        self.project = projector(self.rigid)
        return layout

    def note_hierarchy(self):
        """A history note (and a line with verbose), once per solve, where
        the AMG hierarchy just built is not the default one (AMGSolver.note:
        multigrid over nested meshes, or the lean near null space)."""
        note = getattr(self.solver, "note", None)
        if note is not None and "AMG: " + note not in self.history.notes:
            self.history.notes.append("AMG: " + note)
            if self.opts.verbose:
                print("    AMG: " + note, flush=True)

    def may_reuse(self, opts, n):
        """The next Newton step (n free DOFs) may be solved with the last
        factorization (it is positive definite; see the module docstring)."""
        if opts.reuse_factorization == "never" or not self.direct:
            return False
        if not self.solver.current_is_positive_definite():
            return False
        return opts.reuse_factorization == "always" or n >= REUSE_MIN_DOFS

    def release(self):
        """Free the factors (MKL keeps PARDISO's until told: without this
        every solve of a process kept its two factors to the end)."""
        if self.solver is not None:
            self.solver.release()

    def fall_back_to_direct(self, K, why):
        method = "pardiso" if resolve_method("auto", 0) == "pardiso" else "superlu"
        self.history.notes.append(f"AMG: {why}; falling back to the direct solver '{method}'")
        if self.opts.verbose:
            print(f"    AMG: {why}; falling back to '{method}'", flush=True)
        if self.solver is not None:
            self.solver.release()
        else:
            self._rigid_motions()          # (a first solver: regularized for free bodies)
        self.solver = self._new_solver(method, K, self.opts.factor_precision)
        self.history.linear = f"amg->{method}"
        return self.factorize(K)

    def _new_solver(self, method, K, precision, layout=None):
        solver = make_linear_solver(method, K.shape[0], K.indptr, K.indices, layout,
                                    singular=self.rigid is not None, precision=precision)
        if solver.single:
            self.history.notes.append(f"{solver.name}: factorizations in single precision "
                                      "(the stability inertia in double)")
        return solver

    def to_double(self, why):
        """Replace single-precision factorizations by double ones."""
        self.history.notes.append(f"{self.solver.name}: {why}; factorizations in double precision")
        if self.opts.verbose:
            print(f"    {why}: factorizations in double precision", flush=True)
        self.solver.release()
        self.solver = self._new_solver(self.solver.name, self.solver.K, "double")

    @property
    def direct(self):
        return self.solver is not None and self.solver.direct

    def preconditioner(self, K):
        M = self.solver.preconditioner() if self.solver is not None else None
        return M if M is not None else jacobi(K)


# what preconditions a Newton step's CG, which sets its forcing (_forcing)
FORCING_PRECONDITIONERS = ("current factor", "reused factor", "multilevel AMG", "earlier factor")


def _forcing(preconditioner, gnorm, gnorm_prev, tol):
    """Relative tolerance eta of the Krylov solve, ||K p + g|| <= eta |g|,
    by the step's ``preconditioner`` (FORCING_PRECONDITIONERS).  With the
    factorization of the current Hessian ("current factor"): tight (an
    iteration or two anyway).  Else inexact Newton: Eisenstat-Walker choice
    2 (gamma 0.9, exponent 2, at most 0.1), bounded by the tolerance
    ``tol`` on |g|.  With the previous Hessian's factorization reused on a
    fast Newton step ("reused factor", cheap iterations) no looser than
    leaves the step's residual half the margin of a predicted last step
    below tol, so that the step is the last; with a multilevel AMG
    hierarchy ("multilevel AMG") no tighter than leaves it at half of tol
    (Kelley, Iterative Methods for Linear and Nonlinear Equations, 1995,
    section 6.3.2): the gradient after the step is its residual plus a term
    quadratic in the step, and a smaller residual does not end the solve
    sooner (the 1M default leaf's third
    Newton step, from |g| 2.1e-8, asked 1.3e-5 of CG and had not finished
    at the run's 55-minute limit; with the floor, 33 iterations).  Not with
    the factorization of an earlier Hessian ("earlier factor": PARDISO's
    last positive definite one for an indefinite Hessian, one-level AMG):
    its iterations are cheap, and the paths depend on them (the grown discs
    past secondary bifurcations, bench/disc_robustness.py; the stability
    map's thin panel with one-level AMG and the trust region took 812
    instead of 318 Newton iterations with the floor)."""
    if preconditioner not in FORCING_PRECONDITIONERS:
        raise ValueError(f"preconditioner={preconditioner!r}: one of {', '.join(FORCING_PRECONDITIONERS)}")
    if preconditioner == "current factor":
        return 1e-10
    # (the choice's safeguard max(eta, 0.9 eta_prev^2) acts only where
    # 0.9 eta_prev^2 > 0.1, never below the cap of 0.1)
    eta = 0.1 if gnorm_prev is None else min(max(0.9 * (gnorm / gnorm_prev) ** 2, 1e-10), 0.1)
    if preconditioner == "reused factor":
        return float(max(min(eta, 0.5 * CONVERGED_MARGIN * tol / gnorm), 1e-10))
    if preconditioner == "multilevel AMG":
        return float(min(max(eta, 0.5 * tol / gnorm), 0.1))
    return float(eta)


# trust region: a rejected step's radius shrinks to this fraction of the step
# (0.5 rather than the common 0.25: on the buckling leaf the step at half the
# rejected one, the last accepted radius, is usually accepted; measured:
# 12k-triangle leaf 22 -> 20 Newton iterations, 20 -> 17 factorizations)
TRUST_SHRINK = 0.5
# a load step whose Newton iterations on positive definite Hessians have not
# reduced |g| by SLOW_NEWTON_DROP (a hundredfold) after SLOW_NEWTON of them
# is too large: Newton creeps along a curved valley (a very thin shell's
# inextensional path) with good but short steps, where a smaller step
# converges in a few iterations (thin panel h/R = 1e-3: 237 -> 129 Newton iterations, stability map).
# The lowest |g| of the run counts: near a nearly singular Hessian |g| goes
# up and down on the way (the 6-ring leaf's first step, 2026-12-06: 156-fold
# down at the run's 11th step, 77-fold at its 13th; judged by its last |g|
# the step was cut six times, to dt = 1/256).  Fiftyfold (2e-2) was tried
# (2026-12-06, night): the stability map's leaf with line search and PARDISO
# 145 -> 26 iterations (its first step from the flat disc, 85-fold down in
# ten, is cut four times), every other configuration the same, but the grown
# discs 55 instead of 56 of 60 stable with the default trust region
SLOW_NEWTON = 10
SLOW_NEWTON_DROP = 1e-2
# a load step's Newton iterations that reach max_iter while |g| still falls
# tenfold over the last five go on (to 2 max_iter at most): giving the step
# up restarts it from the last equilibrium with half the step (the 12k leaf
# from the flat disc with AMG, 2026-12-05: 9.8e-9 at the 40th iteration,
# tenfold in five, given up: 374 Newton iterations and 632 s in all)
CONVERGING_SPAN = 5
CONVERGING_DROP = 0.1
# the last Newton step of a load step is predicted where quadratic
# convergence (|g| falling like |g_k|^3 / |g_(k-1)|^2 after a full Newton step
# that cut it tenfold, plus the step's CG residual eta |g_k|) puts |g| at
# x + p below this fraction of the tolerance: x + p gets a gradient but no
# Hessian, and where |g| is below the tolerance the Hessian at x (factorized
# already, unless the step reused an earlier factorization: then LOBPCG,
# assess_stability) stands for that of the equilibrium (stability
# inertia, tangent predictor): one Hessian assembly, and one factorization,
# fewer per load step so ended; a prediction that misses costs one gradient
# (Sze cantilever, 10 equal steps: 7 of them end so, 6 miss: 53 -> 46
# assemblies and factorizations, 2.95 -> 2.65 s).  The two states differ by
# a step of the size of |g| at x over the stiffness, far below the tolerance
# on the state; their inertia differs only if an eigenvalue of K is within
# the change of K over that step of zero (a critical point to round-off)
CONVERGED_MARGIN = 0.1
# a load step on the way to t = 1 whose Newton iteration stagnates (max_iter,
# stalled, or SLOW_NEWTON) is kept, with a note, where its last iterate, or
# else the lowest-|g| iterate it passed off the watchdog's probation
# (restored), has |g| below this fraction of the step's force scale: past
# secondary bifurcations the grown discs' equilibria are nearly singular,
# Newton creeps at |g| of 1e-8 .. 1e-9 (relative 1e-6 .. 1e-7) where the
# tolerance asks 1e-9, and cutting the step only lands on the same
# near-singular states until dt < min_dt (the 4-ring discs failed at
# t = 0.95-0.99).  Such a state is only the start of the next
# step; the path's end is held to the tolerance.  bench/disc_robustness.py:
# 50 -> 60 of 60 discs stable (2026-12-06; 56 with the last iterate alone:
# near t = 0.993 uphill watchdog steps on nearly singular Hessians left the
# free 4-ring disc at |g| 1e-6 after it had passed 9e-9).
ON_THE_WAY_RTOL = 1e-5
# a failed load path gets the hint of a limit point (_limit_point_hint) where
# the tangent at its last equilibrium would move the shell by more than this
# many times its size over the rest of the parameter (measured: a sphere
# inflated past its pressure maximum 14; a failure on a sliver triangle 0.39,
# on a near-symmetry 0.017; a sheet curled by a large G1 45 at t = 0, but
# with no earlier tangent to show the path turning)
LIMIT_POINT_REACH = 1.0
# factorization reuse (module docstring), from REUSE_MIN_DOFS free DOFs on
# ("auto"; a size, not a timing, so that a run is reproducible): PARDISO on
# the leaf, 226k DOFs: a factorization 6.1 s = 24 CG iterations (two
# triangular solves and a product with K each); 56k DOFs: 0.25 s = 8, where
# factorizing is as cheap.  A solve with a reused factorization is given up
# after REUSE_MAX_CG iterations.  Its forcing is inexact Newton's: to 1e-10
# (as with the current Hessian's factor) the 100k leaf's last step missed 10
# iterations and factorized (22 s), with the forcing below it takes 4 (1.1 s)
REUSE_MIN_DOFS = 150_000
REUSE_MAX_CG = 10
# with a single-precision factorization of the current positive definite
# Hessian, the conjugate gradients reach the exact Newton step in a few
# iterations (factor_precision="single"); where they need more than this, the
# Hessian is too ill-conditioned for single precision: factorizations in
# double precision from then on (history note)
SINGLE_MAX_CG = 20


def _uses_trust_region(opts, solver):
    """Globalization "auto": the line search with a multilevel AMG
    hierarchy, else (a factorization, or AMG of one level: the factor of an
    earlier Hessian, as the direct path's last positive definite one) the
    trust region.  Measured (README "Solver", bench/scaling.py, the
    stability map): on the 32-ring leaf from the flat disc (three AMG
    levels) AMG took 23 Newton iterations with the line search and 328 with
    the trust region, and the 12k leaf 67.6 s with the line search against
    more than 7 minutes; with PARDISO the trust region takes fewer
    iterations everywhere (32-ring leaf 18 against 240), and so does
    one-level AMG in time (1.5k leaf 6.9 s against 19.7 s, 10-ring leaf of
    the map 2.2 against 4.0 s)."""
    if opts.globalization != "auto":
        return opts.globalization == "trust-region"
    return solver.direct or solver.one_level


def minimize(problem, t, opts, history, g_ref, lin, may_cut=False, accept=None):
    """Newton iterations at fixed t from the current state.  Returns
    (K, inertia) at the equilibrium reached, or None on failure: K the
    Hessian (lower CSR), inertia the number of its negative eigenvalues
    where the solver's current factorization is a double-precision one of
    K (None: K is not factorized).  K is that of the equilibrium, or, after
    a last step predicted by quadratic convergence (CONVERGED_MARGIN), that
    of the Newton iterate one step before it (see there).
    ``may_cut``: the caller can retry with a smaller load step, so a step on
    which Newton converges only slowly is given up early (SLOW_NEWTON)."""
    x = problem.free_state()
    try:
        E, g, K = problem.evaluate(x, 2)
    except EvaluationError as exc:
        if opts.verbose:
            print(f"    t={t:.4f}: start state not admissible ({exc})")
        return None
    gnorm = np.linalg.norm(g)
    size = problem.size_scale()
    # floor: round-off level, the force of a relative displacement ftol on the stiffest DOF
    stiffest = np.abs(K.diagonal()).max() if K.shape[0] else 0.0
    floor = opts.ftol * size * stiffest
    tol = max(opts.rtol * max(g_ref, gnorm), floor)
    # round-off of the energy, for accepting steps by the gradient where the
    # energy test cannot tell: relative to its terms, or to the energy of a
    # unit strain of the stiffest DOF over the problem size (a stress-free
    # state has no terms to measure it by)
    noise = lambda E: 1e3 * np.finfo(float).eps * max(problem.energy_magnitude(), abs(E),
                                                      stiffest * size * size)
    trust = None                # trust region or line search: decided at the first factorization
    radius = np.inf
    last_step = np.inf
    gnorms, energies = [gnorm], [E]
    factorized = False          # the factorization belongs to the current x
    gnorm_prev = None
    first_norm = None           # size of the first step (trust region collapse test)
    # the trial is evaluated with its Hessian (one assembly instead of two
    # when it is accepted) unless a rejection is likely: after a rejection,
    # and for the first step at a radius just doubled
    hessian_with_trial = True
    cg_path = replay = None     # the CG path of the model at x; set after a rejection
    # watchdog (Chamberlain et al. 1982): full Newton steps are taken even
    # uphill in energy (a large rotation predicted by the linearization
    # stretches the membrane: the step overshoots in energy but lands in the
    # basin of the solution), provided that within opts.watchdog steps the
    # energy falls below that of the last monotone point, else the iteration
    # returns there and globalizes (once per call)
    watch = None                # the last monotone point while on probation
    watch_spent = opts.watchdog <= 0
    pd_since = None             # |g| at the first of the current run of positive definite Hessians
    pd_run = 0
    pd_best = None              # the lowest |g| of that run
    fast = False                # the last step was a full Newton step that cut |g| tenfold
    may_reuse = False           # so the previous factorization may serve this step (fast, and
    #                             not yet tried and failed at this x)
    reused = False              # this step is solved with the previous factorization
    inertia = None              # negative pivots of a double-precision factorization of K
    done = lambda: (K, inertia if factorized else None)
    best = None                 # on the way: the iterate of lowest |g| <= accept (off probation)

    def on_the_way():
        """Whether a step on the way to the path's end that Newton cannot
        finish is kept (``accept``, module constant ON_THE_WAY_RTOL): the
        current iterate if it qualifies, else the best one seen (restored)."""
        nonlocal x, E, g, K, gnorm, factorized
        if not (watch is None and accept is not None and gnorm <= accept):
            if best is None:
                return False
            x, E, g, K, gnorm = _back_to(problem, best)
            factorized = False
        history.notes.append(f"t={t:.4g}: Newton stagnates at |g| {gnorm:.3e} (tolerance {tol:.3e}: "
                             f"a nearly singular equilibrium); kept on the way (|g| <= {accept:.3e})")
        if opts.verbose:
            print(f"    t={t:.4f}: Newton stagnates at |g| {gnorm:.3e}: kept on the way "
                  f"(|g| <= {accept:.3e})")
        return True
    for it in range(2 * opts.max_iter + 1):
        t0 = time.perf_counter()
        if gnorm <= tol or last_step <= opts.xtol * size:
            if watch is None or E < watch["E"]:
                return done()
            x, E, g, K, gnorm = _back_to(problem, watch)     # an equilibrium above the start
            watch, watch_spent, factorized, last_step = None, True, False, np.inf
            fast = may_reuse = False
        if (accept is not None and watch is None and gnorm <= accept
                and (best is None or gnorm < best["gnorm"])):
            best = dict(saved=problem.save_point(), x=x, gnorm=gnorm)
        small_drop = 1e-6 * max(problem.energy_magnitude(), abs(E))
        stalled = (watch is None and len(gnorms) >= 8 and gnorm > 0.5 * gnorms[-7]
                   and energies[-7] - E <= small_drop)
        # an iteration still converging at max_iter (|g| down CONVERGING_DROP
        # over the last CONVERGING_SPAN iterations) goes on, up to twice as long;
        # so does one the caller cannot retry with a smaller step (the start,
        # the arc-length landing at t = 1, a step at min_dt) while its energy
        # still falls (the centre-clamped 3-ring disc's landing from the flat
        # branch to the buckled state: tests/test_solver.py)
        converging = len(gnorms) > CONVERGING_SPAN and gnorm <= CONVERGING_DROP * gnorms[-1 - CONVERGING_SPAN]
        descending = (not may_cut and len(energies) > CONVERGING_SPAN
                      and energies[-1 - CONVERGING_SPAN] - E > small_drop)
        # (not within a watchdog probation, which ends within opts.watchdog
        # steps: its uphill iterates say nothing of the descent)
        if ((it >= opts.max_iter and watch is None and not (converging or descending))
                or it == 2 * opts.max_iter
                or stalled):
            if on_the_way():
                return done()
            if opts.verbose:
                print(f"    t={t:.4f}: Newton stagnates (|g| {gnorm:.3e} after {it} iterations, "
                      f"tolerance {tol:.3e})")
            return None
        setup = 0.0
        if not factorized:
            reused = may_reuse and lin.may_reuse(opts, len(x))
            if reused:
                negative = None
            else:
                negative, setup = lin.factorize(K)
            inertia = negative if lin.direct and not lin.solver.single else None   # None if reused
            factorized = True
        if trust is None:
            trust = _uses_trust_region(opts, lin.solver)
        exact = lin.solver.current_is_positive_definite()
        pd_run, pd_since = (pd_run + 1, pd_since or gnorm) if exact else (0, None)
        pd_best = min(pd_best, gnorm) if exact and pd_run > 1 else gnorm
        if may_cut and pd_run > SLOW_NEWTON and pd_best > SLOW_NEWTON_DROP * pd_since:
            if on_the_way():
                return done()
            if opts.verbose:
                print(f"    t={t:.4f}: Newton converges slowly on positive definite Hessians "
                      f"(|g| {pd_best:.3e} at best after {SLOW_NEWTON} steps from {pd_since:.3e}): "
                      "smaller step")
            return None
        matvec = lower_matvec(K)
        eta = _forcing("reused factor" if reused else "current factor" if exact
                       else "multilevel AMG" if not (lin.direct or lin.solver.one_level)
                       else "earlier factor", gnorm, gnorm_prev, tol)
        ts = time.perf_counter()
        if exact:
            r = np.inf             # the Newton step, truncated to the region below
        elif trust and not np.isfinite(radius):
            # indefinite (or unknown) Hessian: a finite region, the size of the
            # preconditioned gradient step
            r = np.sqrt(max(-(g @ lin.preconditioner(K)(-g)), 0.0)) or 1.0
        else:
            r = radius if trust else np.inf
        # after a rejected step the model at x is the same: the step at the
        # smaller radius comes from the recorded CG path, without iterations
        single = exact and lin.solver.single     # a single-precision factor of the current K
        replayed = replay.step(r) if replay is not None else None
        replay = None
        try:
            if replayed is not None:
                p, info = replayed
            else:
                cg_path = CGPath() if trust and lin.direct and np.isfinite(r) else None
                p, info = steihaug_cg(matvec, g, lin.preconditioner(K), r, eta,
                                      REUSE_MAX_CG if reused else SINGLE_MAX_CG if single else opts.max_cg,
                                      lin.project, cg_path)
        except LinearSolverError as exc:
            cg_path = None
            if not lin.direct and lin.solver.restore_previous():
                history.notes.append(f"t={t:.4g} it={it}: rebuilt AMG hierarchy not SPD ({exc}); "
                                     "previous hierarchy restored")
                M = lin.preconditioner(K)
            else:
                history.notes.append(f"t={t:.4g} it={it}: {exc}; Jacobi preconditioner")
                M = jacobi(K)
            p, info = steihaug_cg(matvec, g, M, r, eta, opts.max_cg, lin.project)
        solve_s = time.perf_counter() - ts
        if reused and info["reason"] != "converged":
            # the previous factorization is no longer a good preconditioner
            # (or the Hessian is indefinite): factorize and solve again (the
            # last step is still fast: the last Newton step may be predicted)
            history.notes.append(f"t={t:.4g} it={it}: reused factorization: CG {info['reason']} "
                                 f"after {info['iterations']} iterations; factorized")
            factorized = may_reuse = False
            continue
        if single and info["reason"] == "maxiter":
            # the Hessian is too ill-conditioned for a single-precision factor
            lin.to_double(f"t={t:.4g} it={it}: CG preconditioned by the single-precision factor "
                          f"of the current Hessian reached {SINGLE_MAX_CG} iterations")
            factorized = False
            continue
        if not lin.direct:
            rebuilt = lin.solver.note_iterations(info["iterations"], info["reason"], eta)
            setup += rebuilt
            if rebuilt:
                lin.note_hierarchy()
                note = (f"t={t:.4g} it={it}: AMG hierarchy rebuilt ({info['iterations']} CG iterations)"
                        + ("; the previous one released first: no memory for two"
                           if lin.solver.released_previous else ""))
                history.notes.append(note)
                if opts.verbose:
                    print("    " + note, flush=True)
            lin.amg_failures = 0 if info["reason"] != "maxiter" else lin.amg_failures + 1
            if lin.amg_failures >= 2:
                negative, more = lin.fall_back_to_direct(K, f"CG reached {opts.max_cg} iterations twice")
                setup += more
                continue
        newton_step = exact and info["reason"] == "converged"
        if newton_step and np.abs(p).max() <= opts.xtol * size and watch is None:
            return done()           # the Newton correction is at round-off
        if (newton_step and fast and watch is None
                and gnorm * ((gnorm / gnorm_prev) ** 2 + eta) <= CONVERGED_MARGIN * tol
                and (not trust or info["norm_M"] <= radius)):
            # quadratic convergence predicts |g| below tol at x + p: its
            # gradient without a Hessian, and, if it is, K at x stands for
            # the equilibrium's (factorized already unless the step reused
            # an earlier factorization)
            final = _final_trial(problem, x, p, E, tol, noise(E))
            if final is not None:
                x = x + p
                problem.set_free_state(x)
                history.iterations.append(Iteration(t, it, final[0], final[1], info["norm_M"],
                                                    radius if trust else np.nan, True, negative,
                                                    info["iterations"], info["reason"],
                                                    lin.solver.name, setup, solve_s,
                                                    time.perf_counter() - t0))
                if opts.verbose:
                    print(f"    t={t:.4f} it={it:2d}  E={final[0]: .10e}  |g|={final[1]:.3e}  "
                          "full Newton step (predicted last)", flush=True)
                return done()
        if watch is not None or (newton_step and not watch_spent):
            trial = _watchdog_trial(problem, x, p, newton_step, g, matvec, noise(E))
            if trial is None and watch is not None:        # off the probation: back
                x, E, g, K, gnorm = _back_to(problem, watch)
                watch, watch_spent, factorized = None, True, False
                fast = may_reuse = False
                continue
            if trial is not None:
                if watch is None and trial[0] >= E:
                    watch = dict(saved=problem.save_point(), x=x, E=E, gnorm=gnorm,
                                 steps=0, predicted=-(g @ p + 0.5 * (p @ matvec(p))))
                x = x + p
                problem.set_free_state(x)
                history.iterations.append(Iteration(t, it, trial[0], np.linalg.norm(trial[1]),
                                                    info["norm_M"], radius if trust else np.nan, True,
                                                    negative, info["iterations"], info["reason"],
                                                    lin.solver.name,
                                                    setup, solve_s, time.perf_counter() - t0,
                                                    uphill=watch is not None))
                E, g, K = trial
                gnorm_prev, gnorm = gnorm, np.linalg.norm(g)
                fast = may_reuse = newton_step and gnorm <= 0.1 * gnorm_prev
                gnorms.append(gnorm)
                energies.append(E)
                factorized, last_step = False, np.abs(p).max()
                if watch is not None:
                    watch["steps"] += 1
                    if E <= watch["E"] - 0.1 * watch["predicted"]:
                        watch = None                      # below the start: monotone again
                    elif watch["steps"] > opts.watchdog:
                        x, E, g, K, gnorm = _back_to(problem, watch)
                        watch, watch_spent, last_step = None, True, np.inf
                        fast = may_reuse = False
                if opts.verbose:
                    print(f"    t={t:.4f} it={it:2d}  E={E: .10e}  |g|={gnorm:.3e}  full Newton step"
                          + (" (watchdog)" if watch is not None else ""), flush=True)
                continue
        if trust and info["norm_M"] > radius:
            # the Newton step (r = inf with a positive definite factor), or the
            # first CG direction where K, though its factor is positive
            # definite, has negative curvature (a near-zero eigenvalue of
            # either sign: a near-symmetry), scaled onto the boundary; the
            # latter, unscaled, repeated one rejected step to max_iter
            p *= radius / info["norm_M"]
            info.update(norm_M=radius, reason="boundary")
            newton_step = False
        first_norm = first_norm or info["norm_M"]
        Kp = matvec(p)
        slope = g @ p
        predicted = -(slope + 0.5 * (p @ Kp))
        # at the round-off floor: the predicted decrease is below the round-off
        # of the energy and the last full step no longer reduced |g|
        # (ill-conditioned problems, e.g. very thin shells, stop here)
        if (newton_step and len(gnorms) > 1 and gnorm > 0.2 * gnorms[-2]
                and abs(predicted) <= 1e3 * np.finfo(float).eps * problem.energy_magnitude()):
            last_step = 0.0
            continue
        saved = problem.save_point()
        if trust:
            accepted, En, trial = _trust_trial(problem, x, p, E, gnorm, predicted, noise(E),
                                               with_hessian=hessian_with_trial)
            alpha = 1.0
            hessian_with_trial = accepted
            # no expansion for a step read off the CG path of a rejected one:
            # the same model along the same path has just failed at twice its radius
            expand = replayed is None
            ratio_good = accepted and (En is None or E - En >= 0.75 * predicted)
            if not accepted and newton_step and abs(predicted) <= noise(E) and En is not None:
                problem.restore_point(saved)
                return done()       # the full Newton step is lost in round-off: converged
            if not accepted:
                problem.restore_point(saved)
                radius = TRUST_SHRINK * info["norm_M"]
                replay = cg_path
            elif ratio_good and expand and info["reason"] in ("boundary", "negative curvature"):
                radius = 2.0 * info["norm_M"]
                hessian_with_trial = False
            elif accepted and En is not None and E - En < 0.25 * predicted:
                radius = 0.5 * info["norm_M"]
            if not accepted and radius < 1e-12 * first_norm:
                if opts.verbose:
                    print(f"    t={t:.4f} it={it}: trust region collapsed")
                return None
        else:
            if slope >= 0:             # not a descent direction (cannot happen with SPD M)
                p, slope = -g, -gnorm ** 2
            accepted, alpha = _line_search(problem, x, p, E, gnorm, slope, opts, noise(E))
            trial = None
            if not accepted and newton_step and abs(predicted) <= noise(E):
                problem.restore_point(saved)
                return done()       # the full Newton step is lost in round-off: converged
            if not accepted:
                problem.restore_point(saved)
                if opts.verbose:
                    print(f"    t={t:.4f} it={it}: line search failed")
                return None
        rec = Iteration(t, it, E, gnorm, info["norm_M"] if trust else alpha,
                        radius if trust else np.nan, accepted, negative, info["iterations"],
                        info["reason"], lin.solver.name, setup, solve_s, 0.0)
        if accepted:
            x = x + alpha * p
            last_step = np.abs(p).max() if newton_step and alpha == 1.0 else np.inf
            problem.set_free_state(x)
            if trial is not None:
                E, g, K = trial
            else:
                try:
                    E, g, K = problem.evaluate(x, 2)
                except EvaluationError:
                    problem.restore_point(saved)
                    return None
            factorized = False
            gnorm_prev, gnorm = gnorm, np.linalg.norm(g)
            fast = may_reuse = newton_step and alpha == 1.0 and gnorm <= 0.1 * gnorm_prev
            gnorms.append(gnorm)
            energies.append(E)
            rec.energy, rec.grad_norm = E, gnorm
        rec.seconds = time.perf_counter() - t0
        history.iterations.append(rec)
        if opts.verbose:
            print(f"    t={t:.4f} it={it:2d}  E={E: .10e}  |g|={gnorm:.3e}  "
                  + (f"|p|={info['norm_M']:.2e} r={radius:.1e}" if trust else f"step={alpha:.3g}")
                  + ("" if accepted else " rejected")
                  + (f"  neg={negative}" if negative else "")
                  + (f"  cg={info['iterations']}" if info["iterations"] > 1 else ""), flush=True)
    return None


def _watchdog_trial(problem, x, p, newton_step, g, matvec, noise):
    """(E, g, K) at x + p for a full Newton step of significant size, or
    None (not a Newton step, at round-off, or not admissible)."""
    if not newton_step or -(g @ p + 0.5 * (p @ matvec(p))) <= noise:
        return None
    try:
        trial = problem.evaluate(x + p, 2)
    except EvaluationError:
        return None
    if not (np.isfinite(trial[0]) and np.all(np.isfinite(trial[1]))):
        return None
    return trial


def _final_trial(problem, x, p, E, tol, noise):
    """(E, |g|) at x + p where that is an equilibrium (|g| <= tol, the
    energy not above E beyond round-off), else None; one energy and gradient
    evaluation, no Hessian."""
    try:
        En, gn, _ = problem.evaluate(x + p, 1)
    except EvaluationError:
        return None
    gnorm = np.linalg.norm(gn)
    if np.isfinite(En) and gnorm <= tol and En <= E + noise:
        return En, gnorm
    return None


def _back_to(problem, watch):
    """Restore the watchdog's monotone point: (x, E, g, K, |g|).  Its
    gradient and Hessian are assembled again (the watchdog seldom returns;
    keeping its Hessian would hold three at once: 2.1 GB each at 1M
    triangles)."""
    problem.restore_point(watch["saved"])
    E, g, K = problem.evaluate(watch["x"], 2)
    return watch["x"], E, g, K, np.linalg.norm(g)


def _trust_trial(problem, x, p, E, gnorm, predicted, noise, with_hessian):
    """Evaluate the trust-region step x + p: (accepted, new energy or None,
    (E, g, K) at x + p or None).  ``with_hessian``: evaluate the Hessian
    with the energy (one assembly instead of two when the step is accepted,
    as it usually is after an accepted step)."""
    xn = x + p
    try:
        trial = problem.evaluate(xn, 2 if with_hessian else 0)
    except EvaluationError:
        return False, None, None
    En = trial[0]
    if not np.isfinite(En):
        return False, None, None
    kept = trial if with_hessian else None
    if predicted > 0 and E - En >= 0.1 * predicted:
        return True, En, kept
    # near the solution the energy test drowns in round-off: accept steps
    # that reduce the gradient instead
    if abs(En - E) <= noise:
        gn = trial[1] if with_hessian else problem.evaluate(xn, 1)[1]
        if np.linalg.norm(gn) < gnorm:
            return True, None, kept
    return False, En, None


def _line_search(problem, x, p, E, gnorm, slope, opts, noise):
    """Armijo backtracking; an inadmissible trial state counts as +inf."""
    alpha = 1.0
    while alpha >= opts.min_alpha:
        xn = x + alpha * p
        try:
            En, _, _ = problem.evaluate(xn, 0)
            ok = np.isfinite(En) and En <= E + opts.armijo * alpha * slope
            if not ok and alpha == 1.0 and abs(En - E) <= noise:
                _, gn, _ = problem.evaluate(xn, 1)
                ok = np.linalg.norm(gn) < gnorm
        except EvaluationError:
            ok = False
        if ok:
            return True, alpha
        alpha *= 0.5
    return False, alpha


# ------------------------------------------------------------------ stability
class StabilityWarning(UserWarning):
    """A solve ended on a state whose stability was not assessed."""


# AMG gives no inertia, and LOBPCG preconditioned by AMG (a block of 5
# vectors, up to 200 iterations, a W-cycle per vector each) took 26 s on top
# of the 68 s finest level of the nested 24k leaf, so stability="auto"
# assesses nothing with AMG; the result may then be an
# unstable equilibrium: a disc grown symmetrically from the flat reference
# stays flat (energy 1.38e-3 where the buckled state has 4.33e-4)
STABILITY_NOT_ASSESSED = (
    "the stability of the solved state was not assessed (linear solver without a "
    "factorization: AMG); it may be an unstable equilibrium, e.g. a symmetric state that "
    "should buckle.  stability=\"eigen\" computes the lowest eigenvalues (LOBPCG "
    "preconditioned by AMG) and leaves unstable states; stability=\"off\" silences this warning")

# LOBPCG's residual tolerance, relative to max |diag K|: a thin shell's
# lowest eigenvalues are far below its largest entries (the leaf: 4e-10 to
# 4e-9 of max |diag| 0.2), and an absolute 1e-8 left residuals as large as
# the lowest eigenvalue (32-ring leaf: 4.7e-10 at 4.0e-10): no sign.  With
# 1e-12 relative, 13-14 instead of 7-8 iterations (preconditioned by a
# nearby factorization), residuals 1e-14.
EIGEN_RTOL = 1e-12
# lowest_eigenpairs(until_sign=True) decides the sign of the lowest
# eigenvalue w (its Ritz value farther from zero than its residual) without
# converging to EIGEN_RTOL: SIGN_BURST iterations estimate w, then LOBPCG goes
# on from its current block (a restart: SciPy's LOBPCG has no callback) to
# the residual SIGN_MARGIN |w| (not below EIGEN_RTOL), repeated with the new
# estimate while the sign stays open.  The 100k leaf (w = 4.0e-11, max |diag|
# 0.25), blocks of 3 vectors: 4 + 3 instead of 9 preconditioner applications
# to EIGEN_RTOL.  Looks after every iteration (restarts) stalled: on the
# 16-ring leaf the residual stayed at 2.6e-7, 60 times w.
SIGN_BURST = 3
SIGN_MARGIN = 0.25
EIGEN_MAXITER = 200


def lowest_eigenpairs(lin, K, count, until_sign=False):
    """The ``count`` algebraically smallest eigenpairs of K (lower CSR) by
    LOBPCG, preconditioned by the solver's SPD preconditioner (the last
    positive definite factorization, or AMG), and their residual norms
    |K v - w v| (|v| = 1): an eigenvalue of K lies within the residual of
    each Ritz value w.  until_sign: converged only as far as the sign of the
    lowest eigenvalue needs (SIGN_BURST)."""
    n = K.shape[0]
    count = max(1, min(count, n - 1))
    matvec = lower_matvec(K)
    A = spla.LinearOperator((n, n), matvec=matvec, matmat=matvec, dtype=np.float64)
    prec, applied = lin.preconditioner(K), [0]     # one application per LOBPCG iteration

    def apply(r):
        applied[0] += 1
        return prec(r)
    M = spla.LinearOperator((n, n), matvec=apply, matmat=apply, dtype=np.float64)
    rng = np.random.default_rng(0)
    # two vectors beyond those wanted (a lowest eigenvalue in a cluster
    # converges faster), none for the sign alone: PARDISO solves 3 vectors in
    # 0.65 s, one in 0.26 s on the 100k leaf, whose sign took 4 + 8 solves of
    # one (4.3 s) against 4 + 3 of three (8.0 s; of two, 4 + 7: 9.5 s)
    X = rng.standard_normal((n, count if until_sign else count + 2))
    # the free rigid motions (zero eigenvalues) are excluded
    floor = EIGEN_RTOL * max(np.abs(K.diagonal()).max(), 1e-300)
    tol, maxiter, done = floor, (SIGN_BURST if until_sign else EIGEN_MAXITER), 0
    while True:
        before = done
        with warnings.catch_warnings():
            # a tolerance not reached is judged below, by the residuals returned
            # (SciPy's message has line breaks before these words: (?s))
            warnings.filterwarnings("ignore", message="(?s).*not reaching the requested tolerance",
                                    category=UserWarning)
            w, X = spla.lobpcg(A, X, M=M, Y=lin.rigid, largest=False, tol=tol, maxiter=maxiter)
        done = applied[0]
        order = np.argsort(w)
        w, X = w[order], X[:, order]
        residuals = np.linalg.norm(matvec(X) - X * w, axis=0)
        if (not until_sign or abs(w[0]) > residuals[0] or residuals.max() <= floor
                or done >= EIGEN_MAXITER or done == before):
            return w[:count], X[:, :count], residuals[:count]
        tol, maxiter = max(floor, SIGN_MARGIN * abs(w[0])), EIGEN_MAXITER - done


def assess_stability(problem, K, opts, history, lin, t, inertia=None):
    """Inertia (and eigenpairs on request) of the Hessian K at a converged
    state.  Returns the most unstable mode (or None).  inertia: that of the
    solver's current factorization, a double-precision one of K (None: K is
    factorized here, or, where the last Newton step reused a factorization,
    its lowest eigenvalue by LOBPCG decides where its residual gives the sign)."""
    if K.shape[0] == 0:
        return None
    negative = inertia
    mode = opts.stability
    history.modes = None
    decided = False             # the sign of K's lowest eigenvalue is known without its inertia
    if (negative is None and mode != "off" and lin.direct and not lin.solver.single
            and lin.solver.K is not K and lin.may_reuse(opts, K.shape[0])):
        # K is not factorized (the last Newton step reused an earlier
        # factorization) where factorizations are reused: LOBPCG
        # preconditioned by the last one finds the lowest eigenvalue (the
        # 100k leaf: a few seconds against a factorization of 22 s) and
        # decides where its residual gives its sign: positive, stable;
        # negative, the lowest eigenpairs below; open, a factorization
        w, _, res = lowest_eigenpairs(lin, K, 1, until_sign=True)
        decided = abs(w[0]) > res[0]
        if decided:
            history.notes.append(f"t={t:.4g}: stability from the lowest eigenvalue (LOBPCG "
                                 "preconditioned by the factorization of an earlier Hessian)")
            if w[0] > 0:
                negative = 0
                history.lowest_eigenvalues = [float(w[0])]
        else:
            history.notes.append(f"t={t:.4g}: LOBPCG left the sign of the lowest eigenvalue open "
                                 f"({w[0]:.3e}, residual {res[0]:.3e}); inertia from a factorization")
    if negative is None and not decided:
        negative, _ = lin.factorize(K, exact_inertia=True)   # inertia (direct); AMG: preconditioner set-up
    if mode == "auto":
        mode = "inertia" if lin.direct else "off"
    if mode == "off":
        history.stable, history.unstable_modes = None, None
        return None
    vec = None
    if mode == "eigen" or negative is None or negative:
        count = 3 if negative is None else max(negative, 1) + 1
        w, V, res = lowest_eigenpairs(lin, K, min(count, 12))
        if negative is None and abs(w[0]) <= res[0]:
            history.notes.append(f"t={t:.4g}: the sign of the lowest eigenvalue is open "
                                 f"({w[0]:.3e}, LOBPCG residual {res[0]:.3e})")
        history.lowest_eigenvalues = [float(v) for v in w]
        # pivots of exact null modes (a free rigid motion) come out with
        # either sign: count an eigenvalue as negative only above round-off
        zero = 1e-12 * max(np.abs(K.diagonal()).max(), 1e-300)
        really = int(np.count_nonzero(w < -zero))
        if negative is None or really < min(count, 12):
            negative = really
        if negative and w[0] < -zero:
            vec = V[:, 0]
            history.modes = V[:, w < -zero]
    history.stable = negative == 0
    history.unstable_modes = negative
    return vec


def escape_along(problem, mode, t, opts, history):
    """Leave an unstable equilibrium along ``mode``: the amplitude (a
    fraction of the problem size, both signs tried) is halved until the
    energy decreases.  Returns True when a lower-energy state was found."""
    x = problem.free_state()
    E, _, _ = problem.evaluate(x, 0)
    v = mode / max(np.abs(mode).max(), 1e-300)
    amp = 1e-2 * problem.size_scale()
    saved = problem.save_point()
    while amp > 1e-9 * problem.size_scale():
        best = None
        for sign in (1.0, -1.0):
            try:
                En, _, _ = problem.evaluate(x + sign * amp * v, 0)
            except EvaluationError:
                problem.restore_point(saved)
                continue
            if En < E - 1e-12 * max(problem.energy_magnitude(), abs(E)) and (best is None or En < best[0]):
                best = (En, sign)
        if best is not None:
            problem.set_free_state(x + best[1] * amp * v)
            history.escapes.append(dict(t=float(t), negative=history.unstable_modes,
                                        eigenvalue=(history.lowest_eigenvalues or [None])[0],
                                        amplitude=float(amp), energy_drop=float(E - best[0])))
            if opts.verbose:
                print(f"    t={t:.4f}: unstable equilibrium ({history.unstable_modes} negative "
                      f"eigenvalues): perturbed along the lowest mode (amplitude {amp:.2e})", flush=True)
            return True
        amp *= 0.5
    problem.restore_point(saved)
    return False


def equilibrium(problem, t, opts, history, g_ref, lin, may_cut=False, accept=None):
    """Minimize at t; assess stability; leave unstable states (opts.escape)."""
    for _ in range(opts.max_escapes + 1):
        found = minimize(problem, t, opts, history, g_ref, lin, may_cut, accept)
        if found is None:
            return False
        K, inertia = found
        mode = assess_stability(problem, K, opts, history, lin, t, inertia=inertia)
        if mode is None or not opts.escape:
            return True
        if not escape_along(problem, mode, t, opts, history):
            history.notes.append(f"t={t:.4g}: unstable equilibrium, no lower state found along its mode")
            return True
    history.notes.append(f"t={t:.4g}: still unstable after {opts.max_escapes} escapes")
    return True


# --------------------------------------------------------------- continuation
def solver_options(steps=1, min_dt=1e-4, verbose=True, **options):
    """The SolverOptions of a solve (Solvable.solve), every option checked,
    and its steps and min_dt."""
    known = {f.name for f in fields(SolverOptions)} - {"verbose"}
    unknown = sorted(set(options) - known)
    if unknown:
        raise TypeError(f"solve() got unknown option(s) {', '.join(unknown)}; "
                        f"the options are {', '.join(sorted(known))}")
    checked_int("steps", steps, 1)
    checked_float("min_dt", min_dt, 0, 1)
    return SolverOptions(verbose=verbose, **options)


class _Counted:
    """The problem, with its evaluations counted by mode in the history."""

    def __init__(self, problem, history):
        self._problem, self._history = problem, history

    def __getattr__(self, name):
        return getattr(self._problem, name)

    def evaluate(self, x, mode):
        self._history.evaluations[mode] += 1
        return self._problem.evaluate(x, mode)

    def set_parameter(self, t):
        """The problem at t; where the scene is not defined there (growth
        that inverts or is not finite, ...) a SolveError that keeps the last
        converged state, the parameter set back to its t."""
        try:
            self._problem.set_parameter(t)
        except ValueError as exc:
            done = [s for s, ok in self._history.steps if ok]
            last = done[-1] if done else None
            if last is not None:
                self._problem.set_parameter(last)
            raise SolveError(f"the scene is not defined at t = {t:.6g}: {exc}"
                             + ("" if last is None else f"; the last converged state (t = {last:.6g}) is kept"),
                             last_t=last, history=self._history) from exc


def continuation(problem, steps=1, opts=None, min_dt=1e-4, t_start=0.0, force_scale=0.0):
    """Follow the equilibrium from t_start to 1: adaptive steps in t
    (opts.path == "load") or arc length (opts.path == "arclength").
    force_scale: the gradient norm the relative tolerance opts.rtol refers
    to, at least (besides the loads and the gradient where each step
    starts): for a start carried over from another mesh, that of the
    reference state (its own gradient is already small)."""
    from threadpoolctl import ThreadpoolController
    opts = opts or SolverOptions()
    history = SolveHistory()
    problem = _Counted(problem, history)
    lin = _Linear(problem, opts, history)
    # OpenBLAS (NumPy's, SciPy's) on one thread while solving: its idle
    # worker threads busy-wait about 0.1 s after every call (OpenBLAS's
    # THREAD_TIMEOUT), taking a core from the assembly's threads and
    # PARDISO's that run next (Sze cantilever, 5,120 triangles: a PARDISO
    # factorization 93 ms inside the solve against 42 ms alone; the solve
    # 20 -> 15 s); the solver's dense algebra is vectors and thin blocks
    try:
        with ThreadpoolController().select(internal_api="openblas").limit(limits=1):
            return _follow_path(problem, steps, opts, history, lin, min_dt, t_start, force_scale)
    finally:
        lin.release()


def _follow_path(problem, steps, opts, history, lin, min_dt, t_start, force_scale):
    t = t_start
    problem.set_parameter(t)
    g_ref = max(problem.load_scale(), force_scale)
    try:
        found = equilibrium(problem, t, opts, history, g_ref, lin)
    except LinearSolverError as exc:
        raise SolveError(_linear_failure(exc, t, lin), last_t=None, history=history) from exc
    if not found:
        raise SolveError(f"no equilibrium at the start t={t}", last_t=None, history=history)
    history.steps.append((t, True))
    if opts.path == "arclength":
        return _arclength(problem, steps, opts, history, lin, g_ref, t, min_dt)
    max_dt = opts.max_dt or 1.0
    dt = min((1.0 - t_start) / max(1, steps), max_dt)
    first_dt = dt
    prev = None          # _PathPoint: the previous converged point
    here = None          # _PathPoint: the current one (its tangent computed once)
    failed_here = False  # a step from the current point failed: the retries use the secant
    while t < 1.0 - 1e-14:
        dt = min(dt, 1.0 - t)
        saved = problem.save_point()
        if here is None:
            # the tangent at the start serves the second step's predictor
            # only (a first step from, e.g., a flat disc is taken from the
            # start itself: there the tangent is the flat linear response)
            x_now = problem.free_state()
            wanted = opts.predictor == "tangent" and (prev is not None or t + dt < 1.0 - 1e-14)
            here = _PathPoint(t, x_now, *(_tangent(problem, lin, x_now, t) if wanted else (None, 0.0)))
        t_new = t + dt
        problem.set_parameter(t_new)
        predictor = _predict(problem, here, prev, dt, tangents=not failed_here)
        history.predictors.append(predictor)
        if opts.verbose:
            print(f"  step t = {t_new:.4f} (dt = {dt:.4f}, predictor: {predictor})", flush=True)
        n_before = len(history.iterations)
        # force scale of the step: besides the loads, the force its increment
        # of t puts on the converged state, dt |dg/dt| (known with the
        # tangent; else the gradient at the start of the step stands for it,
        # which a good predictor makes far too small)
        # (at least that of the first step: a step cut near a critical
        # point is held to the tolerance of the steps before it, not to one
        # that falls with dt below the round-off of |g|: the free 4-ring
        # disc's steps cut to dt = 1e-4 near a near-symmetry (t = 0.937)
        # asked for 1.5e-14 where |g| stalls at about 1e-12, and failed)
        g_step = max(g_ref, problem.load_scale(), max(dt, first_dt) * here.gt_norm)
        try:
            ok = equilibrium(problem, t_new, opts, history, g_step, lin, may_cut=0.5 * dt >= min_dt,
                             accept=ON_THE_WAY_RTOL * g_step if t_new < 1.0 else None)
        except LinearSolverError as exc:
            problem.restore_point(saved)
            problem.set_parameter(t)
            raise SolveError(_linear_failure(exc, t_new, lin) + f"; the last converged state "
                             f"(t = {t:.6g}) is kept", last_t=t, history=history) from exc
        history.steps.append((t_new, ok))
        if ok:
            prev, here, failed_here = here, None, False
            t = t_new
            if len(history.iterations) - n_before < 6:
                dt = min(2 * dt, 1.0 - t, max_dt)
        else:
            failed_here = True
            try:
                dt = _step_back(problem, saved, t, dt, min_dt, opts, history, "step")
            except SolveError as exc:
                _add_hint(exc, _limit_point_hint(problem, prev, here, t))
                raise
    return history


def _add_hint(exc, hint):
    """Append a likely cause ('' for none) to the message of a SolveError."""
    if hint:
        exc.args = (f"{exc}; {hint}",)


def _limit_point_hint(problem, prev, here, t):
    """A hint for a load path that failed beyond t where it turns back (a
    limit point): there |dx/dt| grows like 1/sqrt(t_c - t), so 1/|dx/dt|^2
    through the last two equilibria, extrapolated linearly, vanishes at t_c;
    given when t_c <= 1 and the tangent at t would move the shell by more
    than LIMIT_POINT_REACH times its size over the rest of the parameter
    ('' otherwise, or without both tangents)."""
    if here is None or prev is None or here.tangent is None or prev.tangent is None:
        return ""
    size = problem.size_scale()
    now, before = np.abs(here.tangent).max() / size, np.abs(prev.tangent).max() / size
    reach = now * (1.0 - t)
    if reach <= LIMIT_POINT_REACH or not now > before:
        return ""
    t_c = t + (t - prev.t) * now ** -2 / (before ** -2 - now ** -2)
    if t_c > 1.0:
        return ""
    return (f"the path turns back near t = {t_c:.4g} (a limit point: a load or pressure maximum, "
            f"a snap-through): |dx/dt| grows like 1/sqrt({t_c:.4g} - t) from t = {prev.t:.6g} to "
            f"{t:.6g}, and there it would move the shell by {reach:.3g} times its size over the rest "
            f"of the load; path=\"arclength\" follows the path through it")


def _linear_failure(exc, t, lin):
    """The message of a linear solve that failed at t (SolveError)."""
    hint = ("; the shell has free rigid motions (no supports): remove_rigid_motions() (scene "
            "files: supports = \"rigid\") removes them exactly" if lin.rigid is not None else "")
    return f"t = {t:.6g}: the linear solver failed ({exc}){hint}"


class _PathPoint(NamedTuple):
    """A converged point of the load path."""
    t: float
    x: np.ndarray               # free DOFs
    tangent: object             # dx/dt (None: not known)
    gt_norm: float              # |dg/dt| (0: not known)


def _tangent(problem, lin, x, t):
    """(dx/dt, |dg/dt|) along the path at the converged state x (K dx/dt =
    -dg/dt, the implicit function theorem on g(x, t) = 0) with the
    factorization of K at x (left by the stability assessment, or by the
    arc-length step); dx/dt is None without one (AMG) or where K is
    singular.  |dg/dt| is known either way: it scales the tolerance of the
    next step (without it, with AMG, a growth scene's tolerance was relative
    to the gradient at the predicted state, 1e-15 and below on a disc)."""
    gt = _parameter_derivative(problem, x, t)
    gt_norm = float(np.linalg.norm(gt))
    if not lin.direct:
        return None, gt_norm
    try:
        d = lin.solver.solve(-gt)
    except LinearSolverError:
        return None, gt_norm
    d = lin.project(d) if lin.project is not None else d
    return (d if np.all(np.isfinite(d)) else None), gt_norm


def _hermite(p0, p1, dt):
    """The cubic through the _PathPoints p0, p1 and their tangents evaluated
    at p1.t + dt (error O(dt^4) on a smooth path)."""
    h = p1.t - p0.t
    s = 1.0 + dt / h
    return ((2 * s**3 - 3 * s**2 + 1) * p0.x + (s**3 - 2 * s**2 + s) * h * p0.tangent
            + (-2 * s**3 + 3 * s**2) * p1.x + (s**3 - s**2) * h * p1.tangent)


# the path between two converged points counts as smooth (a cubic through
# them and their tangents extrapolates it) where the trapezoid rule on the
# tangents reproduces the chord to this fraction (the defect is O(dt^3) on
# a smooth path: 0.003-0.01 on the Sze cantilever and the leaf after it has
# buckled; 0.62 for the leaf's first step of four, through its buckling,
# where the Hermite start led into a saddle and a failed step: 76 instead of
# 33 Newton iterations)
SMOOTH_DEFECT = 0.1


def _smooth_between(p0, p1):
    """The chord between the _PathPoints p0, p1 agrees with the trapezoid
    rule on their tangents to SMOOTH_DEFECT."""
    chord = p1.x - p0.x
    defect = chord - 0.5 * (p1.t - p0.t) * (p0.tangent + p1.tangent)
    return np.linalg.norm(defect) <= SMOOTH_DEFECT * np.linalg.norm(chord)


def _predict(problem, here, prev, dt, tangents=True):
    """Set the start of the Newton iterations at t + dt (the parameter is
    set already) and name it.  The first step starts from the start state
    (whose tangent, e.g. the flat linear response of a growing disc, leads
    into a saddle: the 6-ring leaf took 30 instead of 14 Newton iterations
    from it); later steps from the cubic Hermite extrapolation through the
    last two converged points and their tangents where the path between
    them is smooth (_smooth_between), else from the tangent alone (Euler:
    the step crossed a bifurcation, or the previous point has no tangent);
    without tangents (AMG, predictor="secant", or ``tangents=False``: a
    step from this point has failed, as near a limit point, where K is
    nearly singular and the tangent wild) from the secant through the two
    points.  Measured on the Sze cantilever, 10 steps: 61 Newton iterations
    with the secant, 42 with Hermite."""
    if prev is None:
        problem.set_free_state(here.x)
        return "current state"
    if tangents and here.tangent is not None:
        if prev.tangent is not None and _smooth_between(prev, here):
            problem.set_free_state(_hermite(prev, here, dt))
            return "Hermite"
        problem.set_free_state(here.x + dt * here.tangent)
        return "tangent"
    problem.set_free_state(here.x + (dt / (here.t - prev.t)) * (here.x - prev.x))
    return "secant"


def _step_back(problem, saved, t, step, min_step, opts, history, what):
    """Back to the last converged state after a failed step; the halved step
    (SolveError when it falls below min_step)."""
    problem.restore_point(saved)
    problem.set_parameter(t)
    step *= 0.5
    if opts.verbose:
        print(f"  {what} failed: back to t = {t:.4f}, {what} -> {step:.4g}")
    if step < min_step:
        raise SolveError(f"continuation failed beyond t = {t:.6f} ({what} below {min_step}); "
                         "the last converged state is kept", last_t=t, history=history)
    return step


def _parameter_derivative(problem, x, t, delta=1e-6):
    """dg/dt at fixed free DOFs x: the problem's exact one where it has
    it (problem.parameter_derivative, e.g. a shell loaded by nodal forces
    only: two gradient evaluations saved per load step, 10 % of the Sze
    cantilever's solve), else by central differences in t (loads, growth
    and prescribed motions all depend on t)."""
    exact = getattr(problem, "parameter_derivative", None)
    gt = exact(x, t) if exact is not None else None
    if gt is not None:
        return gt
    saved = problem.save_point()
    problem.set_parameter(t + delta)
    _, gp, _ = problem.evaluate(x, 1)
    problem.set_parameter(t - delta)
    _, gm, _ = problem.evaluate(x, 1)
    problem.restore_point(saved)
    problem.set_parameter(t)
    return (gp - gm) / (2 * delta)


ARC_MAX_TURN = 0.8     # arc length: smallest cosine between the tangents and chord of a step


def _arclength(problem, steps, opts, history, lin, g_ref, t, min_ds):
    """Pseudo-arc-length continuation (Riks 1979: corrector in the plane
    normal to the tangent) in (x, t) with the metric |dx|^2 / (n L^2) + dt^2
    (n free DOFs, L the problem size: the root mean square relative motion,
    independent of the mesh); bordered systems by two solves with one
    factorization per corrector iteration.  Passes limit points of t; ends at
    t = 1 by a Newton solve at fixed t from the secant between the path points
    around it, or where ``opts.stop`` says.  Equilibria on the way may be
    unstable (their inertia is recorded).  A step is redone with half the
    length when its corrector fails or leaves the neighbourhood of the
    predictor, the inertia changes by more than one, the path turns over
    the step (tangents at its ends and the chord differ by more than
    ARC_MAX_TURN: a jump across a fold or to another branch), or the parity
    of the inertia changes without t turning back (or t turns back without
    it); at the smallest step what the corrector finds is accepted (a
    bifurcation point)."""
    L2 = problem.size_scale() ** 2 * max(len(problem.free_state()), 1)
    ds = opts.arc_ds or 1.0 / max(1, steps)
    ds_max = opts.arc_max_ds or 4 * ds
    x = problem.free_state()
    E, _, K = problem.evaluate(x, 2)
    # (no solver yet: the start needed no Newton step; none is built for nothing)
    amg = (not lin.direct if lin.solver is not None
           else resolve_method(opts.linear, len(x), hasattr(problem, "block_layout")) == "amg")
    if not amg:
        negative, _ = lin.factorize(K)
    else:
        # the corrector's bordered solves and the inertia that tells limit
        # from bifurcation points need a factorization: AMG (chosen, or by
        # "auto" on a large mesh) gives way to the direct solver where its
        # factors fit, else the path cannot be followed
        if len(x) > AUTO_DIRECT_MAX_DOFS:
            raise SolveError(f"arc length needs a direct linear solver, and {len(x)} free DOFs are "
                             f"more than one takes here (AUTO_DIRECT_MAX_DOFS = {AUTO_DIRECT_MAX_DOFS}); "
                             "use path='load'", last_t=t, history=history)
        negative, _ = lin.fall_back_to_direct(K, "arc length needs a factorization (bordered "
                                                 "solves, inertia)")
    del K

    def tangent(x, t, previous, negative):
        """Unit tangent at a converged, factorized point (K dx = -dg/dt dt),
        oriented along the travel; with its force scale |dg/dt|."""
        dx, gt_norm = _tangent(problem, lin, x, t)
        if dx is None:
            raise SolveError(f"arc length: no tangent at t = {t:.6g} (singular Hessian)",
                             last_t=t, history=history)
        norm = np.sqrt(dx @ dx / L2 + 1.0)
        tau = (dx / norm, 1.0 / norm, negative)
        if previous is not None:
            # continuity with the last tangent; past a sharp limit point (the
            # inertia changes parity: det K and with it dt change sign) the
            # determinant decides
            cos = tau[0] @ previous[0] / L2 + tau[1] * previous[1]
            flip = cos < 0
            if (negative - previous[2]) % 2 and abs(cos) < 0.9:
                flip = previous[1] > 0
            if flip:
                tau = (-tau[0], -tau[1], negative)
        return tau, gt_norm

    tau, gt_norm = tangent(x, t, None, negative)
    for _ in range(opts.arc_max_steps):
        _record_path(problem, history, t, E, negative)
        reason = opts.stop(history.path[-1]) if opts.stop is not None else None
        if reason:
            history.notes.append(f"arc length stopped at t = {t:.6g}: {reason}")
            history.stable, history.unstable_modes = negative == 0, negative
            return history
        if opts.verbose and len(history.path) > 1:
            print(f"  arc t = {t:.5f} (ds = {ds:.4g}, {negative} negative eigenvalues)", flush=True)
        # force scale of the path: the loads, or what the parameter does to the
        # gradient (prescribed motions: no loads at all)
        g_scale = max(g_ref, problem.load_scale(), gt_norm)
        while True:
            saved = problem.save_point()
            ok, xn, tn, its = _riks_corrector(problem, x, t, tau[0], tau[1], ds, L2, opts, history,
                                              lin, g_scale)
            smallest = ds <= 4 * min_ds        # accept what the corrector finds
            if ok:
                En, _, Kn = problem.evaluate(xn, 2)
                neg_new, _ = lin.factorize(Kn)
                del Kn
                ok = neg_new is not None and (abs(neg_new - negative) <= 1 or smallest)
            if ok:
                # the path turns little over the step: the tangents at both
                # ends and the secant between them agree (else the step has
                # jumped across a fold or to another branch)
                tau_new, gt_new = tangent(xn, tn, tau, neg_new)
                dx, dt = xn - x, tn - t
                chord = np.sqrt(dx @ dx / L2 + dt * dt)
                turns = [tau_new[0] @ tau[0] / L2 + tau_new[1] * tau[1],
                         (dx @ tau[0] / L2 + dt * tau[1]) / chord,
                         (dx @ tau_new[0] / L2 + dt * tau_new[1]) / chord]
                # a change of the inertia's parity (det K changes sign) on a
                # regular path is a limit point: t turns back; otherwise the
                # step crossed a bifurcation or jumped to another branch
                parity = (neg_new - negative) % 2 == 1
                turned = tau_new[1] * tau[1] < 0
                ok = (min(turns) >= ARC_MAX_TURN and parity == turned) or smallest
            if ok:
                break
            ds = _step_back(problem, saved, t, ds, min_ds, opts, history, "arc step")
        if tn >= 1.0 and t < 1.0:
            # the path crosses t = 1: Newton at t = 1 from the secant point
            s = (1.0 - t) / (tn - t)
            problem.set_parameter(1.0)
            problem.set_free_state(x + s * (xn - x))
            # (to the path's force scale, as the corrector: without |dg/dt|
            # a growth path asked 9e-16 here: the centre-clamped 3-ring disc failed)
            if not equilibrium(problem, 1.0, opts, history, g_scale, lin):
                raise SolveError("arc length: no equilibrium at t = 1 near the path", last_t=t,
                                 history=history)
            history.steps.append((1.0, True))
            E, _, _ = problem.evaluate(problem.free_state(), 0)
            _record_path(problem, history, 1.0, E, history.unstable_modes)
            return history
        x, t, E, negative, tau, gt_norm = xn, tn, En, neg_new, tau_new, gt_new
        history.steps.append((t, True))
        ds = min(ds * 1.5, ds_max) if its <= 4 else (ds * 0.7 if its > 8 else ds)
    _record_path(problem, history, t, E, negative)
    raise SolveError(f"arc length: t = 1 not reached in {opts.arc_max_steps} steps (t = {t:.6f})",
                     last_t=t, history=history)


def _riks_corrector(problem, x0, t0, tau_x, tau_t, ds, L2, opts, history, lin, g_scale):
    """Newton on g(x, t) = 0 and the plane (x - xp).tau_x / L^2 + (t - tp) tau_t = 0
    through the predictor (xp, tp) = (x0, t0) + ds tau; converged at
    |g| <= rtol g_scale or when the correction is at round-off."""
    size = np.sqrt(L2)
    last = np.inf
    x = x0 + ds * tau_x
    t = t0 + ds * tau_t
    for it in range(opts.max_iter):
        tic = time.perf_counter()
        try:
            problem.set_parameter(t)
        except SolveError as exc:          # not defined at t: a smaller arc step (as inadmissible)
            history.notes.append(f"arc length corrector: {exc}")
            return False, x, t, it
        problem.set_free_state(x)
        try:
            E, g, K = problem.evaluate(x, 2)
        except EvaluationError:
            return False, x, t, it
        gnorm = np.linalg.norm(g)
        c = (x - x0) @ tau_x / L2 + (t - t0) * tau_t - ds
        # the corrector stays near the predictor (else it has jumped to
        # another branch crossing the plane: a smaller step is needed)
        far = np.sqrt((x - x0) @ (x - x0) / L2 + (t - t0) ** 2) > 3.0 * ds
        if far:
            return False, x, t, it
        if (gnorm <= opts.rtol * g_scale or last <= opts.xtol * size) and abs(c) <= 1e-10 * ds:
            return True, x, t, it
        negative, setup = lin.factorize(K)
        gt = _parameter_derivative(problem, x, t)
        a = lin.solver.solve(-g)
        b = lin.solver.solve(-gt)
        dt = -(c + tau_x @ a / L2) / (tau_x @ b / L2 + tau_t)
        x = x + a + dt * b
        t = t + dt
        last = max(np.abs(a + dt * b).max(), abs(dt) * size)
        history.iterations.append(Iteration(t, it, E, gnorm, float(np.abs(a + dt * b).max()), np.nan,
                                            True, negative, 1, "bordered", lin.solver.name, setup,
                                            0.0, time.perf_counter() - tic))
        if not (np.all(np.isfinite(x)) and np.isfinite(t)):
            return False, x0, t0, it
    return False, x, t, opts.max_iter


def _record_path(problem, history, t, E, negative):
    """A path point at the current state (t, energy, inertia, monitored values)."""
    point = dict(t=float(t), energy=float(E), negative=negative)
    if hasattr(problem, "monitor"):
        point["monitor"] = [float(v) for v in np.ravel(problem.monitor())]
    history.path.append(point)


# solve(thickness_path=...): a thickness whose solve fails is approached
# through the geometric mean of it and the last one solved, while their
# ratio is above this
MIN_THICKNESS_RATIO = 1.1


def _checked_thickness_path(path, h):
    """solve(thickness_path=...) as a list of floats: finite, decreasing,
    each above the engine's thickness h."""
    try:
        path = [float(v) for v in np.atleast_1d(np.asarray(path, dtype=float))]
    except (TypeError, ValueError):
        raise ValueError(f"thickness_path must be a sequence of thicknesses, got {path!r}") from None
    if not path:
        raise ValueError("thickness_path is empty")
    for k, v in enumerate(path):
        if not np.isfinite(v) or v <= h:
            raise ValueError(f"thickness_path[{k}] = {v!r}: each thickness must be finite and "
                             f"larger than the shell's own, {h:g}")
        if k and v >= path[k - 1]:
            raise ValueError(f"thickness_path[{k}] = {v!r}: the thicknesses must decrease "
                             f"(previous {path[k - 1]:g})")
    return path


class Solvable:
    """The ``solve`` method shared by the engines.  An engine implements the
    problem protocol above and ``_setup()``, ``_describe()`` (one line) and
    ``_result(history, wall_s, converged, t)``."""

    def solve(self, steps=1, verbose=True, min_dt=1e-4, monitor=None, start=None,
              thickness_path=None, **options):
        """Equilibrium at t = 1 by continuation from the reference (t = 0),
        or from ``start``.

        steps: initial number of continuation steps (adapted: halved on
        failure or when Newton creeps, SLOW_NEWTON; doubled after easy
        steps; arc length: the first arc step is 1/steps); min_dt: smallest
        step before giving up; monitor: node indices whose positions are
        recorded along an arc-length path, or a callable(engine) -> numbers;
        start: a Result on another mesh of the same reference surface
        (typically coarser): its state is carried onto this mesh
        (transfer.py) and Newton starts there, at the result's t (nested
        iteration: README "Scaling"); thickness_path: larger thicknesses,
        decreasing, at which the scene is solved first (the first as asked,
        from the reference or ``start``, each next from the last
        equilibrium) before this engine's own thickness: continuation in the
        thickness, for thin shells whose buckling from the reference state
        Newton finds only slowly (README "Solver"); the stages are in
        ``result.history.thickness_stages``.  Solver options (SolverOptions, with
        their defaults and meaning): rtol (relative gradient tolerance: to
        the loads, to the gradient where a step starts and, with start, to
        the gradient of the reference state at the result's t),
        max_iter (Newton iterations per step; a step still converging
        there, |g| tenfold down over the last five, gets up to twice as
        many), linear ("auto" | "pardiso" | "superlu" | "amg", linalg.py),
        globalization ("auto" | "trust-region" | "line-search"; auto: the
        line search with a multilevel AMG hierarchy, else the trust
        region), watchdog (full Newton steps allowed uphill), path
        ("load" | "arclength": passes limit points, the path is in
        ``result.history.path`` and ``history.write_path(csv)``), stability
        ("auto" | "inertia" | "eigen" | "off"), escape (leave unstable
        equilibria along their most unstable mode), arc_max_steps, arc_ds,
        arc_max_ds (arc length: step count limit, first and largest step, in
        root mean square relative motion and t combined), stop
        (callable(path point) -> reason (str) to end an arc-length path there,
        or None), max_cg, xtol, ftol, armijo, min_alpha, max_escapes.
        Raises SolveError (with ``.result``, the last converged state) on failure.
        """
        opts = solver_options(steps, min_dt, verbose, **options)
        if thickness_path is not None:
            return self._solve_through_thicknesses(thickness_path, steps, verbose, min_dt, monitor,
                                                   start, options)
        self._setup()
        check = getattr(self, "_check_solvable", None)       # engines that can tell at once
        if check is not None:
            check()
        t_start, force_scale = (0.0, 0.0) if start is None else self._start_from(start)
        self._monitor = monitor
        if not (monitor is None or callable(monitor)):
            self._monitor = np.atleast_1d(np.asarray(monitor))
            if not np.issubdtype(self._monitor.dtype, np.integer):
                raise TypeError(f"monitor must be node indices (integers) or a callable(engine), got {monitor!r}")
            try:
                self._node_positions(self._monitor)
            except IndexError:
                raise ValueError(f"monitor: node indices outside the mesh: {monitor!r}") from None
        t0 = time.perf_counter()
        if verbose:
            print(self._describe(), flush=True)
        try:
            history = continuation(self, steps=steps, opts=opts, min_dt=min_dt, t_start=t_start,
                                   force_scale=force_scale)
        except SolveError as exc:
            exc.result = self._result(exc.history, time.perf_counter() - t0, False, exc.last_t)
            hint = getattr(self, "_failure_hint", None)       # engines that know a likely cause
            if hint is not None:
                _add_hint(exc, hint())
            raise
        if history.stable is None and opts.stability == "auto":
            warnings.warn(STABILITY_NOT_ASSESSED, StabilityWarning, stacklevel=2)
        return self._result(history, time.perf_counter() - t0, True, history.steps[-1][0])

    def _solve_through_thicknesses(self, path, steps, verbose, min_dt, monitor, start, options):
        """solve(thickness_path=path): the scene at each thickness of the
        path, then at this engine's own, each from the last equilibrium (the
        first from ``start`` or the reference, with ``steps``).  Where one
        fails, the thickness halfway (geometric mean) between it and the
        last solved one is solved first, down to a ratio of
        MIN_THICKNESS_RATIO (history note); then its SolveError is raised,
        with its result and the stages solved.  The result's
        ``history.thickness_stages`` lists the stages before the own
        thickness."""
        own_h = getattr(self, "h", 0.0)
        path = _checked_thickness_path(path, own_h) + [own_h]
        stages, notes, last_h = [], [], None
        while True:
            h = path[0]
            own = len(path) == 1
            t0 = time.perf_counter()
            if verbose:
                print(f"thickness continuation: h = {h:g}", flush=True)
            engine = self if own else self.with_thickness(h)
            try:
                result = engine.solve(steps=steps if start is None else 1, verbose=verbose,
                                      min_dt=min_dt, monitor=monitor if own else None,
                                      start=start, **options)
            except SolveError as exc:
                if last_h is not None and last_h / h > MIN_THICKNESS_RATIO:
                    between = float(np.sqrt(last_h * h))
                    notes.append(f"thickness continuation: no equilibrium at h = {h:g} from "
                                 f"h = {last_h:g} ({exc}); h = {between:g} first")
                    if verbose:
                        print("  " + notes[-1], flush=True)
                    path.insert(0, between)
                    continue
                exc.args = (f"thickness continuation, stage h = {h:g}: {exc}",)
                exc.history.thickness_stages = stages
                exc.history.notes[:0] = notes
                raise
            record = result.history
            if own:
                record.thickness_stages = stages
                record.notes[:0] = notes
                return result
            stages.append(dict(thickness=h, newton_its=len(record.iterations),
                               assemblies=record.assemblies,
                               factorizations=record.factorizations,
                               energy=float(result.energy), stable=record.stable,
                               wall_s=time.perf_counter() - t0))
            start, last_h = result, h
            path.pop(0)

    def with_thickness(self, thickness):
        """This engine at another thickness (solve(thickness_path=...))."""
        raise TypeError(f"solve(thickness_path=...) is available for the triangle engine (Shell), "
                        f"not for {type(self).__name__}")

    def _start_from(self, result):
        """Carry ``result``'s state onto this engine; returns its t and the
        force scale of the solve (continuation)."""
        raise TypeError(f"solve(start=...) is available for the triangle engine (Shell), "
                        f"not for {type(self).__name__}")

    def monitor(self):
        """The monitored values (solve(monitor=...)): positions of nodes, or
        what the callable returns."""
        m = getattr(self, "_monitor", None)
        if m is None:
            return np.zeros(0)
        return m(self) if callable(m) else self._node_positions(m)
