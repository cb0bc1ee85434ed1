"""The nonlinear solver layer (solve.py): globalizations, the watchdog,
stability and escape, AMG with its fall-back to a factorization, option
checking, the history, reproducibility.  (Linear algebra: test_linalg.py;
arc length on the snapping cap and pulled cylinder:
test_benchmark_scenes.py; necking: test_necking.py.)"""

import numpy as np
import pytest

from shellritz import NeoHookean, Shell, SolveError, StabilityWarning, StVenantKirchhoff, shapes
from shellritz.discretize.planestrain import PlaneStrainShell
from shellritz.linalg import pardiso_available
from shellritz.scenes import leaf
from shellritz.solve import ON_THE_WAY_RTOL


def dkt_leaf(*args, **kw):
    """The leaf with the DKT membrane metric, the scene file's until
    2026-12-07 (now regge, which the 16-ring leaf does not lock with): the
    solver tests counted on its path (a bifurcation in the first load step,
    trust-region rejections, fast last steps, a nearly double lowest
    eigenvalue) were built on it, and the regge leaf takes another."""
    return leaf(*args, membrane="dkt", **kw)


# --------------------------------------------------------------- cantilever
def cantilever(nx=16, ny=2):
    """Sze et al. 2004, 3.1: strip L = 10, b = 1, h = 0.1, E = 1.2e6, nu = 0,
    clamped at x = 0, end shear P = 4 (the elastica tip: w = 6.6996, u = -3.2894)."""
    mesh = shapes.rectangle(nx, ny, lx=10.0, ly=1.0)
    shell = Shell(mesh, 0.1, StVenantKirchhoff.from_young(1.2e6, 0.0), level="consistent")
    shell.clamp(mesh.nodes_on_plane("x", 0.0))
    tip = mesh.nodes_on_plane("x", 10.0)
    shell.edge_load(tip, [0.0, 0.0, 4.0])
    return shell, tip


def tip_of(result, tip):
    return result.displacement[tip].mean(axis=0)


@pytest.fixture(scope="module")
def cantilever_default():
    shell, tip = cantilever()
    return shell.solve(steps=10, verbose=False), tip


def test_watchdog_takes_full_newton_steps_uphill_and_agrees_with_the_monotone_solve(cantilever_default):
    """From the flat strip the first Newton step is the linear solution: it
    stretches the membrane (energy 97 against 0 at the start) but lands in
    the basin of the solution.  The watchdog keeps it: 33 Newton iterations
    from 10 load steps against 74 monotone (with the secant predictor 61
    against 114), the same equilibrium."""
    res, tip = cantilever_default
    h = res.history
    assert any(it.uphill for it in h.iterations)
    shell, _ = cantilever()
    mono = shell.solve(steps=10, verbose=False, watchdog=0)
    assert not any(it.uphill for it in mono.history.iterations)
    assert len(h.iterations) <= 0.75 * len(mono.history.iterations)
    np.testing.assert_allclose(tip_of(res, tip), tip_of(mono, tip), rtol=0, atol=1e-8)
    # the elastica: this 16 x 2 mesh is 0.49 % (w) and 1.06 % (u) short of it
    # (64 x 10: 5e-5, bench/peers.py)
    u = tip_of(res, tip)
    assert 0 < 1 - u[2] / 6.6996 < 6e-3 and 0 < 1 - u[0] / -3.2894 < 1.2e-2


def test_tangent_predictor_saves_newton_iterations_on_the_same_path(cantilever_default):
    """Each load step after the first starts from the cubic Hermite
    extrapolation through the last two equilibria and their tangents
    dx/dt = -K^-1 dg/dt.  The protocol's 10 equal steps (max_dt = 0.1):
    42 Newton iterations against 61 from the secant (5 -> 3 per step at
    the end of the path), the same equilibrium; the adaptive default, whose
    steps double after easy ones, 33 in 6 steps."""
    res, tip = cantilever_default
    runs = {}
    for predictor in ("tangent", "secant"):
        shell, _ = cantilever()
        runs[predictor] = shell.solve(steps=10, verbose=False, max_dt=0.1, predictor=predictor)
    steps = {k: [t for t, ok in r.history.steps[1:] if ok] for k, r in runs.items()}
    assert steps["tangent"] == pytest.approx(np.linspace(0.1, 1.0, 10)) and steps["secant"] == steps["tangent"]
    its = {k: len(r.history.iterations) for k, r in runs.items()}
    assert its["tangent"] <= 0.75 * its["secant"]
    # the tangents are right: |g| at the predicted start of steps 4-10 is
    # 700-7,700 times below the secant's (observed 2e-2 ... 1e-3 against 65 ... 1.1)
    start = {k: np.array([it.grad_norm for it in r.history.iterations if it.it == 0]) for k, r in runs.items()}
    assert np.all(start["tangent"][3:] <= 1e-2 * start["secant"][3:])
    assert len(res.history.iterations) < its["tangent"]
    assert len([1 for _, ok in res.history.steps[1:] if ok]) < 10
    for r in (*runs.values(), res):
        np.testing.assert_allclose(tip_of(r, tip), tip_of(runs["secant"], tip), rtol=0, atol=1e-8)


def test_parameter_derivative_is_exact_for_nodal_loads_and_numerical_otherwise():
    """dg/dt (the tangent's right-hand side) from the shell where only nodal
    forces depend on t: -f on the positions, equal to the central difference
    of the gradient in t (which it replaces: two gradient evaluations per
    load step); None (central differences) where the element energies
    depend on t: growth, prescribed motions, face loads, pressure."""
    from shellritz.solve import _parameter_derivative
    shell, _ = cantilever()
    shell._setup()
    rng = np.random.default_rng(3)
    x = shell.free_state() + 1e-2 * rng.standard_normal(len(shell.free))
    shell.set_parameter(0.4)
    exact = shell.parameter_derivative(x, 0.4)
    assert exact is not None and np.count_nonzero(exact) == np.count_nonzero(shell._f_nodes)
    shell.parameter_derivative = lambda x, t: None          # the numerical path
    numerical = _parameter_derivative(shell, x, 0.4)
    np.testing.assert_allclose(exact, numerical, rtol=0, atol=1e-6 * np.abs(exact).max())
    for change in (lambda s: s.set_growth(G0=np.diag([1.1, 1.0, 1.0])),
                   lambda s: s.clamp(s.mesh.nodes_on_plane("x", 10.0), rotation=[0.0, 0.1, 0.0]),
                   lambda s: s.face_tractions(q_plus=[0.0, 0.0, 1.0]),
                   lambda s: s.pressure(1.0)):
        shell, _ = cantilever()
        change(shell)
        shell._setup()
        shell.set_parameter(0.4)
        assert shell.parameter_derivative(shell.free_state(), 0.4) is None


