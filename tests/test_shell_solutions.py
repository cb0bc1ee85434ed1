"""Solved scenes on triangulated surfaces against exact solutions (MODEL.md 7).

Observed (see the assertions):
* gradient-growth strip rolled into a full circle (eq:x0z0asy): max error
  0.26, 0.026, 2.3e-3, 2.2e-4 for 10, 20, 40, 80 elements along the half
  strip (about a factor 10 per halving);
* growing cylinder under outer traction: mesh error O(n^-2) (ratio 3.98-4.00);
  the mesh-extrapolated radius (Richardson, n = 128, 256, 512) matches the
  1D shell value to 2e-9 and the error against eq:r0ex falls by 15.9-16.0 per
  halving of h = 0.2 ... 0.025 (fourth order; at least third is required);
* with Shell(membrane="regge"): strip errors 2.8e-3, 8.8e-5, 8.9e-5, 3.5e-6
  at 20, 40, 80, 160 (below the DKT metric's, not at a steady rate); thin
  cylinder (h = 0.01) second order, ratios 3.99-4.00, errors 10-20 % below
  the DKT metric's;
* clamped / simply supported square plates under uniform pressure (nu = 0.3):
  centre deflection within 0.7 % / 0.4 % of the classical coefficients on a
  16 x 16 mesh, errors falling like the mesh size squared, on structured and
  randomly perturbed meshes alike;
* the same plates under a central point load: from above (the DKT bending
  is softer than Kirchhoff's plate), 0.35-0.74 % at 16 x 16, 0.035-0.089 %
  at 64 x 64, errors falling 2.9-3.2 per halving;
* cantilever strip with an end rotation of 2 pi: a closed circle of radius
  L / 2 pi (0.06 % at 64 elements).
"""

import sys
from pathlib import Path

import numpy as np
import pytest

from shellritz import CubicStretch, LinearIsotropic, NeoHookean, Shell, shapes

sys.path.insert(0, str(Path(__file__).parent))
from test_closed_forms import exact_cylinder_r0, shell_cylinder_r0  # noqa: E402

# ---------------------------------------------------------------------------
# gradient-growth strip
# ---------------------------------------------------------------------------

G0S, G1S, HS, DS = 1.2, 2.0, 0.02, 2.0


def strip_error(nx, level="consistent", perturb=0.0, membrane="dkt"):
    half = np.pi / G1S          # half length: the strip closes into a full circle
    mesh = shapes.rectangle(nx, 2, lx=half, ly=0.1, origin=(0, -0.05), perturb=perturb, seed=1)
    s = Shell(mesh, HS, NeoHookean(1.0, D=DS), level=level, membrane=membrane)
    s.set_growth(G0=np.diag([G0S, 1, 1]), G1=np.diag([G1S, 0, 0]))
    s.symmetry("x", 0.0)
    s.pin(mesh.nodes_where(lambda X: (np.abs(X[:, 0]) < 1e-12) & (np.abs(X[:, 1]) < 1e-12)))
    s.pin(mesh.nodes_on_plane("x", 0.0), components="z")     # no rigid rotation about x
    res = s.solve(steps=8, verbose=False)
    X = mesh.vertices
    x0 = G0S / G1S * np.sin(G1S * X[:, 0])
    z0 = G0S / G1S * (np.cos(G1S * X[:, 0]) - 1)
    return np.sqrt((res.r[:, 0] - x0) ** 2 + (res.r[:, 2] - z0) ** 2 + (res.r[:, 1] - X[:, 1]) ** 2).max()


def test_strip_rolls_into_the_exact_circle():
    errors = [strip_error(nx) for nx in (20, 40, 80)]
    assert errors[-1] < 3e-4, errors                  # radius 0.6: 0.04 %
    assert errors[0] / errors[1] > 6 and errors[1] / errors[2] > 6, errors


@pytest.mark.filterwarnings("ignore::shellritz.validity.ValidityWarning")
def test_strip_with_the_regge_metric_converges():
    """Shell(membrane="regge"): errors 2.8e-3, 8.8e-5, 8.9e-5, 3.5e-6 at 20,
    40, 80, 160 (DKT metric 2.6e-2, 2.3e-3, 2.2e-4, 1.8e-5; at 160 the
    triangles are thinner than h / 2 and take beta = 1, discretize/regge.py:
    8.8e-6 before): below the
    DKT metric's at every mesh but not at a steady rate: the blend beta =
    2h/l_e rises from 0.43 to 0.78 over these meshes, and the plain cubic's
    metric, O(l^2) accurate, takes over from the Regge field's O(l^4) (with
    beta = 0: 3.0e-4, 2.1e-5 at 20, 40, but then the in-plane rotation of
    the nodal gradients has no stiffness and the solve at 80 fails).  At 160
    the elements are shorter than h: the validity diagnostic warns of the
    strain-gradient share, as with the DKT metric, the rolled state being
    almost stress free (ignored here)."""
    errors = [strip_error(nx, membrane="regge") for nx in (20, 40, 80, 160)]
    assert errors[0] / errors[1] > 20 and errors[1] < 1e-4 and errors[2] < 1e-4, errors
    assert errors[3] < 5e-6, errors


