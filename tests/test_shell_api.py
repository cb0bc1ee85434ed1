"""Shell API: loads, growth input, output files, bad input and failures.

Observed: a pressurized icosphere converges to the radius of the 1D
(uniform-state) solution of the same energy with error 4e-4, 1e-4, 2.6e-5 for
icosphere levels 2, 3, 4 (second order); the volume potential's gradient and
Hessian match central differences to 1e-9.
"""

import numpy as np
import pytest
import scipy.sparse as sp
from scipy.optimize import brentq

from shellritz import (EvaluationError, NeoHookean, Shell, SolveError, shapes)
from shellritz.scenes import leaf
from shellritz.model import evaluate_point

LAW = NeoHookean(1.0, nu=0.3)


def sphere_point(r0, h):
    """Point data of a uniformly inflated unit sphere (see tests/pointdata.py)."""
    from pointdata import sphere
    ref = sphere(1.0)
    return r0 * ref, ref


def one_d_pressure_radius(p, h):
    """Minimize 4 pi L(r0) - p 4 pi r0^3 / 3 over the radius (uniform state)."""
    def dE(r0):
        v, ref = sphere_point(r0, h)
        r = evaluate_point(LAW, v, ref, h, "consistent", mode="gradient")
        dv = ref.copy()
        return r.grad @ dv - p * r0 ** 2
    return brentq(dE, 1.0, 3.0, xtol=1e-14)


def test_pressurized_sphere_matches_uniform_solution():
    h, p = 0.05, 0.02
    exact = one_d_pressure_radius(p, h)
    errors = []
    for level in (2, 3, 4):
        mesh = shapes.sphere(level)
        s = Shell(mesh, h, LAW).pressure(p)
        res = s.solve(steps=4, verbose=False)
        radius = np.linalg.norm(res.r - res.r.mean(axis=0), axis=1)
        errors.append(abs(radius.mean() - exact))
    assert errors[-1] < 1e-4, errors
    assert errors[0] / errors[1] > 3 and errors[1] / errors[2] > 3, errors


def test_volume_potential_derivatives():
    mesh = shapes.sphere(1)
    s = Shell(mesh, 0.05, LAW).pressure(0.3)
    s._setup()
    s.set_parameter(1.0)
    rng = np.random.default_rng(0)
    x = s.free_state() + 0.01 * rng.standard_normal(len(s.free))
    E, g, K = s.evaluate(x, 2)
    K = (K + sp.tril(K, -1).T).toarray()
    eps = 1e-6
    for i in rng.choice(len(x), 12, replace=False):
        e = np.zeros_like(x)
        e[i] = eps
        Ep, gp, _ = s.evaluate(x + e, 1)
        Em, gm, _ = s.evaluate(x - e, 1)
        assert (Ep - Em) / (2 * eps) == pytest.approx(g[i], rel=1e-6, abs=1e-9)
        np.testing.assert_allclose((gp - gm) / (2 * eps), K[:, i], atol=1e-8 * np.abs(K).max())


def test_growth_as_function_of_position_and_parameter():
    mesh = shapes.rectangle(4, 2, lx=1.0, ly=0.5)
    calls = []

    def growth(t):
        calls.append(t)
        G0 = np.broadcast_to(np.diag([1 + 0.2 * t, 1, 1]), (mesh.n_nodes, 3, 3)).copy()
        return G0, np.zeros((mesh.n_nodes, 3, 3))
    s = Shell(mesh, 0.02, LAW).set_growth(function=growth)
    s.pin([0])
    s.symmetry("y", 0.0)
    s.symmetry("x", 0.0)
    res = s.solve(steps=2, verbose=False)
    assert 1.0 in calls
    np.testing.assert_allclose(res.r[:, 0], 1.2 * mesh.vertices[:, 0], atol=1e-9)
    # positional form: callable(X, N)
    s2 = Shell(mesh, 0.02, LAW).set_growth(G0=lambda X, N: np.broadcast_to(1.1 * np.eye(3), (len(X), 3, 3)))
    assert s2._G0.shape == (mesh.n_nodes, 3, 3)