def test_predictor_takes_the_tangent_alone_after_a_bifurcation(tmp_path):
    """The leaf in four load steps buckles within the first: the cubic
    through the flat start and the buckled state at t = 0.25 (its trapezoid
    defect 0.62, SMOOTH_DEFECT 0.1) led into a saddle and a failed step (76
    Newton iterations); the next step starts from the tangent alone, the
    later ones from the cubic again, no failed step, the same stable
    equilibrium as from the secant.  Which of the two takes fewer Newton
    iterations on one leaf can be decided by round-off there, so four leaves
    are counted together: the 6-ring leaf with the growth coefficient 0.3
    changed by 0, 1e-12, -1e-12, 3e-12 of itself, tangent 38 / 37 / 38 / 38
    against secant 42 / 42 / 44 / 44 Newton iterations, 151 against 172 (a
    Hessian product of other round-off, tried: 47 / 39 / 40 / 38 against
    43 / 44 / 44 / 39, 164 against 170; the unchanged leaf on a machine of
    other round-off 33 against 39).  (On this machine the first step had
    been cut six times, to dt = 1/256, by the slow-Newton test judging the run by its last |g|, 77-fold
    down, where it had been 156-fold down two steps before: now the run's
    lowest |g| counts, solve.SLOW_NEWTON.)"""
    from importlib.resources import files
    from shellritz.meshdata import Surface
    from shellritz.scenefile import load_scene
    text = (files("shellritz.meshes") / "leaf.toml").read_text()
    assert 'membrane = "regge"' in text
    text = text.replace('membrane = "regge"', 'membrane = "dkt"')          # as dkt_leaf
    total = {"tangent": 0, "secant": 0}
    for coefficient in ("0.3", "0.3000000000003", "0.2999999999997", "0.3000000000009"):
        path = tmp_path / f"leaf_{coefficient}.toml"
        path.write_text(text.replace("0.3*", coefficient + "*"))
        scene = load_scene(path)
        runs = {p: scene.build(Surface(shapes.disc(6)))[0].solve(steps=4, verbose=False, predictor=p)
                for p in ("tangent", "secant")}
        h = runs["tangent"].history
        assert h.predictors == ["current state", "tangent", "Hermite", "Hermite"]
        assert runs["secant"].history.predictors == ["current state", "secant", "secant", "secant"]
        assert all(ok for _, ok in h.steps)
        assert runs["tangent"].energy == pytest.approx(runs["secant"].energy, rel=1e-10)
        assert h.stable and runs["secant"].history.stable
        for p, r in runs.items():
            total[p] += len(r.history.iterations)
    assert total["tangent"] < total["secant"]


def test_line_search_reaches_the_same_equilibrium(cantilever_default):
    res, tip = cantilever_default
    shell, _ = cantilever()
    ls = shell.solve(steps=10, verbose=False, globalization="line-search")
    np.testing.assert_allclose(tip_of(ls, tip), tip_of(res, tip), rtol=0, atol=1e-8)
    assert np.all(np.isnan([it.radius for it in ls.history.iterations]))      # no trust region


def test_history_records_the_linear_solves(cantilever_default):
    res, _ = cantilever_default
    h = res.history
    assert h.linear in ("pardiso", "superlu")
    its = h.iterations
    assert all(it.linear == h.linear and it.setup_s >= 0 and it.solve_s >= 0 and it.seconds > 0
               for it in its)
    assert all(it.krylov_its >= 1 for it in its)
    # one factorization per Newton iteration, plus the stability checks
    assert len(its) <= h.factorizations <= len(its) + len(h.steps) + 1
    assert h.stable is True and h.unstable_modes == 0


def test_reruns_are_bitwise_identical(cantilever_default):
    """No decision depends on timings: the same solve gives the same bits."""
    res, _ = cantilever_default
    shell, _ = cantilever()
    again = shell.solve(steps=10, verbose=False)
    assert np.array_equal(again.r, res.r)
    assert len(again.history.iterations) == len(res.history.iterations)


@pytest.mark.skipif(not pardiso_available(), reason="pypardiso not installed")
def test_direct_methods_take_the_same_newton_path():
    """Every Newton step factorizes its Hessian, whichever direct method:
    PARDISO and SuperLU take the same steps through the buckling of the
    leaf (14 Newton iterations at 6 rings, indefinite Hessians on the way)
    and reach the same equilibrium.  (A rule that reused a factorization
    while CG with it looked cheaper made SuperLU's steps inexact: 29 instead
    of 18 Newton iterations on the 16-ring leaf.)"""
    runs = [leaf(6).solve(verbose=False, linear=m) for m in ("pardiso", "superlu")]
    hp, hs = (r.history for r in runs)
    assert any(it.negative for it in hp.iterations)            # it does cross indefinite Hessians
    assert len(hp.iterations) == len(hs.iterations)
    assert hp.factorizations == hs.factorizations
    assert [it.accepted for it in hp.iterations] == [it.accepted for it in hs.iterations]
    assert abs(runs[0].energy - runs[1].energy) <= 1e-10 * abs(runs[0].energy)
    assert np.abs(runs[0].r - runs[1].r).max() <= 1e-8


def test_trust_region_does_not_expand_right_after_a_rejection():
    """On the buckling leaf the model holds up to a radius r and fails at 2r
    (a rejection, then the step at r read off the same CG path is excellent,
    ratio ~1).  Doubling again at once repeated the rejection: the radius
    stays after a step read off the path of a rejected one.  16-ring leaf:
    17 Newton iterations with 3 rejected (18 with 4 before; 12k triangles:
    18 with 3 against 20 with 5, bench/scaling.py).  (Without the path, e.g.
    with AMG, a fresh step may expand: holding the radius there doubled the
    thin panel's iterations in the stability map, 352 -> 775.)"""
    h = dkt_leaf(16).solve(verbose=False).history
    its = h.iterations
    after = [(a, b) for a, b in zip(its, its[1:]) if not a.accepted and b.accepted and np.isfinite(b.radius)]
    assert after                                              # the situation does arise
    assert all(b.radius <= a.radius for a, b in after)
    assert sum(not it.accepted for it in its) <= 3 and len(its) <= 17
    assert h.stable


def test_slow_newton_on_a_too_large_load_step_cuts_the_step_early(monkeypatch):
    """Very thin clamped panel (h/R = 1e-3) loaded in one step: after the
    first full Newton steps the Hessian is positive definite and the Newton
    steps are good (ratio ~1) but short, creeping along the curved
    inextensional valley, so |g| does not fall; 40 such iterations were spent
    before each cut of the load step.  Giving up after SLOW_NEWTON = 10 of
    them: 12 x 12 panel 84 instead of 165 Newton iterations (16 x 16, the
    stability map: 129 instead of 237), the same equilibrium."""
    from shellritz import solve as solve_module
    from shellritz.benchmark_scenes import thin_panel
    early = thin_panel(12).solve(verbose=False)
    monkeypatch.setattr(solve_module, "SLOW_NEWTON", 10 ** 9)
    late = thin_panel(12).solve(verbose=False)
    assert sum(not ok for _, ok in early.history.steps) >= 1     # the step is cut
    assert len(early.history.iterations) <= 0.6 * len(late.history.iterations)
    assert early.energy == pytest.approx(late.energy, rel=1e-10)
    assert early.history.stable and late.history.stable


