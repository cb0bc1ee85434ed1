"""Growth from data: target fundamental forms (abar, bbar) -> G0, G1, rigid
supports of free bodies, and the output fields under uniform growth."""

import numpy as np
import pytest

from shellritz import NeoHookean, Shell, shapes
from shellritz.growth import cells_to_nodes, from_fundamental_forms
from shellritz.post import fields

R = 2.0


def forms_of(mesh, Y, sphere_radius=None):
    """abar of the target positions Y (the target mesh's edge vectors, as
    libshell and MorphoShell compute it) and bbar of a sphere of that radius
    (outward normal: bbar = -abar / R), components (11, 12, 22)."""
    t = mesh.triangles
    E1, E2 = Y[t[:, 1]] - Y[t[:, 0]], Y[t[:, 2]] - Y[t[:, 0]]
    a = np.c_[(E1 * E1).sum(1), (E1 * E2).sum(1), (E2 * E2).sum(1)]
    return a, (np.zeros_like(a) if sphere_radius is None else -a / sphere_radius)


def cap(X, radial=lambda s: s):
    """The disc mapped onto a spherical cap of radius R: the point at distance
    rho from the centre goes to geodesic distance radial(rho) from the pole."""
    rho, phi = np.hypot(X[:, 0], X[:, 1]), np.arctan2(X[:, 1], X[:, 0])
    s = radial(rho)
    return np.c_[R * np.sin(s / R) * np.cos(phi), R * np.sin(s / R) * np.sin(phi), R * np.cos(s / R) - R]


def fit_sphere(P):
    A = np.c_[2 * P, np.ones(len(P))]
    c = np.linalg.lstsq(A, (P ** 2).sum(1), rcond=None)[0]
    return np.sqrt(c[3] + c[:3] @ c[:3])


def aligned_error(P, Q):
    """max |P - Q| after the best rigid motion (Kabsch)."""
    P, Q = P - P.mean(0), Q - Q.mean(0)
    U, _, Vt = np.linalg.svd(P.T @ Q)
    D = np.diag([1, 1, np.sign(np.linalg.det(U @ Vt))])
    return np.abs(P @ U @ D @ Vt - Q).max()


def grow_free(mesh, abar, bbar, steps=4, h=0.02):
    G0, G1 = from_fundamental_forms(mesh.vertices, mesh.triangles, mesh.normals, abar, bbar)
    shell = Shell(mesh, h, NeoHookean(1.0, nu=0.4))
    shell.set_growth(G0=cells_to_nodes(mesh, G0), G1=cells_to_nodes(mesh, G1))
    shell.remove_rigid_motions()
    return shell, shell.solve(steps=steps, verbose=False)


def test_reference_forms_give_no_growth():
    """abar = a and bbar = b of the reference itself (a curved mesh): G0 = I, G1 = 0."""
    m = shapes.sphere(2)
    t = m.triangles
    a, _ = forms_of(m, m.vertices)
    N = m.normals
    E = [m.vertices[t[:, k]] - m.vertices[t[:, 0]] for k in (1, 2)]
    dN = [N[t[:, k]] - N[t[:, 0]] for k in (1, 2)]
    b12 = -0.5 * ((dN[0] * E[1]).sum(1) + (dN[1] * E[0]).sum(1))
    b = np.c_[-(dN[0] * E[0]).sum(1), b12, -(dN[1] * E[1]).sum(1)]
    G0, G1 = from_fundamental_forms(m.vertices, t, N, a, b)
    assert np.abs(G0 - np.eye(3)).max() < 1e-13 and np.abs(G1).max() < 1e-12


def test_bad_fundamental_forms_are_named():
    m = shapes.disc(3)
    a, b = forms_of(m, m.vertices)
    a[5] = [1.0, 2.0, 1.0]
    with pytest.raises(ValueError, match=r"abar: not positive definite at triangles \[5\]"):
        from_fundamental_forms(m.vertices, m.triangles, m.normals, a, b)
    with pytest.raises(ValueError, match=r"expected cell data of shape \(n_triangles, 3\)"):
        from_fundamental_forms(m.vertices, m.triangles, m.normals, a[:, :2], b)


