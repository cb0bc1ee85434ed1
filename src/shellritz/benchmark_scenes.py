"""Benchmark scenes of the solver: limit points, snap-through, stability.

Each function returns an engine ready to solve (``engine.solve(...)``) with
the literature's data; units are those of the reference (consistent, any
system).

* :func:`snapping_cap` -- a clamped shallow spherical cap under external
  pressure snaps through and ends inverted (axisymmetric engine).
* :func:`pulled_cylinder` -- Sze, Liu & Lo (2004), section 3.5: an
  open-ended cylinder pulled by two opposite radial point loads; the
  load-deflection curve has a sharp turn near P = 20 000 (DKT engine,
  one eighth of the cylinder).  :func:`pulled_cylinder_monitor` gives the
  radial displacements at the paper's points A, B, C.

Scenes of the solver's stability map (bench/stability_map.py), each a hard
case for one reason:

* :func:`thin_panel` -- a very thin (h/R = 1e-3) clamped cylindrical panel
  bent by a normal load (ill-conditioned: membrane/bending stiffness ratio
  (R/h)^2 = 1e6);
* :func:`inflated_disc` -- a clamped disc of nearly incompressible material
  (nu = 0.499) inflated by a follower pressure;
* :func:`grown_strip` -- a strip clamped at both ends that grows to twice its
  length and buckles into an arch (growth stretch 2, a bifurcation on the
  way).
"""

import numpy as np

from . import shapes
from .discretize.axisym import AxisymmetricShell
from .materials import NeoHookean, StVenantKirchhoff
from .shell import Shell

__all__ = ["snapping_cap", "cap_critical_pressure", "pulled_cylinder", "pulled_cylinder_monitor",
           "PULLED_CYLINDER", "PULLED_CYLINDER_REFERENCE", "thin_panel", "inflated_disc", "grown_strip"]


def cap_critical_pressure(h, R, nu):
    """Classical buckling pressure of a complete sphere, p_cl = 2 E /
    sqrt(3 (1 - nu^2)) (h/R)^2 with the small-strain Young's modulus of
    the neo-Hookean law of unit shear modulus, E = 2 (1 + nu)."""
    E = 2.0 * (1.0 + nu)
    return 2.0 * E / np.sqrt(3.0 * (1.0 - nu ** 2)) * (h / R) ** 2


def snapping_cap(n=40, h=0.02, alpha=0.3, R=1.0, nu=0.3, factor=1.0, level="consistent"):
    """Clamped shallow spherical cap (radius R, half-opening angle alpha
    radians, thickness h; neo-Hookean, shear modulus 1, Poisson's ratio nu)
    under an external pressure ramped to ``factor`` times the classical
    pressure of the complete sphere (:func:`cap_critical_pressure`).

    The meridian runs from the apex (s = 0, node 0) to the clamped rim
    (s = alpha), n elements.  The cap's geometric parameter (Budiansky 1959;
    Huang 1964, the classical snap-through problem of clamped shallow caps)
    is lambda = (12 (1 - nu^2))^(1/4) sqrt(R/h) alpha = 3.86 for the
    defaults.  ``solve(path="arclength", monitor=[0])`` records the apex
    position (r, z); the apex moves up (+z) into the sphere as the cap
    inverts.

    Measured (``solve(steps=5, path="arclength")``): limit t = 0.5856 (40
    elements) / 0.5853 (80), snap back to t = 0.479, inertia 0 -> 1 -> 0
    around the unstable branch, stable inverted at t = 1 with an apex
    displacement 0.0813 = 1.82 cap heights R (1 - cos alpha).
    """
    eng = AxisymmetricShell.sphere(n, R, h, NeoHookean(1.0, nu=nu), level=level, s_range=(0.0, alpha))
    eng.clamp(-1)
    eng.pressure(-factor * cap_critical_pressure(h, R, nu))
    return eng


# Sze, Liu & Lo, Finite Elements in Analysis and Design 40 (2004) 1551-1569, section 3.5
PULLED_CYLINDER = dict(R=4.953, L=10.35, h=0.094, E=10.5e6, nu=0.3125, P=40000.0)

