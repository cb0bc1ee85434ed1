"""Necking in plane strain (paper section 4.3, docs/necking.md).

Observed:
* identity: the plane-strain engine's energy for symmetric necking
  kinematics equals an independent quadrature of E_1d to 5e-16 relative
  (the gradient term alone to 4e-12 of itself: a few ulps of the total),
  levels "bending" and "consistent";
* onset: the engine's Hessian inertia along the displacement-controlled
  path finds the E_1d onset stretch to 1e-9 (20 elements, bisection to
  1e-9); h/l = 0.05, 0.1, 0.2 in the slow test; the unstable eigenvector
  just past it is x0 ~ sin(pi X / l) (correlation 1 - 1e-10), no bending;
* the power-law solid: nominal stress maximum (Considere) at lam = 1.2422,
  strongly elliptic along the plane-strain tension path to lam = 1.5 (it
  loses ellipticity at lam = 1.60, shear bands at 32 degrees to the axis).
"""

import numpy as np
import pytest
from scipy.interpolate import CubicHermiteSpline

from shellritz.discretize.line import GAUSS_POINTS
from shellritz.discretize.planestrain import PlaneStrainShell
from shellritz.necking import (considere_stretch, default_law, e1d_energy, end_force,
                               engine_inertia, engine_onset, follow_neck, homogeneous_state,
                               necking_strip, onset_stretch, path_landmarks, plane_strain_tension)


def _x0_fields(length):
    """Non-uniform x0 fields (value, slope functions) of symmetric necks."""
    def field(lam, amps):
        def x0(X):
            return lam * X + sum(a * length * np.sin(k * np.pi * X / length) for k, a in amps)

        def dx0(X):
            return lam + sum(a * k * np.pi * np.cos(k * np.pi * X / length) for k, a in amps)
        return x0, dx0
    return [field(1.1, [(1, 0.02), (4, 0.005)]), field(1.25, [(1, -0.03), (3, 0.008)]),
            field(1.4, [(2, 0.02), (5, -0.004)])]


@pytest.mark.parametrize("level", ["consistent", "bending"])
def test_engine_energy_equals_e1d(level):
    law = default_law()
    h, length, N = 0.15, 1.0, 0.07
    s = length * np.linspace(0, 1, 13) ** 1.3          # graded, non-uniform mesh
    straight = lambda s: (s.copy(), np.zeros_like(s), np.ones_like(s), np.zeros_like(s))
    # independent quadrature: the same Gauss rule per element, x0 from a
    # SciPy Hermite spline through the same nodal values and slopes
    xg, wg = np.polynomial.legendre.leggauss(GAUSS_POINTS)
    for x0, dx0 in _x0_fields(length):
        eng = PlaneStrainShell(s, straight, h, law, level)
        eng.edge_load(0, (-N * h, 0.0)).edge_load(-1, (N * h, 0.0))
        eng._setup()
        eng.set_parameter(1.0)
        U = np.zeros((len(s), 4))
        U[:, 0], U[:, 1] = x0(s), dx0(s)
        # the engine's energy is the model's plus the h^5 strain-gradient
        # term of docs/validity.md (not part of E_1d): compare the model's
        E_engine = eng.evaluate(U.reshape(-1)[eng.free], 0)[0] - eng.strain_gradient.evaluate(U.reshape(-1), 0)[0]
        spline = CubicHermiteSpline(s, x0(s), dx0(s))
        Xq = np.concatenate([s[e] + 0.5 * (xg + 1) * (s[e + 1] - s[e]) for e in range(len(s) - 1)])
        wq = np.concatenate([0.5 * wg * (s[e + 1] - s[e]) for e in range(len(s) - 1)])
        lam, dlam = spline(Xq, 1), spline(Xq, 2)
        E_1d = e1d_energy(law, h, lam, dlam, wq, N)
        E_membrane = e1d_energy(law, h, lam, 0 * dlam, wq, N)
        assert abs(E_engine - E_1d) <= 1e-14 * abs(E_1d)
        # the gradient term is 1e-4..1e-3 of the total, so the round-off of the
        # totals (a few ulps) limits its check to ~1e-12 relative
        assert abs(E_1d - E_membrane) > 1e-4 * abs(E_1d)
        assert abs((E_engine - E_membrane) - (E_1d - E_membrane)) <= 1e-10 * abs(E_1d - E_membrane)