@pytest.mark.parametrize("rings, radius_tol", [
    (12, 0.025),
    pytest.param(20, 0.01, marks=pytest.mark.slow),
])
def test_flat_disc_with_cap_forms_becomes_the_cap(rings, radius_tol):
    """The issue's test: a flat disc given the abar, bbar of a spherical cap of
    radius R = 2 (half-angle 29 degrees) becomes that cap.  Fitted radius error
    (the triangle engine's mesh error, second order): 4.1 %, 1.03 %, 0.66 %,
    0.45 % for 8, 16, 20, 24 rings, so the 1 % target needs 20 rings (slow
    test; the fast one checks 12 rings against the same trend: 1.84 %).
    Energy at 12 rings 3.3e-7, against 6.2e-5 for the disc held flat at full
    growth (ratio 5.3e-3); 1.3e-7 at 20 rings."""
    m = shapes.disc(rings)
    shell, res = grow_free(m, *forms_of(m, cap(m.vertices), R))
    assert res.history.stable
    assert abs(fit_sphere(res.r) / R - 1) < radius_tol
    # shape after a rigid fit, relative to the size 2: 1.6e-3 / 6.7e-4 at 12 / 20 rings
    assert aligned_error(res.r, cap(m.vertices)) / 2 < 2e-3
    flat = shell.evaluate(shell._Uref.reshape(-1)[shell.free], 0)[0]   # the disc held flat
    assert res.energy < 1e-2 * flat


def test_flat_target_with_a_sheared_metric_is_reached_exactly():
    """A nontrivial in-plane metric: abar of an affine image (stretch and
    shear), bbar = 0.  Uniform G0, G1 = 0: the free disc becomes that image up
    to a rigid motion, to the solver's tolerance."""
    m = shapes.disc(5)
    M = np.array([[1.2, 0.15, 0.0], [0.0, 0.9, 0.0], [0.0, 0.0, 1.0]])
    Y = m.vertices @ M.T
    shell, res = grow_free(m, *forms_of(m, Y), steps=1)
    assert aligned_error(res.r, Y) < 1e-10
    point, cell = fields(res)
    assert np.abs(cell["cauchy_stress"]).max() < 1e-10
    assert np.allclose(cell["principal_stretch"], np.linalg.svd(M, compute_uv=False), atol=1e-10)


@pytest.mark.slow
def test_curved_target_with_a_nonisometric_metric():
    """The cap again, mapped non-isometrically (geodesic distance
    rho (1 + 0.2 rho^2)): metric and curvature both nontrivial.  16 rings:
    radius error 1.5 %, shape error 2.3e-3 of the size after a rigid fit."""
    m = shapes.disc(16)
    Y = cap(m.vertices, lambda s: s * (1 + 0.2 * s ** 2))
    shell, res = grow_free(m, *forms_of(m, Y, R))
    assert abs(fit_sphere(res.r) / R - 1) < 0.02
    assert aligned_error(res.r, Y) < 3e-3 * 2


@pytest.mark.parametrize("mesh, G", [(shapes.disc(6), np.diag([1.1, 1.1, 1.0])),
                                     (shapes.sphere(2), 1.1 * np.eye(3))], ids=["disc", "sphere"])
def test_free_body_grown_uniformly_is_exactly_scaled_and_stress_free(mesh, G):
    """remove_rigid_motions only removes rigid motions: uniform growth 1.1 of
    a free disc / sphere gives the exact scaled shape (about the pinned node)
    with zero stress, and the output fields say so: principal stretches =
    growth stretches, directions orthonormal, energy density 0."""
    shell = Shell(mesh, 0.02, NeoHookean(1.0, nu=0.4))
    shell.set_growth(G0=G)
    a, b, c = shell.remove_rigid_motions()
    assert len({a, b, c}) == 3
    res = shell.solve(steps=1, verbose=False, rtol=1e-14)       # Newton to round-off
    X = mesh.vertices
    assert aligned_error(res.r, X[a] + (X - X[a]) @ G.T) < 1e-12   # observed 2e-16 / 4e-16
    point, cell = fields(res)
    assert np.abs(cell["cauchy_stress"]).max() < 1e-12            # observed 3e-14 / 1e-14
    assert np.abs(cell["first_piola_kirchhoff"]).max() < 1e-12
    assert np.abs(cell["energy_density"]).max() < 1e-14
    expect = np.sort(np.linalg.svd(G, compute_uv=False))[::-1]
    assert np.allclose(cell["principal_stretch"], expect, atol=1e-12)
    D = np.stack([cell[f"principal_direction_{k}"] for k in (1, 2, 3)], axis=2)
    assert np.allclose(np.einsum("mki,mkj->mij", D, D), np.eye(3), atol=1e-12)
    assert np.allclose(point["thickness_stretch"], G[2, 2], atol=1e-12)
    assert np.allclose(point["G0"], G.ravel())