# Sze et al.'s reference table (their 24 x 36 S4R mesh of the octant) as
# transcribed in MBDyn's test suite (tests/plates/sze2004/sze35/sze35_ref.dat):
# columns P / P_max, w_A, -u_B, -u_C
PULLED_CYLINDER_REFERENCE = np.array([
    [0.00, 0.000, 0.000, 0.000], [0.025, 0.819, 0.864, 0.872], [0.05, 1.260, 1.471, 1.493],
    [0.075, 1.527, 1.901, 1.946], [0.10, 1.707, 2.217, 2.293], [0.15, 1.936, 2.641, 2.792],
    [0.20, 2.079, 2.904, 3.106], [0.25, 2.180, 3.087, 3.310], [0.30, 2.257, 3.227, 3.452],
    [0.35, 2.321, 3.342, 3.556], [0.40, 2.376, 3.443, 3.632], [0.45, 2.425, 3.539, 3.688],
    [0.50, 2.473, 3.653, 3.718], [0.525, 2.543, 4.061, 3.580], [0.55, 2.577, 4.171, 3.518],
    [0.60, 2.618, 4.274, 3.452], [0.65, 2.648, 4.338, 3.410], [0.70, 2.672, 4.385, 3.378],
    [0.75, 2.692, 4.423, 3.353], [0.80, 2.710, 4.455, 3.332], [0.85, 2.726, 4.483, 3.313],
    [0.90, 2.741, 4.508, 3.297], [0.95, 2.755, 4.530, 3.283], [1.00, 2.768, 4.551, 3.269]])


def _cylinder_points(R, L):
    """Reference positions of the paper's points in the octant model: A the
    load point (mid-length, on the load line), B the mid-length point and C
    the free-edge point 90 degrees from it."""
    return np.array([[0.0, R, 0.0], [R, 0.0, 0.0], [R, 0.0, L / 2]])


def pulled_cylinder(n_theta=8, n_z=None, level="consistent", membrane="dkt"):
    """Pull-out of an open-ended cylindrical shell (Sze, Liu & Lo 2004,
    section 3.5): radius R = 4.953, length L = 10.35, thickness h = 0.094,
    E = 10.5e6, nu = 0.3125 (Saint Venant-Kirchhoff), ends free, two
    opposite radial point loads P (P_max = 40 000 at t = 1) at mid-length
    pull it apart.

    One eighth is modelled: the quarter circle theta in [0, pi/2] (x = R
    cos theta, y = R sin theta) times z in [0, L/2], n_theta x n_z grid
    cells (two triangles each; n_z defaults to n_theta), with the symmetry
    planes x = 0, y = 0 and z = 0 (mid-length); the free edge is z = L/2.
    The load point A = (0, R, 0) lies on two of the planes and carries P/4
    along +y.  :func:`pulled_cylinder_monitor` returns the radial
    displacements (w_A, u_B, u_C) (B = (R, 0, 0), C = (R, 0, L/2)); the
    paper tabulates w_A, -u_B, -u_C against P (PULLED_CYLINDER_REFERENCE).
    """
    d = PULLED_CYLINDER
    n_z = n_theta if n_z is None else n_z
    mesh = shapes.cylinder(n_theta, n_z, radius=d["R"], length=d["L"] / 2, theta=(0.0, np.pi / 2))
    shell = Shell(mesh, d["h"], StVenantKirchhoff.from_young(d["E"], d["nu"]), level=level,
                  membrane=membrane)
    shell.symmetry("x", 0.0).symmetry("y", 0.0).symmetry("z", 0.0)
    a = _nearest(mesh.vertices, _cylinder_points(d["R"], d["L"])[0])
    shell.point_force([a], [0.0, d["P"] / 4, 0.0])
    return shell


def _nearest(X, point):
    return int(np.argmin(np.linalg.norm(X - point, axis=1)))