def test_power_law_plane_strain_force_maximum_and_ellipticity():
    law = default_law()
    lam_c = considere_stretch(law)
    assert lam_c == pytest.approx(1.242222, abs=1e-6)
    lams = np.linspace(1.001, 1.5, 60)
    states = [plane_strain_tension(law, lam) for lam in lams]
    w1 = np.array([st.w1 for st in states])
    imax = int(np.argmax(w1))
    assert 0 < imax < len(lams) - 1 and abs(lams[imax] - lam_c) < 0.02
    assert np.all(np.diff(w1[: imax]) > 0) and np.all(np.diff(w1[imax + 1:]) < 0)
    for st in states:
        assert abs(law.evaluate(np.diag([st.lam, 1.0, st.z1]))[1][2, 2]) < 1e-12   # faces free
        # strong ellipticity: (a x N) : AA : (a x N) > 0 for unit a, N (a grid of directions)
        AA = law.evaluate(np.diag([st.lam, 1.0, st.z1]))[2].reshape(3, 3, 3, 3)
        u = np.random.default_rng(0).standard_normal((400, 3))
        u /= np.linalg.norm(u, axis=1)[:, None]
        Q = np.einsum("iJkL,nJ,nL->nik", AA, u, u)          # acoustic tensors
        assert np.linalg.eigvalsh(Q).min() > 0


def test_onset_analysis_is_considere_corrected_by_the_gradient_term():
    law = default_law()
    lam_m = considere_stretch(law)
    d = [onset_stretch(law, r) - lam_m for r in (0.025, 0.05, 0.1)]
    assert all(x > 0 for x in d)
    # the correction is O((h/l)^2): ratio 4 per doubling of h/l at small h/l
    assert d[1] / d[0] == pytest.approx(4.0, rel=0.01)
    assert d[2] / d[1] == pytest.approx(4.0, rel=0.05)
    st = plane_strain_tension(law, onset_stretch(law, 0.1))
    assert st.w2 + (np.pi * 0.1) ** 2 / 12 * st.C == pytest.approx(0.0, abs=1e-12)
    # mode 2 goes unstable later
    assert onset_stretch(law, 0.1, mode=2) > onset_stretch(law, 0.1)


def _onset_check(h_over_l, n=20):
    law = default_law()
    lam_c = onset_stretch(law, h_over_l)
    lam_e, n_hi, gmax = engine_onset(law, h_over_l, 1.0, n, considere_stretch(law), lam_c + 2e-3)
    assert gmax < 1e-13            # the homogeneous path is an exact equilibrium of the engine
    return lam_e - lam_c


def test_engine_onset_matches_e1d_analysis():
    # observed 6e-10 (20 elements; 1.1e-8 with 10, 1.8e-7 with 5: fourth order)
    assert abs(_onset_check(0.1)) < 1e-7


@pytest.mark.slow
@pytest.mark.parametrize("h_over_l", [0.05, 0.1, 0.2])
def test_engine_onset_sweep(h_over_l):
    # observed 1.6e-10, 6.1e-10, 3.1e-9
    assert abs(_onset_check(h_over_l)) < 1e-7


def test_solver_follows_the_homogeneous_path_and_reports_the_instability():
    """The engine's own continuation along the displacement-controlled path
    stays homogeneous and its final inertia agrees with engine_inertia."""
    law = default_law()
    h, n = 0.1, 10
    lam_c = onset_stretch(law, h)
    for lam, stable in ((lam_c - 2e-3, True), (lam_c + 2e-3, False)):
        eng = necking_strip(law, h, 1.0, n, lam)
        # first step: end element stretched to about 1 + 0.12 (well before the
        # Considere maximum; from a first step past it the Newton iteration escapes
        # into the spurious short-wave bending modes of docs/necking.md)
        res = eng.solve(steps=20, verbose=False, escape=False)     # report, do not leave
        # homogeneous to the solver's tolerance (rtol 1e-9 of the force of
        # each step's increment of t, dt |dg/dt|: observed 6e-10 on a strip
        # of length 1; 1e-12 while the tolerance referred to the gradient
        # at the start of a secant-predicted step); a neck would be O(1e-2)
        assert np.abs(eng.free_state() - homogeneous_state(eng, lam)).max() < 1e-8
        assert res.history.stable == stable
        assert res.history.unstable_modes == engine_inertia(law, h, 1.0, n, lam)[0]