def test_fast_newton_steps_reuse_the_previous_factorization(monkeypatch):
    """Once a full Newton step on a positive definite Hessian cuts |g|
    tenfold, the next step is solved by CG preconditioned by the previous
    factorization (reuse_factorization="always"; "auto" does so from
    REUSE_MIN_DOFS = 150k free DOFs on, large meshes), as an inexact
    Newton step; the Hessian of the equilibrium, not factorized then, is
    assessed by LOBPCG preconditioned by the last factorization instead of a
    factorization of its own.
    16-ring leaf: the last two Newton steps reuse it (8 CG iterations each),
    15 -> 13 factorizations (the stability inertia's is the second),
    67 -> 81 CG iterations, the same 17 Newton iterations and the same
    equilibrium (energy to 2e-14); its lowest eigenvalue by LOBPCG
    (4.2533e-9, residual about 1e-14) is that of the run with a factorization
    at the equilibrium (stability="eigen": 4.261e-9, 4.269e-9; a nearly
    double pair) to 2e-3.
    (Without the predicted last step, which saves one factorization of its
    own where the factorizations are not reused.)"""
    from shellritz import solve as solve_module
    monkeypatch.setattr(solve_module, "CONVERGED_MARGIN", 0.0)
    never = dkt_leaf(16).solve(verbose=False, reuse_factorization="never", stability="eigen").history
    always = dkt_leaf(16).solve(verbose=False, reuse_factorization="always").history
    reused = [it for it in always.iterations if it.negative is None]
    assert len(reused) >= 2 and all(it.krylov_exit == "converged" for it in reused)
    assert always.factorizations <= never.factorizations - 2
    assert len(always.iterations) == len(never.iterations)
    assert always.iterations[-1].energy == pytest.approx(never.iterations[-1].energy, rel=1e-12)
    assert always.stable and never.stable and not never.notes
    assert always.notes == ["t=1: stability from the lowest eigenvalue (LOBPCG preconditioned by "
                            "the factorization of an earlier Hessian)"]
    assert min(never.lowest_eigenvalues) > 0
    assert always.lowest_eigenvalues[0] == pytest.approx(never.lowest_eigenvalues[0], rel=5e-3)


def test_stability_by_lobpcg_falls_back_to_the_inertia_where_the_sign_is_open(monkeypatch):
    """The equilibrium's Hessian after a reused factorization: its lowest
    eigenvalues by LOBPCG decide only where the residual of the lowest is
    below its size (an eigenvalue of K lies within the residual of each
    Ritz value), else the inertia of a factorization.  32-ring leaf: with
    the tolerance relative to max |diag K| (EIGEN_RTOL = 1e-12) lowest
    eigenvalue 3.97e-10, residual about 1e-14, decided; with a loose
    LOBPCG (EIGEN_RTOL = 1e-3: one iteration or two) the sign is open and
    a factorization decides: one more, stable either way.  (An absolute
    1e-8 had left a residual of 4.7e-10 at 3.97e-10.)"""
    from shellritz import solve as solve_module
    monkeypatch.setattr(solve_module, "CONVERGED_MARGIN", 0.0)
    tight = dkt_leaf(32).solve(verbose=False, reuse_factorization="always").history
    monkeypatch.setattr(solve_module, "EIGEN_RTOL", 1e-3)
    loose = dkt_leaf(32).solve(verbose=False, reuse_factorization="always").history
    assert tight.notes[-1].startswith("t=1: stability from the lowest eigenvalue (LOBPCG")
    assert 3e-10 < tight.lowest_eigenvalues[0] < 5e-10
    assert loose.notes[-1].startswith("t=1: LOBPCG left the sign of the lowest eigenvalue open")
    assert loose.factorizations == tight.factorizations + 1
    assert tight.stable and loose.stable and loose.unstable_modes == 0


def test_a_failed_reuse_still_lets_the_last_newton_step_be_predicted(monkeypatch):
    """A reused factorization that fails (CG past REUSE_MAX_CG) is replaced by
    a new one, and the step is still the one after a fast step: the last
    Newton step is predicted as without reuse.  16-ring leaf with every
    reuse failing (REUSE_MAX_CG = 1): 16 Hessian assemblies and 15
    factorizations, as with reuse_factorization="never" (before the fix 17
    and 16: the failure also dropped the prediction, which on the 100k-triangle
    leaf cost a Hessian and a factorization of the finest mesh)."""
    from shellritz import solve as solve_module
    monkeypatch.setattr(solve_module, "REUSE_MAX_CG", 1)
    never = dkt_leaf(16).solve(verbose=False, reuse_factorization="never").history
    always = dkt_leaf(16).solve(verbose=False, reuse_factorization="always").history
    assert sum("reused factorization: CG maxiter" in n for n in always.notes) >= 1
    assert always.evaluations[1] >= 1                     # a predicted last step
    assert always.assemblies == never.assemblies
    assert always.factorizations == never.factorizations
    assert always.iterations[-1].energy == pytest.approx(never.iterations[-1].energy, rel=1e-12)
    assert always.stable and never.stable


def test_krylov_forcing_is_eisenstat_walker_bounded_by_the_tolerance_on_the_gradient():
    """The relative tolerance of CG in a Newton step (solve._forcing): tight
    with the current Hessian's factor; else Eisenstat-Walker choice 2,
    0.9 (|g| / |g_prev|)^2 within [1e-10, 0.1], 0.1 on the first step; with
    AMG no tighter than leaves the residual at half the tolerance tol on
    |g| (Kelley 1995, 6.3.2): the 1M default leaf's third Newton step, from
    |g| 2.1e-8 after 5.5e-6, asked 1.3e-5 of CG and had not finished at the
    run's 55-minute limit; with an earlier Hessian's factor no looser than leaves
    it at half of CONVERGED_MARGIN x tol, so that the step is the last;
    the floor only with a multilevel AMG hierarchy: with an earlier factor
    preconditioning (PARDISO's last positive definite one for an indefinite
    Hessian, one-level AMG), Eisenstat-Walker alone (the grown discs' paths
    past secondary bifurcations depend on it, test_steps_on_the_way_...; the
    stability map's thin panel with one-level AMG and the trust region took
    812 instead of 318 Newton iterations with the floor)."""
    from shellritz.solve import CONVERGED_MARGIN, _forcing
    assert _forcing("current factor", 1e-3, 1e-2, 1e-9) == 1e-10
    assert _forcing("multilevel AMG", 1e-3, None, 1e-9) == 0.1
    assert _forcing("multilevel AMG", 1e-3, 1e-2, 1e-9) == pytest.approx(9e-3, rel=1e-12)    # far: EW
    ew = 0.9 * (2.1e-8 / 5.5e-6) ** 2
    assert _forcing("multilevel AMG", 2.1e-8, 5.5e-6, 1e-13) == pytest.approx(ew, rel=1e-12)
    assert _forcing("multilevel AMG", 2.1e-8, 5.5e-6, 1e-9) == pytest.approx(0.5e-9 / 2.1e-8, rel=1e-12)
    assert _forcing("multilevel AMG", 2.1e-8, 5.5e-6, 1e-8) == 0.1                         # capped
    assert _forcing("reused factor", 2.1e-8, 5.5e-6, 1e-8) == pytest.approx(ew, rel=1e-12)
    assert _forcing("reused factor", 1e-3, 1e-2, 1e-9) == pytest.approx(
        0.5 * CONVERGED_MARGIN * 1e-9 / 1e-3, rel=1e-12)
    assert _forcing("multilevel AMG", 1.0, 1e30, 1e-30) == 1e-10
    # an earlier factor preconditioning (PARDISO's for an indefinite Hessian, one-level AMG): EW alone
    assert _forcing("earlier factor", 2.1e-8, 5.5e-6, 1e-8) == pytest.approx(ew, rel=1e-12)
    with pytest.raises(ValueError, match="multilevel AMG"):
        _forcing("amg", 2.1e-8, 5.5e-6, 1e-8)