def test_save_any_meshio_format(tmp_path):
    import meshio
    mesh = shapes.rectangle(3, 3)
    s = Shell(mesh, 0.02, LAW).set_growth(G0=np.diag([1.1, 1.0, 1.0]))
    s.pin([0]).symmetry("x", 0.0).symmetry("y", 0.0)
    res = s.solve(verbose=False)
    for name in ("out.vtu", "out.vtk"):
        res.save(tmp_path / name)
        m = meshio.read(tmp_path / name)
        assert len(m.points) == mesh.n_nodes
    m = meshio.read(tmp_path / "out.vtu")
    np.testing.assert_allclose(m.point_data["displacement"], res.displacement)
    stretch = m.cell_data["principal_stretch"][0]
    np.testing.assert_allclose(stretch[:, 0], 1.1, atol=1e-8)     # the grown stress-free state
    P = m.cell_data["first_piola_kirchhoff"][0]
    assert np.abs(P).max() < 1e-8


def test_bad_input_is_rejected_with_a_clear_message():
    mesh = shapes.rectangle(2, 2)
    with pytest.raises(ValueError, match="thickness"):
        Shell(mesh, -0.1, LAW)
    with pytest.raises(ValueError, match="level"):
        Shell(mesh, 0.1, LAW, level="plate")
    with pytest.raises(ValueError, match="no 5-point triangle rule"):
        Shell(mesh, 0.1, LAW, quadrature=5)
    s = Shell(mesh, 0.1, LAW)
    with pytest.raises(ValueError, match=r"det G0 <= 0 at nodes \[0, 1"):
        s.set_growth(G0=np.diag([1.0, 1.0, -1.0]))
    with pytest.raises(ValueError, match="non-finite growth"):
        s.set_growth(G1=np.full((3, 3), np.nan))
    with pytest.raises(ValueError, match="node indices outside"):
        s.clamp([99])
    with pytest.raises(ValueError, match="no nodes on it"):
        s.symmetry("x", 5.0)
    with pytest.raises(ValueError, match="pressure must be finite"):
        s.pressure(np.inf)
    with pytest.raises(ValueError, match="pressure face 'top': choose 'inner', 'outer' or 'middle'"):
        s.pressure(1.0, face="top")
    with pytest.raises(ValueError, match="membrane='cst': choose one of"):
        Shell(mesh, 0.1, LAW, membrane="cst")
    with pytest.raises(ValueError, match="membrane='regge' needs a rule of 6 or 7 points, got quadrature=3"):
        Shell(mesh, 0.1, LAW, membrane="regge", quadrature=3)
    with pytest.raises(TypeError):
        Shell(mesh, 0.1, "rubber")
    with pytest.raises(TypeError, match="thickness must be a number, got '0.1'"):
        Shell(mesh, "0.1", LAW)
    with pytest.raises(ValueError, match="axis must be 'x', 'y', 'z' or 0, 1, 2, got 'q'"):
        s.symmetry("q")
    with pytest.raises(ValueError, match="axis must be .* got 5"):
        s.diaphragm(mesh.boundary_nodes(), 5)
    with pytest.raises(ValueError, match=r"function\(t\) must return \(G0, G1\) nodal arrays"):
        s.set_growth(function=lambda t: 1.0)


def test_bad_loads_supports_and_node_selections_are_named():
    """Non-finite loads and prescribed rotations are refused where they are
    given (not at the solve); a boolean mask selects its nodes, float
    indices that are not integers are refused."""
    from shellritz.shell import _nodes
    mesh = shapes.rectangle(3, 3)
    s = Shell(mesh, 0.02, LAW)
    with pytest.raises(ValueError, match=r"point_force: force: non-finite value at index \(0, 2\)"):
        s.point_force([5], [0, 0, np.nan])
    with pytest.raises(ValueError, match="edge_load: traction: non-finite"):
        s.edge_load(mesh.nodes_on_plane("x", 1.0), [np.inf, 0, 0])
    with pytest.raises(ValueError, match="q_plus: non-finite"):
        s.face_tractions(q_plus=[0, 0, np.nan])
    with pytest.raises(ValueError, match="rotation: non-finite"):
        s.clamp([0], rotation=[np.nan, 0, 0])
    with pytest.raises(ValueError, match="position: expected numbers broadcastable to shape"):
        s.clamp([0, 1], position=[[0, 0, 0]] * 3)
    mask = mesh.vertices[:, 0] < 1e-9
    np.testing.assert_array_equal(_nodes(mask, mesh.n_nodes), np.flatnonzero(mask))
    with pytest.raises(ValueError, match="one entry per node"):
        _nodes(mask[:-1], mesh.n_nodes)
    with pytest.raises(ValueError, match="must be integers"):
        _nodes([2.7, 3.2], mesh.n_nodes)
    np.testing.assert_array_equal(_nodes([3.0, 2.0], mesh.n_nodes), [2, 3])