def test_engine_derivatives_with_the_power_law_at_a_neck():
    """Gradient and Hessian of the engine with the new law against central
    differences at a necked, bent state (observed 1e-9 / 1e-8 relative)."""
    law = default_law()
    eng = necking_strip(law, 0.1, 1.0, 6, 1.2)
    eng._setup()
    eng.set_parameter(1.0)
    x = homogeneous_state(eng, 1.2)
    rng = np.random.default_rng(1)
    x = x + 0.01 * rng.standard_normal(len(x))
    E, g, K = eng.evaluate(x, 2)
    Kf = K.toarray()
    Kf = Kf + np.tril(Kf, -1).T
    v = rng.standard_normal(len(x))
    eps = 1e-6
    Ep, gp, _ = eng.evaluate(x + eps * v, 1)
    Em, gm, _ = eng.evaluate(x - eps * v, 1)
    assert (Ep - Em) / (2 * eps) == pytest.approx(g @ v, rel=1e-7)
    assert np.abs((gp - gm) / (2 * eps) - Kf @ v).max() <= 1e-6 * np.abs(Kf @ v).max()


@pytest.mark.slow
def test_2d_solid_onset_converges_to_the_exact_incremental_solution():
    """bench/necking_2d.py: the scikit-fem Q2 block's onset (stiffness
    inertia) against the exact separable solution (observed at h/l = 0.2:
    3.3e-6, 2.5e-7 with 2, 4 elements across h/2), and the exact 2D onset
    against E_1d (fourth order in h/l: 1.6e-5 at 0.2, 1.0e-6 at 0.1)."""
    pytest.importorskip("skfem")
    import sys
    from pathlib import Path
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "bench"))
    from necking_2d import exact_onset, fe_onset
    law = default_law()
    exact = exact_onset(law, 0.2)
    errors = [abs(fe_onset(law, 0.2, nz)[0] - exact) for nz in (2, 4)]
    assert errors[1] < 5e-7 and errors[0] / errors[1] > 8
    d = [abs(onset_stretch(law, r) - exact_onset(law, r)) for r in (0.1, 0.2)]
    assert d[1] < 3e-5 and 12 < d[1] / d[0] < 20