def test_the_forcing_floor_applies_with_a_multilevel_amg_hierarchy_only(monkeypatch):
    """solve._forcing is told "multilevel AMG" in the Newton steps of a
    multilevel AMG solve (until a fall-back to the direct solver), never
    with one-level AMG or the direct solver ("auto" on the 10-ring
    leaf; the test above for the rule)."""
    import shellritz.linalg as linalg
    from shellritz import solve as solve_module
    forcing, seen = solve_module._forcing, []

    def spy(preconditioner, *args):
        seen.append(preconditioner == "multilevel AMG")
        return forcing(preconditioner, *args)

    monkeypatch.setattr(solve_module, "_forcing", spy)
    for linear, levels, expected in (("auto", None, False), ("amg", "one", False), ("amg", "several", True)):
        if levels == "several":
            monkeypatch.setattr(linalg, "AMG_ONE_LEVEL_BLOCKS", 0)
        seen.clear()
        res = leaf(10).solve(verbose=False, linear=linear)
        if linear == "amg":
            assert res.history.iterations[0].linear == "amg"
        assert seen and seen[0] == expected
        if expected:
            # multilevel AMG from the flat disc falls back to PARDISO on this
            # leaf (CG reached 300 iterations twice; README "Worse from the
            # flat disc"): from there on the steps are direct ones
            fallback = any("falling back to the direct solver" in n for n in res.history.notes)
            assert seen == sorted(seen, reverse=True) and (all(seen) or fallback)
        else:
            assert not any(seen)


def test_predicted_last_newton_step_saves_a_hessian_per_load_step(monkeypatch):
    """Where quadratic convergence puts |g| after the next full Newton step
    below CONVERGED_MARGIN x the tolerance, that state gets its gradient
    but no Hessian, and the Hessian one step before it (factorized already)
    gives the stability inertia and the tangent.  16 x 2 cantilever, the
    peers protocol (10 equal load steps, rtol 1e-9): 7 of the 10 steps end
    so (measured: 53 -> 46 Hessian assemblies and factorizations; 13 more
    gradient evaluations, 6 of them predictions that missed), the same
    Newton iterations, tip to 1e-12, stable; the 16-ring leaf (free,
    buckles; stability by inertia): one Hessian fewer, the same
    equilibrium and verdict."""
    from shellritz import solve as solve_module
    protocol = dict(steps=10, max_dt=0.1, rtol=1e-9, verbose=False)
    predicted = cantilever()[0].solve(**protocol)
    leaf_predicted = dkt_leaf(16).solve(verbose=False).history
    monkeypatch.setattr(solve_module, "CONVERGED_MARGIN", 0.0)
    shell, tip = cantilever()
    full = shell.solve(**protocol)
    leaf_full = dkt_leaf(16).solve(verbose=False).history
    hp, hf = predicted.history, full.history
    saved = hf.assemblies - hp.assemblies
    assert saved >= 6
    assert hf.factorizations - hp.factorizations == saved
    assert hp.evaluations[1] - hf.evaluations[1] >= saved
    assert all(it.grad_norm <= 1e-8 for it, nxt in zip(hp.iterations, hp.iterations[1:] + [None])
               if nxt is None or nxt.t != it.t)       # the last state of each load step
    assert len(hp.iterations) == len(hf.iterations)
    np.testing.assert_allclose(tip_of(predicted, tip), tip_of(full, tip), rtol=0, atol=1e-12)
    assert hp.stable and hf.stable
    assert leaf_full.assemblies - leaf_predicted.assemblies == 1
    assert leaf_predicted.iterations[-1].energy == pytest.approx(leaf_full.iterations[-1].energy,
                                                                  rel=1e-12)
    assert leaf_predicted.stable and leaf_full.stable
    assert leaf_predicted.unstable_modes == leaf_full.unstable_modes == 0


@pytest.mark.skipif(not pardiso_available(), reason="pypardiso not installed")
def test_single_precision_factorizations_reach_the_same_equilibrium(monkeypatch):
    """factor_precision="single": the 16-ring leaf (free rigid motions: regularized factors)
    takes the same Newton iterations to the same equilibrium (energy to
    1e-10) with more CG iterations, the stability inertia from a double
    factorization; where CG preconditioned by the single factor of a
    positive definite Hessian misses SINGLE_MAX_CG iterations (here forced
    by a limit of 1) the solver says so and goes on in double precision."""
    import shellritz.solve as solve_module
    double = leaf(16).solve(verbose=False, factor_precision="double").history
    single = leaf(16).solve(verbose=False, factor_precision="single").history
    assert any("single precision" in n for n in single.notes)
    assert len(single.iterations) == len(double.iterations)
    assert sum(i.krylov_its for i in single.iterations) > sum(i.krylov_its for i in double.iterations)
    assert single.iterations[-1].energy == pytest.approx(double.iterations[-1].energy, rel=1e-10)
    assert single.stable and double.stable
    monkeypatch.setattr(solve_module, "SINGLE_MAX_CG", 1)
    fallback = leaf(16).solve(verbose=False, factor_precision="single").history
    assert any("reached 1 iterations" in n and "double precision" in n for n in fallback.notes)
    assert fallback.iterations[-1].energy == pytest.approx(double.iterations[-1].energy, rel=1e-10)
    assert fallback.stable


@pytest.mark.parametrize("method", ["pardiso", "superlu"])
def test_a_solve_frees_its_factorizations(monkeypatch, method):
    """MKL keeps PARDISO's factors until told to free them: before this was
    done every solve of a process kept two factors (measured: +0.4 GB per
    solve of the 12k-triangle leaf, 0.34 -> 1.9 GB after four solves; now
    0.34 -> 0.54)."""
    if method == "pardiso" and not pardiso_available():
        pytest.skip("pypardiso not installed")
    import shellritz.solve as solve_module
    made, original = [], solve_module.make_linear_solver

    def recording(*args, **kw):
        made.append(original(*args, **kw))
        return made[-1]

    monkeypatch.setattr(solve_module, "make_linear_solver", recording)
    leaf(6).solve(verbose=False, linear=method)
    assert len(made) == 1
    slots = made[0]._slots
    assert all(not s.handle.analysed for s in slots) if method == "pardiso" else all(s._lu is None for s in slots)


def test_openblas_runs_on_one_thread_while_solving_and_is_restored_after(monkeypatch):
    """OpenBLAS's idle threads busy-wait about 0.1 s after each call, taking
    a core from the assembly and PARDISO (solve.continuation): during a
    solve every OpenBLAS the process has loaded runs on one thread, after it
    (converged or not) on as many as before.  MKL (PARDISO) is left alone."""
    from threadpoolctl import threadpool_info

    def threads(api):
        return [i["num_threads"] for i in threadpool_info() if i["internal_api"] == api]
    before = threads("openblas")
    if not before or max(before) < 2:
        pytest.skip("no multi-threaded OpenBLAS loaded")
    seen = []
    shell, _ = cantilever(4, 1)
    evaluate = shell.evaluate

    def spy(x, mode):
        if mode == 2:                      # Newton's (the result's own energy comes after)
            seen.append((threads("openblas"), threads("mkl")))
        return evaluate(x, mode)
    monkeypatch.setattr(shell, "evaluate", spy)
    shell.solve(steps=2, verbose=False)
    assert seen and all(o == [1] * len(before) for o, _ in seen)
    assert all(m in ([], threads("mkl")) for _, m in seen)     # MKL: loaded at the first factorization
    assert threads("openblas") == before
    with pytest.raises(SolveError):
        shell.solve(steps=1, verbose=False, max_iter=1, min_dt=0.5)
    assert threads("openblas") == before