def test_strip_on_a_perturbed_mesh_converges_too():
    errors = [strip_error(nx, perturb=0.3) for nx in (20, 40)]
    assert errors[1] < 5e-3 and errors[0] / errors[1] > 4, errors


# ---------------------------------------------------------------------------
# growing cylinder under outer traction (paper section 5.1)
# ---------------------------------------------------------------------------

GAMMA, QN = 1.2, 0.3          # q+ = QN h: net normal traction O(h)


def cylinder_radius(h, n, membrane="dkt", spread=0.05):
    """Quarter ring of n square elements, symmetry planes x, y, z = 0, z = L;
    the nodal radii may differ by spread / n^2 (relative standard deviation)."""
    Lz = np.pi / 2 / n
    mesh = shapes.cylinder(n, 1, radius=1.0, length=Lz, theta=(0, np.pi / 2))
    s = Shell(mesh, h, CubicStretch(1.0), membrane=membrane)
    ez = np.array([0, 0, 1.0])
    s.set_growth(G0=GAMMA * (np.eye(3) - np.outer(ez, ez)) + np.outer(ez, ez))
    s.face_tractions(q_plus=lambda X, N: QN * h * N)
    s.symmetry("x").symmetry("y").symmetry("z", 0.0).symmetry("z", Lz)
    res = s.solve(steps=8, verbose=False, rtol=1e-12)
    radius = np.hypot(res.r[:, 0], res.r[:, 1])
    assert radius.std() < spread / n ** 2 * radius.mean()     # node-to-node mesh error
    return radius.mean()


def test_cylinder_mesh_convergence_at_fixed_h():
    h = 0.1
    one_d = shell_cylinder_r0(GAMMA, QN * h, h)
    err = [abs(cylinder_radius(h, n) - one_d) for n in (16, 32, 64, 128)]
    ratios = [err[k] / err[k + 1] for k in range(3)]
    assert all(3.8 < r < 4.2 for r in ratios), (err, ratios)


def test_cylinder_mesh_convergence_with_the_regge_metric():
    """h = 0.01, so that the regge metric is not the plain cubic's (beta =
    2h/l_e = 0.07, 0.14, 0.28 at n = 8, 16, 32; at h = 0.1 beta = 1 on these
    meshes): errors 1.51e-3, 3.77e-4, 9.44e-5, 2.36e-5 for n = 8 ... 64,
    ratios 3.99, 4.00, 4.00 (DKT metric: 1.86e-3, 4.53e-4, 1.04e-4, 2.33e-5):
    second order."""
    h = 0.01
    one_d = shell_cylinder_r0(GAMMA, QN * h, h)
    err = [abs(cylinder_radius(h, n, "regge", spread=0.2) - one_d) for n in (8, 16, 32)]
    ratios = [err[k] / err[k + 1] for k in range(2)]
    assert err[-1] < 1e-4 and all(3.9 < r < 4.1 for r in ratios), (err, ratios)


def test_cylinder_error_against_exact_3d_solution_falls_with_h():
    errors = []
    for h in (0.2, 0.1, 0.05, 0.025):
        r = np.array([cylinder_radius(h, n) for n in (128, 256, 512)])
        r1 = (4 * r[1:] - r[:-1]) / 3            # Richardson: n^-2, then n^-4
        r_mesh_converged = (16 * r1[1] - r1[0]) / 15
        # the 1D solution of the same energy: 2e-9 before issue 14; the DKT
        # discretization of the h^5 strain-gradient term (zero for this uniform
        # state in the continuum) leaves 5e-8 at h = 0.2, falling like h^5
        assert abs(r_mesh_converged - shell_cylinder_r0(GAMMA, QN * h, h)) < 3e-9 + 1e-7 * (h / 0.2) ** 5, h
        errors.append(abs(r_mesh_converged - exact_cylinder_r0(GAMMA, QN * h, h)[2]))
    ratios = [errors[k] / errors[k + 1] for k in range(3)]
    # at least third order (ratio 8) is required; fourth (16) is observed
    assert all(14.0 < r < 18.0 for r in ratios), (errors, ratios)