def test_engine_arc_length_passes_the_force_maximum_and_the_snap_back():
    """The solver's arc length on the imperfect block (16 elements, h/l =
    0.2, the example's case on a coarser mesh, 23 arc steps): the force maximum,
    the fold where the end stretch turns back (the neck snaps back), the
    stability change there, and a continuous path.  Observed: fold sampled at
    1.2305 (2D solid 1.23060), force maximum N/h = 0.091462 (2D 0.091474),
    energy-work mismatch per step <= 2.1e-4 F_max l (7e-3 measured across a
    jump of the corrector to another branch on a 10-element mesh), thickness
    change per step <= 0.06 h."""
    law = default_law()
    h = 0.2
    eng = necking_strip(law, h, 1.0, 16, 1.3, imperfection=1e-3, symmetric=True)
    rows, stop = follow_neck(eng, steps=30, max_steps=23)
    assert "not reached in 23 steps" in stop
    lam, F, t_min, E = (np.array([r[k] for r in rows]) for k in ("lam", "force", "t_min", "energy"))
    negative = [r["negative"] for r in rows]
    marks = path_landmarks(lam, F, t_min, np.ones(len(rows)))
    kf, km = marks["fold"]["index"], marks["force_max"]["index"]
    # the end stretch rises to the fold and falls after it; the force has its
    # maximum at or before the fold; the neck deepens all along
    assert np.all(np.diff(lam[:kf + 1]) > 0) and np.all(np.diff(lam[kf:]) < 0)
    assert lam[kf] - lam[-1] > 0.04 and km <= kf
    assert np.all(np.diff(F[:km + 1]) > 0) and np.all(np.diff(F[km:]) < 0)
    assert np.all(np.diff(t_min) < 0)
    assert abs(lam[kf] - 1.23060) < 2e-3 and abs(F[km] / h - 0.091474) < 5e-5     # as sampled
    # displacement control: stable up to the fold, one unstable mode past it
    assert all(k == 0 for k in negative[:kf]) and all(k == 1 for k in negative[kf + 1:])
    # continuity: the energy change between path points is the work of the
    # end force (trapezoid; a jump to another branch breaks it), and no
    # section jumps
    work = 0.5 * (F[1:] + F[:-1]) * np.diff(lam)
    assert np.abs(np.diff(E) - work).max() < 1e-3 * F.max()
    th = np.array([r["thickness"] for r in rows])
    assert np.abs(np.diff(th, axis=0)).max() < 0.1 * h
    # a path point on the stable branch is the displacement-controlled equilibrium
    k = km - 1
    ref = necking_strip(law, h, 1.0, 16, lam[k], imperfection=1e-3, symmetric=True)
    ref.solve(steps=20, verbose=False)
    assert end_force(ref) == pytest.approx(F[k], rel=1e-8)
    assert h * np.linalg.norm(ref.Y1, axis=1).min() == pytest.approx(t_min[k], rel=1e-8)