# ------------------------------------------------------------------- AMG
def test_amg_gives_the_direct_solution_and_falls_back_when_cg_stalls(cantilever_default):
    res, tip = cantilever_default
    shell, _ = cantilever()
    amg = shell.solve(steps=10, verbose=False, linear="amg")
    np.testing.assert_allclose(tip_of(amg, tip), tip_of(res, tip), rtol=0, atol=1e-7)
    assert amg.history.linear == "amg"
    assert max(it.krylov_its for it in amg.history.iterations) > 1
    # CG limited to 2 iterations cannot converge: after two misses the
    # solver factorizes instead, says so, and still converges
    shell, _ = cantilever()
    fallback = shell.solve(steps=10, verbose=False, linear="amg", max_cg=2)
    assert any("CG reached 2 iterations twice" in n for n in fallback.history.notes)
    assert fallback.history.iterations[-1].linear in ("pardiso", "superlu")
    np.testing.assert_allclose(tip_of(fallback, tip), tip_of(res, tip), rtol=0, atol=1e-7)


def test_auto_globalization_is_the_line_search_with_multilevel_amg_else_the_trust_region(monkeypatch):
    """globalization="auto": the trust region with a factorization and with
    one-level AMG (history radius finite or inf), the line search with a
    multilevel AMG hierarchy (radius nan), all to the same equilibrium of
    the buckling leaf.  Why (README "Solver", bench/scaling.py): on the
    32-ring leaf from the flat disc, where the hierarchy has three levels,
    AMG took 23 Newton iterations with the line search and 328 with the
    trust region; PARDISO 18 with the trust region and 240 with the line
    search; one-level AMG on the 1.5k leaf 6.9 s with the trust region,
    19.7 s with the line search."""
    import shellritz.linalg as linalg
    energy = None
    for linear, levels in (("auto", None), ("amg", "one"), ("amg", "several")):
        if levels == "several":
            monkeypatch.setattr(linalg, "AMG_ONE_LEVEL_BLOCKS", 0)
        res = leaf(10).solve(verbose=False, rtol=1e-8, linear=linear)
        its = res.history.iterations
        assert its[0].linear == "amg" if linear == "amg" else its[0].linear in ("pardiso", "superlu")
        radius_nan = [np.isnan(it.radius) for it in its if it.linear == its[0].linear]
        assert all(radius_nan) if levels == "several" else not any(radius_nan)
        energy = energy or its[-1].energy
        assert its[-1].energy == pytest.approx(energy, rel=1e-9)


# ------------------------------------------------------- stability, escape
def compressed_strip():
    """Clamped-clamped strip (plane strain, L = 1, h = 0.02) grown 2 % along
    its length: the straight state is an equilibrium, unstable (Euler
    strain pi^2 h^2 / (3 L^2) = 1.3e-3 per unit grown length)."""
    eng = PlaneStrainShell.strip(20, 1.0, 0.02, NeoHookean(1.0, nu=0.3))
    eng.clamp(0).clamp(-1)
    eng.set_stretch_growth(1.0, 1.02)
    return eng


def test_unstable_equilibrium_is_reported_with_its_modes_and_escaped():
    """escape=False: the straight strip is reported unstable (six negative
    eigenvalues, the first Euler modes); by default the solver leaves it
    along the most unstable mode (one escape) and ends on the stable buckled
    state.  Its mid deflection 0.0869 against 0.0861 from the small-slope
    estimate (2L/pi) sqrt(eps - eps_c), eps = 0.02/1.02 (the elastica
    correction at this slope is of the order of 1 %)."""
    straight = compressed_strip().solve(steps=1, verbose=False, escape=False)
    h = straight.history
    assert h.stable is False and h.unstable_modes >= 1
    assert h.lowest_eigenvalues and h.lowest_eigenvalues[0] < 0
    assert h.modes.shape[1] == h.unstable_modes
    # the modes are directions of descent of the energy from the straight state
    eng = compressed_strip()
    eng.solve(steps=1, verbose=False, escape=False, stability="off")
    x = eng.free_state()
    assert h.modes.shape[0] == len(x)
    E0 = eng.evaluate(x, 0)[0]
    assert all(eng.evaluate(x + 1e-3 * v, 0)[0] < E0 for v in h.modes.T)
    assert np.abs(straight.b).max() < 1e-8

    buckled = compressed_strip().solve(steps=1, verbose=False)
    h = buckled.history
    assert h.stable is True and h.unstable_modes == 0 and len(h.escapes) >= 1
    eps, eps_c = 0.02 / 1.02, np.pi ** 2 * 0.02 ** 2 / 3
    estimate = 2 / np.pi * np.sqrt(eps - eps_c)
    assert np.abs(buckled.b).max() == pytest.approx(estimate, rel=0.03)
    assert buckled.energy < straight.energy


# ------------------------------------------------------------ bad options
def test_options_are_checked_with_clear_errors():
    shell, _ = cantilever(4, 1)
    with pytest.raises(ValueError, match="unknown linear solver 'mumps': choose one of auto, pardiso"):
        shell.solve(linear="mumps", verbose=False)
    with pytest.raises(ValueError, match="globalization='newton': choose one of"):
        shell.solve(globalization="newton", verbose=False)
    with pytest.raises(ValueError, match="reuse_factorization='sometimes': choose one of auto"):
        shell.solve(reuse_factorization="sometimes", verbose=False)
    with pytest.raises(TypeError, match="unknown option.*tolerance.*the options are .*rtol"):
        shell.solve(tolerance=1e-8, verbose=False)
    with pytest.raises(ValueError, match=r"rtol must be in \(0, inf\), got -1.0"):
        shell.solve(rtol=-1.0, verbose=False)
    with pytest.raises(ValueError, match="factor_precision='half': choose one of double, single"):
        shell.solve(factor_precision="half", verbose=False)
    with pytest.raises(ValueError, match="factor_precision='single' with path='arclength'"):
        shell.solve(factor_precision="single", path="arclength", verbose=False)
    with pytest.raises(ValueError, match="predictor='quadratic': choose one of tangent, secant"):
        shell.solve(predictor="quadratic", verbose=False)
    with pytest.raises(ValueError, match=r"max_dt must be in \(0, 1\], got 0"):
        shell.solve(max_dt=0, verbose=False)


def test_arc_length_with_amg_falls_back_to_the_direct_solver(monkeypatch):
    """Arc length needs a factorization (bordered solves, inertia): with
    linear="amg" the path is followed with the direct solver (history note),
    the same path as with it from the start; above AUTO_DIRECT_MAX_DOFS a
    clear error instead."""
    from shellritz import solve as solve_module
    shell, tip = cantilever(4, 1)
    amg = shell.solve(path="arclength", linear="amg", steps=4, verbose=False)
    assert amg.history.linear in ("amg->pardiso", "amg->superlu")
    assert any("arc length needs a factorization" in n for n in amg.history.notes)
    shell, _ = cantilever(4, 1)
    direct = shell.solve(path="arclength", linear=amg.history.linear.split("->")[1], steps=4,
                         verbose=False)
    assert len(amg.history.path) == len(direct.history.path) > 2
    np.testing.assert_allclose(tip_of(amg, tip), tip_of(direct, tip), rtol=0, atol=1e-10)
    monkeypatch.setattr(solve_module, "AUTO_DIRECT_MAX_DOFS", 10)
    shell, _ = cantilever(4, 1)
    with pytest.raises(SolveError, match="arc length needs a direct linear solver, and 72 free DOFs"):
        shell.solve(path="arclength", linear="amg", verbose=False)