def test_solver_options_are_checked_before_solving():
    """Out-of-range or mistyped options fail at once with their name (a
    negative max_escapes used to skip Newton and report converged)."""
    s = Shell(shapes.rectangle(2, 2), 0.02, LAW)
    for options, error, message in [
            (dict(max_escapes=-1), ValueError, "max_escapes must be at least 0, got -1"),
            (dict(steps=0), ValueError, "steps must be at least 1, got 0"),
            (dict(steps=2.5), TypeError, "steps must be an integer"),
            (dict(min_dt=0.0), ValueError, r"min_dt must be in \(0, 1\)"),
            (dict(max_iter=2.5), TypeError, "max_iter must be an integer"),
            (dict(max_iter=True), TypeError, "max_iter must be an integer"),
            (dict(rtol="1e-9"), TypeError, "rtol must be a number"),
            (dict(xtol=np.nan), ValueError, r"xtol must be in \[0, inf\)"),
            (dict(armijo=5.0), ValueError, r"armijo must be in \(0, 1\)"),
            (dict(arc_ds=-0.1), ValueError, "arc_ds must be in"),
            (dict(escape="no"), TypeError, "escape must be True or False"),
            (dict(monitor="abc"), TypeError, "monitor must be node indices"),
            (dict(monitor=[999]), ValueError, "monitor: node indices outside the mesh")]:
        with pytest.raises(error, match=message):
            s.solve(verbose=False, **options)


def test_growth_undefined_partway_keeps_the_converged_steps():
    """G0 = diag(-1, -1, 1) is admissible at t = 1 (det 1) but its ramp
    I + t (G0 - I) is singular at t = 0.5: the solve stops there with a
    SolveError that names t and hands back the state of t = 0.25."""
    mesh = shapes.rectangle(4, 4)
    s = Shell(mesh, 0.02, LAW)
    s.clamp(mesh.nodes_on_plane("x", 0.0))
    s.set_growth(G0=np.diag([-1.0, -1.0, 1.0]))
    with pytest.raises(SolveError, match=r"not defined at t = 0.5: .*det G0 <= 0.*t = 0.25\) is kept") as info:
        s.solve(steps=4, max_dt=0.25, verbose=False)
    result = info.value.result
    assert result.t == 0.25 and result.converged is False
    assert np.isfinite(result.energy) and np.abs(result.r - mesh.vertices).max() > 0.1   # it shrank


def test_growth_that_folds_the_grown_state_through_the_thickness_is_refused():
    """G0 = I, G1 = g e1 e1 at h = 0.05: det(G0 + Z G1) = 1 + g Z vanishes at
    Z = -h/2 once g h / 2 >= 1.  g = 45 (1.125) used to fail at t = 0.875
    with the generic continuation message; it is refused when set.  A
    rotation-like G1 (complex eigenvalues) never folds."""
    mesh = shapes.rectangle(4, 4)
    s = Shell(mesh, 0.05, LAW)
    with pytest.raises(ValueError, match=r"G1: the grown state folds through the thickness at nodes "
                                         r"\[0, 1, 2.*h \|mu\| / 2 = 1.12 >= 1"):
        s.set_growth(G1=np.diag([45.0, 0.0, 0.0]))
    with pytest.warns(UserWarning, match="through-thickness growth gradients"):
        s.set_growth(G1=np.diag([35.0, 0.0, 0.0]))          # h |mu| / 2 = 0.875: admissible
        s.set_growth(G1=[[0.0, -45.0, 0.0], [45.0, 0.0, 0.0], [0.0, 0.0, 0.0]])


def test_an_unsupported_shell_under_a_net_load_says_why():
    mesh = shapes.rectangle(3, 3)
    s = Shell(mesh, 0.02, LAW)
    s.point_force([5], [0, 0, 1e-5])
    with pytest.raises(ValueError, match=r"no supports \(free rigid motions\) but its loads have a net force"):
        s.solve(verbose=False)
    s.point_force([6], [0, 0, -1e-5])      # balanced (a net moment remains: Newton's to find out)
    s._check_solvable()