@pytest.mark.slow
def test_necking_example(tmp_path, capsys):
    """examples/necking.py (about 2 min): the shell engine's arc-length path
    (20 and 40 elements) against the 2D solid past the force maximum and
    through the snap-back, up to the loss of strong ellipticity."""
    import importlib.util
    from pathlib import Path
    path = Path(__file__).resolve().parent.parent / "examples" / "necking.py"
    spec = importlib.util.spec_from_file_location("necking_example", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    out = module.main(tmp_path)
    assert (tmp_path / "necking.png").stat().st_size > 10000
    solid = out["solid"]["landmarks"]
    h = out["h"]
    for sh in out["shell"]:
        assert sh["stop"].startswith("reached the end stretch")
        marks, path = sh["landmarks"], sh["path"]
        # observed (20 / 40 elements; 2D): force maximum N/h 0.0914793 / 0.0914777
        # (0.0914792), fold 1.23060 / 1.23187 (1.23067; located to ~1e-3 by the
        # sampling of the path near it), ellipticity lost in the neck at t_min
        # 0.640 h (the 2D criterion, over the whole section, at 0.657 h)
        assert marks["force_max"]["force"] == pytest.approx(solid["force_max"]["force"], rel=1e-4)
        assert marks["fold"]["lam"] == pytest.approx(solid["fold"]["lam"], abs=2e-3)
        assert 0.635 < marks["ellipticity_loss"]["t_min"] / h < 0.645 < solid["ellipticity_loss"]["t_min"] / h
        # the inertia changes exactly at the folds of the end stretch (the
        # sampled extreme itself lies on either side of the fold)
        kf, ks = marks["fold"]["index"], marks["second_fold"]["index"]
        negative = [p["negative"] for p in path]
        assert set(negative[:kf]) == {0} and set(negative[kf + 1:ks]) == {1}
        assert set(negative[ks + 1:]) == {0}
        # against the 2D solid (observed: force 6.4e-7 F_max and section 4.2e-5 h
        # at equal stretch before the maximum; end stretch 1.4e-4 down to
        # 0.71 h, 5.1e-4 at 0.68 h and force 5.3e-4 F_max at equal section past it)
        rising = [d for d in sh["vs_2d"] if d["part"] == "rising"]
        past = [d for d in sh["vs_2d"] if d["part"] != "rising"]
        assert len(rising) >= 8 and len(past) >= 5
        assert max(abs(d["d_force"]) for d in rising) < 1e-6
        assert max(abs(d["d_t_min"]) for d in rising) < 1e-4
        assert max(abs(d["d_lam"]) for d in past if d["t_min"] > 0.7 * h) < 3e-4
        assert max(abs(d["d_lam"]) for d in past) < 1.5e-3
        assert max(abs(d["d_force"]) for d in past) < 1e-3
    # past the loss of ellipticity the shell path localizes onto the mesh:
    # second fold 1.0935 / 1.0789, neck stretch at the end 16.6 / 32.8
    coarse, fine = out["shell"]
    assert coarse["landmarks"]["second_fold"]["lam"] - fine["landmarks"]["second_fold"]["lam"] > 0.01
    assert 1.8 < fine["path"][-1]["stretch_max"] / coarse["path"][-1]["stretch_max"] < 2.2
def test_end_reaction_and_per_node_constraints():
    """LineShell.end_reaction at the homogeneous stretched state is the
    plane-strain nominal stress times h (and minus it at the other end);
    fix_node checks its input.  Solved to rtol 1e-12: at the default 1e-9 a
    load step may end without a Newton step on a state whose stretch is off
    by 2e-10 (observed), which the checks below at 1e-10 would catch."""
    law = default_law()
    h, lam = 0.1, 1.2
    eng = necking_strip(law, h, 1.0, 6, lam, symmetric=True)
    eng.solve(steps=10, verbose=False, rtol=1e-12)
    w1 = plane_strain_tension(law, lam).w1
    assert eng.end_reaction(-1)[0] == pytest.approx(h * w1, rel=1e-10)
    assert eng.end_reaction(0)[0] == pytest.approx(-h * w1, rel=1e-10)
    assert abs(eng.end_reaction(-1)[1]) < 1e-12 * h * w1
    assert eng.U.reshape(-1, 4)[:, 1] == pytest.approx(np.full(7, lam), rel=1e-10)    # a' = lam
    with pytest.raises(ValueError, match="node 7 out of range"):
        eng.fix_node(7, ["b"])
    with pytest.raises(ValueError, match="dofs"):
        eng.fix_node(2, ["c"])
    with pytest.raises(ValueError, match="values"):
        eng.fix_node(2, ["a", "b"], [1.0])


def test_clear_errors():
    from shellritz import NeoHookean
    with pytest.raises(ValueError, match="no maximum"):
        considere_stretch(NeoHookean(1.0, nu=0.3))
    with pytest.raises(ValueError, match="positive"):
        plane_strain_tension(default_law(), -1.0)
    with pytest.raises(ValueError, match="bracket"):
        engine_onset(default_law(), 0.1, 1.0, 10, 1.3, 1.4)


def test_engine_unstable_mode_is_the_first_necking_mode():
    """Just past the onset the engine's one negative Hessian eigenvector is
    x0 ~ sin(pi X / l), i.e. the stretch perturbation cos(pi X / l), with no
    bending part (observed correlation 1 - 1e-10 at 1e-6 past the onset)."""
    from shellritz.linalg import symmetric_from_lower
    law = default_law()
    lam = onset_stretch(law, 0.1) + 1e-6
    eng = necking_strip(law, 0.1, 1.0, 20, lam)
    eng._setup()
    eng.set_parameter(1.0)
    _, _, K = eng.evaluate(homogeneous_state(eng, lam), 2)
    ev, V = np.linalg.eigh(symmetric_from_lower(K).toarray())
    assert ev[0] < 0 < ev[1]
    mode = np.zeros(4 * eng.n_nodes)
    mode[eng.free] = V[:, 0]
    a, da, b, db = mode.reshape(-1, 4).T
    s = eng.s
    assert np.abs(np.r_[b, db]).max() < 1e-8 * np.abs(a).max()
    shape = np.r_[np.sin(np.pi * s), np.pi * np.cos(np.pi * s)]    # values and slopes
    corr = abs(np.r_[a, da] @ shape) / (np.linalg.norm(np.r_[a, da]) * np.linalg.norm(shape))
    assert corr > 1 - 1e-8