# ------------------------------------------------------ thickness continuation
def test_thickness_path_reaches_the_thin_leafs_equilibrium_from_the_thicker_ones():
    """The leaf at h = 0.005 on 1,944 triangles: by continuation in the
    thickness (h = 0.02 from the flat disc, then 0.01, then 0.005, each from
    the last equilibrium) the stable equilibrium of the solve from the flat
    disc (observed: energy equal to 1e-9; 14 + 4 + 14 Newton iterations
    against 32).  On finer meshes the flat disc is the hard start (README
    Solver, thickness_path: 2,400 triangles fail from it after 474 Newton
    iterations, 125 s, and take 7.2 s by continuation); on coarser ones
    continuation can end on another stable state (864 triangles: +0.1 %
    energy)."""
    flat = leaf(18, thickness=0.005).solve(verbose=False)
    res = leaf(18, thickness=0.005).solve(verbose=False, thickness_path=[0.02, 0.01])
    stages = res.history.thickness_stages
    assert [s["thickness"] for s in stages] == [0.02, 0.01]
    assert all(s["stable"] for s in stages) and res.history.stable and flat.history.stable
    assert res.shell.h == 0.005 and not res.history.notes
    assert stages[0]["energy"] > stages[1]["energy"] > res.energy      # thinner: softer
    assert res.energy == pytest.approx(flat.energy, rel=1e-9)


def test_thickness_path_solves_a_failing_stage_through_an_intermediate_thickness(monkeypatch):
    """A stage whose solve fails (here forced: at most 3 Newton iterations
    at h = 0.005 from h = 0.01, no load steps to cut at t = 1) is approached
    through the geometric mean of the two thicknesses (history note)."""
    own = dkt_leaf(18, thickness=0.005)
    original = type(own).solve

    def solve(engine, *args, **kw):
        if engine is own and kw.get("start") is not None and engine.h == 0.005:
            kw = dict(kw, max_iter=3) if kw["start"].shell.h == 0.01 else kw
        return original(engine, *args, **kw)
    monkeypatch.setattr(type(own), "solve", solve)
    res = own.solve(verbose=False, thickness_path=[0.02, 0.01])
    assert [s["thickness"] for s in res.history.thickness_stages] == pytest.approx([0.02, 0.01, 0.005 * 2 ** 0.5])
    assert any("no equilibrium at h = 0.005 from h = 0.01" in n for n in res.history.notes)
    assert res.converged and res.history.stable


def test_thickness_path_checks_its_input_and_keeps_a_failed_stage():
    shell = leaf(6, thickness=0.005)
    for bad, why in (([0.004], "larger than the shell's own"), ([0.01, 0.02], "must decrease"),
                     ([], "empty"), ("thick", "sequence of thicknesses"),
                     ([0.01, float("nan")], "finite")):
        with pytest.raises(ValueError, match=why):
            shell.solve(verbose=False, thickness_path=bad)
    with pytest.raises(TypeError, match="triangle engine"):
        PlaneStrainShell.strip(20, 1.0, 0.02, NeoHookean(1.0, nu=0.3)).solve(
            verbose=False, thickness_path=[0.04])
    with pytest.raises(SolveError, match=r"thickness continuation, stage h = 0.02") as info:
        shell.solve(verbose=False, thickness_path=[0.02], max_iter=1, min_dt=0.25)
    assert info.value.result is not None and info.value.history.thickness_stages == []