def test_a_failed_linear_solve_keeps_the_last_converged_state(monkeypatch):
    """A LinearSolverError in the second load step becomes a SolveError
    with the state of the first (not a bare linear-algebra error)."""
    import shellritz.solve as solve
    from shellritz.linalg import LinearSolverError
    real, calls = solve.minimize, []

    def failing(problem, t, *args, **kwargs):
        calls.append(t)
        if len(calls) == 3:                 # t = 0, 0.5, then 1
            raise LinearSolverError("injected")
        return real(problem, t, *args, **kwargs)
    monkeypatch.setattr(solve, "minimize", failing)
    mesh = shapes.rectangle(4, 1, lx=1.0, ly=0.25)
    s = Shell(mesh, 0.02, LAW)
    s.clamp(mesh.nodes_on_plane("x", 0.0))
    s.point_force(mesh.nodes_on_plane("x", 1.0), [0, 0, 1e-7])
    with pytest.raises(SolveError, match=r"t = 1: the linear solver failed \(injected\); the last "
                                         r"converged state \(t = 0.5\) is kept") as info:
        s.solve(steps=2, max_dt=0.5, verbose=False)
    assert info.value.result.t == 0.5 and info.value.result.r[:, 2].max() > 0


def test_failure_keeps_the_last_converged_state():
    """A cantilever rolled up by an end rotation of 2 pi, with Newton allowed
    only 3 iterations per step and steps no smaller than 0.02: the
    continuation cannot advance.  The error says where it stopped and hands
    back the last converged state (here the reference)."""
    mesh = shapes.rectangle(16, 1, lx=1.0, ly=0.05)
    s = Shell(mesh, 0.01, NeoHookean(1.0, nu=0.0))
    s.clamp(mesh.nodes_on_plane("x", 0.0))
    s.rotate(mesh.nodes_on_plane("x", 1.0), rotation=[0, -2 * np.pi, 0])
    with pytest.raises(SolveError, match="continuation failed beyond t = 0.0") as info:
        s.solve(steps=8, verbose=False, max_iter=3, min_dt=0.02)
    err = info.value
    assert err.last_t == 0.0 and err.result.converged is False
    np.testing.assert_allclose(err.result.r, mesh.vertices, atol=1e-14)
    assert len(err.history.steps) > 1


@pytest.mark.parametrize("membrane", ["dkt", "regge"])
def test_inverted_elements_are_named(membrane):
    """The centre node of a 2 x 2 patch pushed through its neighbours folds
    the triangles around it: the evaluation names an inverted element (with
    the regge metric the assumed metric of a folded triangle fails first;
    it is named inverted all the same, its facet having turned over)."""
    mesh = shapes.rectangle(2, 2)
    s = Shell(mesh, 0.02, LAW, membrane=membrane)
    s._setup()
    s.set_parameter(1.0)
    s.U[4, 0] = [2.0, 0.5, 0.0]          # node 4 is the centre (0.5, 0.5)
    s.Y1[:] = 0.0
    s.Y1[..., 2] = 1.0                   # directors continued from the reference side
    with pytest.raises(EvaluationError, match=r"element \d+ \(nodes \[.*4.*\]\): inverted"):
        s.evaluate(s.free_state(), 0)


def test_the_result_energy_is_the_last_evaluation_where_that_was_of_the_final_state(monkeypatch):
    """Shell.final_energy (Result.energy, and the per-element arrays the
    validity check reads) takes the last evaluation where it was of the
    current state and parameter, else evaluates: after a solve no
    evaluation and the energy of a fresh one (to round-off of the directors'
    warm start: observed below 1e-13 relative on an Intel Xeon, 2.5e-13 on
    an AMD EPYC, the kernels compiled for the host CPU; the state 1.001 x
    differs by 0.43); after a move, a change of t, or a failed evaluation
    (partly overwritten element arrays), one."""
    res = leaf(8).solve(verbose=False)
    s = res.shell
    calls = []
    evaluate = Shell.evaluate
    monkeypatch.setattr(Shell, "evaluate", lambda self, x, mode: calls.append(mode) or evaluate(self, x, mode))
    assert s.final_energy() == res.energy and not calls
    assert res.energy == pytest.approx(s.evaluate(s.free_state(), 0)[0], rel=1e-12, abs=0)
    x = s.free_state()
    s.evaluate(1.001 * x, 1)                       # a trial elsewhere
    calls.clear()
    assert s.final_energy() == pytest.approx(res.energy, rel=1e-12, abs=0) and calls == [0]
    s.set_parameter(0.5)
    calls.clear()
    s.final_energy()
    assert calls == [0]
    s.set_parameter(1.0)
    s.final_energy()
    U = s.U.copy()
    s.U[0, 0] += [2.0, 0.5, 0.0]                   # node 0 through its neighbours
    with pytest.raises(EvaluationError):
        s.evaluate(s.free_state(), 0)
    s.U[:] = U
    calls.clear()
    assert s.final_energy() == pytest.approx(res.energy, rel=1e-12, abs=0) and calls == [0]