# ---------------------------------------------------------------------------
# linear plates (Kirchhoff limit)
# ---------------------------------------------------------------------------

E_, NU_, H_, Q_ = 1.0, 0.3, 0.01, 1e-7
PLATE_REF = {"clamped": 0.00126532, "simply_support": 0.00406235}   # w D / (q a^4)


def plate_coefficient(bc, n, perturb=0.0):
    lam, mu = E_ * NU_ / ((1 + NU_) * (1 - 2 * NU_)), E_ / (2 * (1 + NU_))
    mesh = shapes.rectangle(n, n, perturb=perturb, seed=2)
    s = Shell(mesh, H_, LinearIsotropic(lam, mu))
    getattr(s, "clamp" if bc == "clamped" else bc)(mesh.boundary_nodes())
    s.face_tractions(q_plus=[0, 0, Q_])
    res = s.solve(verbose=False)
    c = np.argmin(np.linalg.norm(mesh.vertices - [0.5, 0.5, 0], axis=1))
    D = E_ * H_ ** 3 / (12 * (1 - NU_ ** 2))
    return res.displacement[c, 2] * D / Q_


@pytest.mark.parametrize("bc", ["clamped", "simply_support"])
@pytest.mark.parametrize("perturb", [0.0, 0.3])
def test_square_plate_centre_deflection(bc, perturb):
    err = [abs(plate_coefficient(bc, n, perturb) / PLATE_REF[bc] - 1) for n in (8, 16, 32)]
    assert err[1] < 0.01, err                         # within 1 % on a 16 x 16 mesh
    assert all(3.0 < err[k] / err[k + 1] < 4.5 for k in range(2)), err


POINT_REF = {"clamped": 0.0056112, "simply_support": 0.0116008}    # w D / (P a^2)


def point_load_coefficient(bc, n):
    lam, mu = E_ * NU_ / ((1 + NU_) * (1 - 2 * NU_)), E_ / (2 * (1 + NU_))
    mesh = shapes.rectangle(n, n)
    s = Shell(mesh, H_, LinearIsotropic(lam, mu))
    getattr(s, "clamp" if bc == "clamped" else bc)(mesh.boundary_nodes())
    c = np.argmin(np.linalg.norm(mesh.vertices - [0.5, 0.5, 0], axis=1))
    D = E_ * H_ ** 3 / (12 * (1 - NU_ ** 2))
    P = 1e-3 * D
    s.point_force([c], [0, 0, -P])
    res = s.solve(verbose=False)
    return -res.displacement[c, 2] * D / P


@pytest.mark.parametrize("bc", ["clamped", "simply_support"])
def test_point_loaded_plate_converges_from_above(bc):
    """The DKT bending is softer than the Kirchhoff plate under a point load
    and converges from above (observed w / w_exact: clamped 1.0074, 1.0025,
    1.00089, simply supported 1.0035, 1.0011, 1.00035 at n = 16, 32, 64;
    ratios of the errors 2.9-3.2).  This is why the pinched cylinder
    converges from above once its membrane does not lock (README, Membrane
    locking: regge +0.36 % / +0.18 % off the common limit, about 1.0017 of
    the reference, at n = 32 / 64)."""
    err = [point_load_coefficient(bc, n) / POINT_REF[bc] - 1 for n in (16, 32, 64)]
    assert all(e > 0 for e in err), err
    assert err[0] < 0.01, err
    assert all(2.5 < err[k] / err[k + 1] < 4.0 for k in range(2)), err


# ---------------------------------------------------------------------------
# cantilever rolled into a circle by a prescribed end rotation of 2 pi
# ---------------------------------------------------------------------------

def test_cantilever_rolls_into_a_closed_circle():
    L, h = 1.0, 0.01
    mesh = shapes.rectangle(64, 1, lx=L, ly=0.05)
    s = Shell(mesh, h, NeoHookean(1.0, nu=0.0))
    s.clamp(mesh.nodes_on_plane("x", 0.0))
    end = mesh.nodes_on_plane("x", L)
    s.rotate(end, rotation=[0, -2 * np.pi, 0])
    res = s.solve(steps=16, verbose=False)
    R = L / (2 * np.pi)
    dist = np.hypot(res.r[:, 0], res.r[:, 2] - R)
    assert np.abs(dist / R - 1).max() < 1e-3          # a circle of radius L / 2 pi
    assert np.linalg.norm(res.r[end][:, [0, 2]], axis=1).max() < 1e-5   # closed