def test_a_negative_lowest_eigenvalue_by_lobpcg_gets_the_lowest_eigenpairs():
    """assess_stability on a Hessian K1 that was not factorized, with the
    factorization of a nearby positive definite K0 (a reused step): K1 =
    K0 - 3 e e^T on a chain stiffness has one negative eigenvalue; the
    lowest eigenvalue by LOBPCG is negative beyond its residual, so the
    lowest eigenpairs are computed and the state is reported unstable with
    its one mode (the eigenvector of K1's negative eigenvalue)."""
    import scipy.sparse as sp
    from shellritz.solve import SolveHistory, SolverOptions, _Linear, assess_stability
    n = 60
    K0 = sp.diags([np.full(n, 2.0), np.full(n - 1, -0.5)], [0, -1], format="csr")   # lower triangle
    e = np.zeros(n)
    e[n // 2] = 1.0
    K1 = (K0 - sp.diags(3.0 * e * e, 0)).tocsr()
    K1.sort_indices()
    opts = SolverOptions(reuse_factorization="always", verbose=False)
    history = SolveHistory()
    lin = _Linear(object(), opts, history)
    assert lin.factorize(K0)[0] == 0
    mode = assess_stability(object(), K1, opts, history, lin, 1.0)
    full = (K1 + sp.tril(K1, -1).T).toarray()
    w = np.linalg.eigvalsh(full)
    assert w[0] < 0 < w[1]
    assert history.notes[0].startswith("t=1: stability from the lowest eigenvalue (LOBPCG")
    assert history.stable is False and history.unstable_modes == 1
    assert history.lowest_eigenvalues[0] == pytest.approx(w[0], rel=1e-8)
    assert history.factorizations == 1                  # K0's only
    assert np.linalg.norm(full @ mode - w[0] * mode) <= 1e-8 * np.linalg.norm(mode)


def test_lobpcg_for_the_sign_alone_stops_once_it_is_decided():
    """lowest_eigenpairs(until_sign=True), as assess_stability calls it for a
    Hessian that was not factorized: LOBPCG stops as soon as the lowest Ritz
    value is farther from zero than its residual, here (a positive definite
    chain K1 near the factorized K0, lowest eigenvalue 1.5e-3) after 4
    preconditioner applications instead of 19 to EIGEN_RTOL, and the exact
    lowest eigenvalue lies within that residual."""
    import scipy.sparse as sp
    from shellritz.solve import SolveHistory, SolverOptions, _Linear, lowest_eigenpairs
    n = 400
    K0 = sp.diags([np.full(n, 2.0 + 1e-3), np.full(n - 1, -1.0)], [0, -1], format="csr")   # lower triangle
    K1 = (K0 + sp.diags(1e-3 * np.random.default_rng(1).random(n), 0)).tocsr()
    K1.sort_indices()
    lin = _Linear(object(), SolverOptions(verbose=False, reuse_factorization="always"), SolveHistory())
    assert lin.factorize(K0)[0] == 0
    factor, applications = lin.preconditioner, []

    def counted(K):
        apply = factor(K)
        return lambda r: applications.append(1) or apply(r)

    lin.preconditioner = counted
    exact = np.linalg.eigvalsh((K1 + sp.tril(K1, -1).T).toarray())[0]
    w, _, res = lowest_eigenpairs(lin, K1, 1)
    full = len(applications)
    assert abs(w[0] - exact) <= res[0] <= 1e-10
    applications.clear()
    w, _, res = lowest_eigenpairs(lin, K1, 1, until_sign=True)
    assert 0 < res[0] < w[0] and abs(w[0] - exact) <= res[0]
    assert len(applications) <= full // 2


class _Quartic:
    """E(x) = sum (x - t a)^4 / 4 through the solver's problem protocol:
    Newton's step shrinks x - t a by a third, |g| by (2/3)^3 = 0.30 per
    iteration at any scale, so from x = 0 at t = 1 it takes 18 iterations
    to |g| <= 1e-9 |g(0)| (and a smaller load step no fewer)."""

    def __init__(self):
        self.a = np.linspace(1.0, 2.0, 4)
        self.x, self.t = np.zeros(4), 0.0

    def set_parameter(self, t):
        self.t = t

    def evaluate(self, x, mode):
        import scipy.sparse as sp
        d = x - self.t * self.a
        K = sp.csr_matrix((3 * d ** 2, np.arange(4), np.arange(5)), shape=(4, 4))   # diagonal kept
        return np.sum(d ** 4) / 4, d ** 3, K

    def free_state(self):
        return self.x.copy()

    def set_free_state(self, x):
        self.x = np.array(x, dtype=float)

    def save_point(self):
        return self.x.copy(), self.t

    def restore_point(self, saved):
        self.x, self.t = saved[0].copy(), saved[1]

    def load_scale(self):
        return 0.0

    def size_scale(self):
        return 1.0

    def energy_magnitude(self):
        return 1.0


def test_newton_still_converging_at_max_iter_goes_on():
    """A load step whose Newton iterations reach max_iter while |g| still
    falls tenfold over the last five (CONVERGING_SPAN) goes on, up to
    2 max_iter, instead of being given up and restarted with half the step
    (the 12k leaf from the flat disc with AMG: 374 instead of 42 Newton
    iterations): the quartic needs 18 iterations, which max_iter = 10
    allows; max_iter = 8 (at most 16) does not, at any load step."""
    from shellritz.solve import SolverOptions, continuation
    history = continuation(_Quartic(), steps=1, opts=SolverOptions(max_iter=10, verbose=False), min_dt=0.5)
    assert history.steps == [(0.0, True), (1.0, True)]
    assert len(history.iterations) == 18
    with pytest.raises(SolveError):
        continuation(_Quartic(), steps=1, opts=SolverOptions(max_iter=8, verbose=False), min_dt=0.5)


def test_lobpcg_short_of_its_tolerance_does_not_warn():
    """SciPy's LOBPCG warns when it stops short of its tolerance ('Exited at
    iteration 200 with accuracies ... not reaching the requested tolerance',
    a message with line breaks); the residuals lowest_eigenpairs returns
    judge that, and the warning reached users on ordinary solves.  An
    unpreconditioned (identity factor) chain Laplacian of 3,000 DOFs: LOBPCG
    stops at 200 iterations, silently, with residuals above its tolerance."""
    import warnings

    import scipy.sparse as sp
    from shellritz.solve import EIGEN_RTOL, SolveHistory, SolverOptions, _Linear, lowest_eigenpairs
    n = 3000
    K = sp.diags([np.full(n, 2.0), np.full(n - 1, -1.0)], [0, -1], format="csr")   # lower triangle
    K.sort_indices()
    lin = _Linear(object(), SolverOptions(verbose=False), SolveHistory())
    lin.factorize(sp.identity(n, format="csr"))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        w, V, residuals = lowest_eigenpairs(lin, K, 1)
    assert residuals[0] > EIGEN_RTOL * 2.0          # short of the tolerance, so SciPy did warn


def _free_grown_disc(supported, rings=3):
    """The leaf's growth 1 + 0.3 rho^2 on a free disc (h = 0.05): it buckles
    (3 rings: 57 negative eigenvalues at its flat start at t = 0.25)."""
    s = Shell(shapes.disc(rings), 0.05, NeoHookean(1.0, nu=0.3))
    s.set_growth(G0=lambda X, N: np.einsum("n,ij->nij", 1 + 0.3 * (X[:, 0] ** 2 + X[:, 1] ** 2),
                                           np.diag([1, 1, 0])) + np.diag([0, 0, 1.0]))
    if supported:
        s.remove_rigid_motions()
    return s


def test_a_free_body_buckles_to_the_equilibrium_of_the_supported_one():
    """No supports: the free rigid motions are projected out of the Newton
    steps.  Before CG took the projected residual (linalg.steihaug_cg) this
    solve failed at t = 0.25 ("preconditioner not positive definite", and a
    hint about a net force it does not have).  Observed: 61 Newton
    iterations (216 with remove_rigid_motions), the same energy to 1e-15."""
    free = _free_grown_disc(False).solve(steps=4, verbose=False)
    held = _free_grown_disc(True).solve(steps=4, verbose=False)
    assert free.history.stable and held.history.stable
    assert free.energy == pytest.approx(held.energy, rel=1e-10)


def test_trust_region_steps_stay_within_the_radius():
    """Grown discs buckle into shapes with a soft mode (a near-symmetry: the
    free 4-ring disc's eigenvalue changes sign near t = 0.94) where
    trust-region steps are rejected and load steps cut.
    Where K's factorization is positive definite the step is the Newton
    step (r = inf), scaled onto the trust-region boundary; so must be the
    first CG direction where K nonetheless has negative curvature: unscaled,
    the same rejected step came back 261 times.  How many steps are rejected
    or cut on which disc, round-off decides: the centre-clamped 8-ring disc
    took 303 Newton iterations and 17 cut steps in IEEE order on one
    machine, 54 iterations, 4 rejected trust-region steps and 1 cut step
    with the kernels' fused multiply-adds (kernels/small.py, fma).  So the
    test asserts that rejections happen and that no step after one goes
    beyond the radius; the tolerance of cut steps is checked by
    test_cut_load_steps_keep_the_tolerance_of_the_first_step."""
    s = _free_grown_disc(False, rings=8)
    s.clamp(s.mesh.nodes_where(lambda X: X[:, 0] ** 2 + X[:, 1] ** 2 < 1e-12))
    history = s.solve(steps=4, verbose=False).history
    its = history.iterations
    rejected = [a for a in its if not a.accepted and np.isfinite(a.radius)]
    beyond = [b for a, b in zip(its, its[1:])
              if a.t == b.t and not a.accepted and np.isfinite(a.radius) and b.step > a.radius * (1 + 1e-9)]
    assert rejected and not beyond
    assert history.stable


def test_steps_on_the_way_that_stagnate_near_an_equilibrium_are_kept():
    """Past secondary bifurcations the grown discs' equilibria are nearly
    singular: Newton creeps with |g| of 1e-8 .. 1e-9 against a tolerance of
    1.6e-11, the step was cut to min_dt and the solve failed (this disc at
    t = 0.95; bench/disc_robustness.py: 50 of 60 discs stable).  A step on
    the way to t = 1 whose Newton iteration stagnates is kept, with a note,
    where it or an earlier iterate of it (restored) is below
    solve.ON_THE_WAY_RTOL times the step's force scale; the end of the path
    is not (there Newton ends at the tolerance or where its correction is
    lost in round-off, as the step kept on the way: below ON_THE_WAY_RTOL
    of the force scale).  Observed: stable, states kept from t = 0.25 on
    (|g| up to 1.6e-7), final |g| 2.4e-9 on an Intel Xeon (its Newton steps
    2e-8 of the size, the energy flat to round-off; 60 of 60 discs stable)
    and 1.8e-8 on an AMD EPYC (the kernels are compiled for the host CPU:
    there the last escape, along an eigenvalue of -3.7e-10, lowers the
    energy by 1e-15 and leaves a state whose Newton correction is lost in
    round-off), against ON_THE_WAY_RTOL times the force scale, 1.6e-7."""
    s = _free_grown_disc(False, rings=4)
    s.clamp(s.mesh.nodes_where(lambda X: X[:, 0] ** 2 + X[:, 1] ** 2 < 1e-12))
    result = s.solve(steps=4, verbose=False)
    assert result.history.stable
    kept = [n for n in result.history.notes if "kept on the way" in n]
    assert kept
    assert all(float(n.split(":")[0][2:]) < 1.0 for n in kept)
    force_scale = float(kept[0].split("|g| <= ")[1].rstrip(")")) / ON_THE_WAY_RTOL
    assert np.linalg.norm(s.evaluate(s.free_state(), 1)[1]) < ON_THE_WAY_RTOL * force_scale


def test_cut_load_steps_keep_the_tolerance_of_the_first_step(monkeypatch):
    """A load step retried with a smaller dt keeps the force scale of the
    first step (the tolerance is rtol times it): relative to dt |dg/dt| it
    fell to 1.5e-14 at dt = 1e-4, below where |g| stalls (about 1e-12), and
    the free 4-ring disc failed at t = 0.937.  Which disc cuts how far,
    round-off decides; the free 5-ring disc with max_iter = 8 cuts its steps
    (8-10 times, to dt = 1/512, in both arithmetics tried: IEEE order and
    the reassociating build of branch fastmath-kernels; since steps on the
    way that stagnate near |g| = 0 are kept, solve.ON_THE_WAY_RTOL, three
    times from one point), and every retry from one point with dt up to the
    first step's must be held to the same force scale (under the old rule:
    halved with each cut)."""
    import shellritz.solve as solve_module
    calls = []
    real = solve_module.equilibrium

    def spy(problem, t, opts, history, g_ref, lin, may_cut=False, accept=None):
        ok = real(problem, t, opts, history, g_ref, lin, may_cut, accept)
        calls.append((t, g_ref, ok))
        return ok
    monkeypatch.setattr(solve_module, "equilibrium", spy)
    result = _free_grown_disc(False, rings=5).solve(steps=4, verbose=False, max_iter=8)
    assert result.history.stable
    start, first_dt, retries = 0.0, 0.25, []
    for t, g_ref, ok in calls[1:]:               # calls[0]: the start, t = 0
        if t - start <= first_dt * (1 + 1e-12):
            retries.append((start, g_ref))
        if ok:
            start = t
    by_start = {}
    for start, g_ref in retries:
        by_start.setdefault(start, []).append(g_ref)
    cut = [v for v in by_start.values() if len(v) > 1]
    assert sum(len(v) - 1 for v in cut) >= 3            # cuts observed: 3 (from one point)
    for scales in cut:
        assert max(scales) == pytest.approx(min(scales), rel=1e-12)


def test_amg_load_steps_keep_a_tolerance_relative_to_the_growth_force():
    """With AMG (no factorization, no tangent dx/dt) |dg/dt| was not computed,
    so a growth scene's tolerance was relative to the gradient at the
    predicted state only (rtol times 1e-6 and below): the free 3-ring disc
    failed at t = 0.25.  Observed now: it converges (194 Newton iterations)
    to the buckled state the factorization finds."""
    import warnings
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", StabilityWarning)
        amg = _free_grown_disc(False).solve(steps=4, verbose=False, linear="amg")
    direct = _free_grown_disc(False).solve(steps=4, verbose=False)
    assert direct.history.stable
    assert amg.energy == pytest.approx(direct.energy, rel=1e-9)


def test_a_solve_whose_stability_is_not_assessed_says_so():
    """AMG gives no inertia, and stability="auto" does not run LOBPCG with
    it: a disc grown symmetrically from its flat reference (centre clamped,
    3 rings) stays flat, an unstable equilibrium (energy 1.38e-3 where the
    factorization's escape finds the buckled 4.34e-4).  The solve warns;
    stability="off" asks for no assessment and gets no warning; with the
    factorization the state is assessed and left."""
    import warnings

    def centred():
        s = _free_grown_disc(False)
        s.clamp(s.mesh.nodes_where(lambda X: X[:, 0] ** 2 + X[:, 1] ** 2 < 1e-12))
        return s

    with pytest.warns(StabilityWarning, match="not assessed"):
        flat = centred().solve(steps=4, verbose=False, linear="amg")
    assert flat.history.stable is None
    with warnings.catch_warnings():
        warnings.simplefilter("error", StabilityWarning)
        centred().solve(steps=4, verbose=False, linear="amg", stability="off")
        buckled = centred().solve(steps=4, verbose=False)
    assert buckled.history.stable and buckled.energy < 0.5 * flat.energy


def test_arc_length_lands_at_t_1_to_the_tolerance_of_its_path():
    """Arc length follows a symmetrically grown disc (centre clamped, 3
    rings) along its flat branch through the bifurcations (31 negative
    eigenvalues at t = 1) and lands at t = 1 by Newton, escaping from
    there.  The landing's tolerance was rtol times the loads (none) or the
    gradient where it starts (2.8e-10): 9e-16, unreachable; now the
    corrector's, rtol |dg/dt|.  The landing, from the flat branch to the
    buckled state, cannot be retried with a smaller step and so goes on past
    max_iter while its energy falls: with max_iter = 30 it took 43 Newton
    iterations (it stopped at the 30th before, energy still falling).  A
    watchdog probation under way at max_iter ends first (its uphill iterates
    say nothing of the descent): on another machine the landing stopped on
    probation at its 38th iteration, one step after |g| = 4e-6.  Observed:
    395 Newton iterations, 47 at t = 1, the stable buckled state of the load
    path (energy to 1e-9)."""
    def centred():
        s = _free_grown_disc(False)
        s.clamp(s.mesh.nodes_where(lambda X: X[:, 0] ** 2 + X[:, 1] ** 2 < 1e-12))
        return s
    arc = centred().solve(steps=4, verbose=False, path="arclength", max_iter=30)
    load = centred().solve(steps=4, verbose=False)
    assert arc.history.stable and load.history.stable
    assert arc.energy == pytest.approx(load.energy, rel=1e-9)


def test_a_load_path_failing_at_a_limit_point_says_so():
    """A sphere (80 triangles, h = 0.02, nu = 0.45) inflated by an inner
    pressure twice its maximum (about 1.24 mu h / R for a thin neo-Hookean
    sphere) has no equilibrium beyond the maximum: the load path fails there
    and says that the path turns back (|dx/dt| ~ 1/sqrt(t_c - t), observed
    t_c = 0.6501 against the failure at t = 0.650024, reach 14 sizes) and
    that arc length follows it; a failure elsewhere gets no such hint (the
    sliver of tests/test_validity.py: reach 0.39)."""
    s = Shell(shapes.sphere(1), 0.02, NeoHookean(1.0, nu=0.45))
    s.remove_rigid_motions()
    s.pressure(0.04, face="inner")
    with pytest.raises(SolveError, match=r"path turns back near t = 0\.65.*path=\"arclength\" follows") as info:
        s.solve(verbose=False)
    assert 0.6 < info.value.last_t < 0.7