def pulled_cylinder_monitor(shell):
    """Radial displacements (w_A, u_B, u_C) of the pulled cylinder's
    points A, B, C (positive outward): a monitor for
    ``solve(path="arclength", monitor=pulled_cylinder_monitor)``."""
    X = shell.mesh.vertices
    d = PULLED_CYLINDER
    idx = [_nearest(X, p) for p in _cylinder_points(d["R"], d["L"])]
    u = shell.U[idx, 0] - X[idx]
    return np.array([u[0, 1], u[1, 0], u[2, 0]])


def _bending_stiffness(h, nu):
    """D = E h^3 / (12 (1 - nu^2)) of the neo-Hookean law with shear
    modulus 1 (E = 2 (1 + nu))."""
    return 2.0 * (1.0 + nu) * h ** 3 / (12.0 * (1.0 - nu ** 2))


def thin_panel(n=8, h=1e-3, load=40.0, nu=0.3, level="consistent", membrane="dkt"):
    """Cylindrical panel (radius 1, opening +-40 degrees, length 2 along z,
    the panel of bench/obstacle.py's locking study), thickness h, clamped
    along the generator at -40 degrees, under a dead load normal to the
    reference surface (inward, -N) of ``load`` D / l^3 per unit area (l =
    1.396 the arc length of the panel's section, D the bending stiffness of
    the neo-Hookean law with shear modulus 1; h/R = 1e-3: membrane and
    bending stiffness differ by (R/h)^2 = 1e6).  The default load bends the
    free edge by 0.14 (10 % of l; measured, 8 x 8 cells).  n x n grid cells.
    """
    span = np.radians(40.0)
    mesh = shapes.cylinder(n, n, radius=1.0, length=2.0, theta=(-span, span))
    shell = Shell(mesh, h, NeoHookean(1.0, nu=nu), level=level, membrane=membrane)
    shell.clamp(mesh.nodes_where(lambda X: np.abs(np.arctan2(X[:, 1], X[:, 0]) + span) < 1e-9))
    q = load * _bending_stiffness(h, nu) / (2 * span) ** 3
    shell.face_tractions(q_plus=lambda X, N: -0.5 * q * N, q_minus=lambda X, N: -0.5 * q * N)
    return shell


def inflated_disc(rings=6, h=0.02, nu=0.499, pressure=0.02, level="consistent", membrane="dkt"):
    """Flat disc of radius 1 (``shapes.disc(rings)``), thickness h,
    neo-Hookean with shear modulus 1 and Poisson's ratio nu (0.499: nearly
    incompressible: the law's D/C = 2 nu / (1 - 2 nu) = 499), clamped at the
    rim and inflated by a follower pressure (per unit area, towards +z)
    ramped to ``pressure``; the default lifts the centre by 0.51 (measured,
    6 rings)."""
    mesh = shapes.disc(rings)
    shell = Shell(mesh, h, NeoHookean(1.0, nu=nu), level=level, membrane=membrane)
    shell.clamp(mesh.boundary_nodes())
    shell.pressure(pressure)
    return shell


def grown_strip(n=16, stretch=2.0, h=0.01, width=0.1, nu=0.3, level="consistent",
                membrane="dkt"):
    """Strip [0, 1] x [0, width] (n x 2 grid cells), thickness h,
    neo-Hookean (shear modulus 1), clamped at both ends x = 0 and x = 1, grown
    along its length by ``stretch`` (G0 = diag(stretch, 1, 1), ramped from
    1): past the Euler bifurcation at a growth strain of about (pi h)^2 / 3
    it buckles into a clamped arch of twice its span (rise 0.70 measured with
    16 cells).  An upward dead load of 1e-3 D per unit area (D the bending
    stiffness) picks the side."""
    mesh = shapes.rectangle(n, 2, lx=1.0, ly=width)
    shell = Shell(mesh, h, NeoHookean(1.0, nu=nu), level=level, membrane=membrane)
    shell.set_growth(G0=np.diag([stretch, 1.0, 1.0]))
    shell.clamp(mesh.nodes_where(lambda X: (X[:, 0] < 1e-9) | (X[:, 0] > 1 - 1e-9)))
    q = 0.5e-3 * _bending_stiffness(h, nu)
    shell.face_tractions(q_plus=[0.0, 0.0, q], q_minus=[0.0, 0.0, q])
    return shell
