"""Nested iteration: a solved state carried onto another mesh of the same
reference surface (transfer.py, ``Shell.solve(start=result)``)."""

from types import SimpleNamespace

import numpy as np
import pytest

from shellritz import NeoHookean, Shell, shapes
from shellritz.discretize.planestrain import PlaneStrainShell
from shellritz.scenes import leaf
from shellritz.transfer import carry_over, interpolate, interpolation_jacobian


def _shell(mesh):
    shell = Shell(mesh, 0.02, NeoHookean(1.0, nu=0.3))
    shell._setup()
    return shell


def _quadratic_state(shell):
    """U of the deformation r = A X + (x^2, x y, x^2 + y^2) c of a flat
    reference, with its exact tangent derivatives along the frames."""
    A = np.array([[1.1, 0.2, 0.0], [-0.1, 0.9, 0.0], [0.3, 0.1, 1.0]])
    c = np.array([0.3, -0.2, 0.5])
    x, y = shell.X[:, 0], shell.X[:, 1]
    r = shell.X @ A.T + np.c_[c[0] * x * x, c[1] * x * y, c[2] * (x * x + y * y)]
    grad = np.broadcast_to(A, (len(x), 3, 3)).copy()            # dr/dX, (n, 3, 3)
    grad[:, :, 0] += np.c_[2 * c[0] * x, c[1] * y, 2 * c[2] * x]
    grad[:, :, 1] += np.c_[np.zeros_like(x), c[1] * x, 2 * c[2] * y]
    T = shell.frames
    return np.stack([r, np.einsum("nkj,nj->nk", grad, T[:, :, 0]),
                     np.einsum("nkj,nj->nk", grad, T[:, :, 1])], axis=1)


def test_quadratic_deformations_are_carried_exactly():
    """Positions and tangent derivatives of a deformation quadratic in the
    reference position reach the new nodes exactly (observed 4e-16), also
    where the new rim lies outside the old polygon (extrapolation)."""
    coarse, fine = _shell(shapes.disc(5)), _shell(shapes.disc(13, perturb=0.2, seed=3))
    U = _quadratic_state(coarse)
    old = SimpleNamespace(shell=coarse, r=U[:, 0], derivatives=U[:, 1:])
    error = np.abs(carry_over(old, fine)[0] - _quadratic_state(fine)).max()
    assert error < 1e-13


@pytest.mark.parametrize("surface", ["disc", "cylinder"])
def test_interpolation_jacobian_is_the_derivative_of_the_transfer(surface):
    """interpolation_jacobian (the prolongation of multigrid over nested
    meshes) is d interpolate / dU: against central differences at a
    perturbed state of a flat and of a curved reference (observed 2.1e-10 /
    2.4e-10 of the increments' 3.1), and it carries the old mesh's rigid
    motions of that state onto the new mesh's exactly (observed 3e-16 of
    their size): the rotations through the normal's derivative."""
    if surface == "disc":
        coarse, fine = _shell(shapes.disc(4)), _shell(shapes.disc(9, perturb=0.2, seed=3))
    else:
        coarse, fine = (_shell(shapes.cylinder(n, n // 2, theta=(0.0, 2.0)))
                        for n in (6, 13))
    rng = np.random.default_rng(1)
    U = coarse.U + 0.2 * rng.standard_normal(coarse.U.shape)
    J = interpolation_jacobian(coarse, U, fine)
    assert J.shape == (9 * len(fine.X), 9 * len(coarse.X)) and J.blocksize == (9, 9)
    dU = rng.standard_normal(U.shape)
    eps = 1e-6
    central = (interpolate(coarse, U + eps * dU, fine) - interpolate(coarse, U - eps * dU, fine)) / (2 * eps)
    assert np.abs(J @ dU.ravel() - central.ravel()).max() < 1e-8 * np.abs(central).max()
    coarse.U, fine.U = U, interpolate(coarse, U, fine)
    rigid_coarse, rigid_fine = coarse.block_layout().rigid_modes(), fine.block_layout().rigid_modes()
    assert np.abs(J @ rigid_coarse - rigid_fine).max() < 1e-12 * np.abs(rigid_fine).max()


def test_a_fine_solve_from_a_coarse_equilibrium_reaches_the_same_equilibrium_sooner():
    """The leaf on 14 rings solved from the 10-ring equilibrium: the same
    equilibrium as the solve from the flat disc (energy to 1e-10, positions
    to 1e-9; observed 3e-15 and 1e-12), stable, in fewer Newton
    iterations (observed 17 -> 5, 16 -> 6 factorizations)."""
    direct = leaf(14).solve(verbose=False)
    coarse = leaf(10).solve(verbose=False)
    nested = leaf(14).solve(verbose=False, start=coarse)
    assert nested.converged and nested.history.stable
    assert nested.history.steps[0][0] == 1.0                  # Newton started at t = 1
    assert nested.energy == pytest.approx(direct.energy, rel=1e-10)
    assert np.abs(nested.r - direct.r).max() < 1e-9
    assert len(nested.history.iterations) < len(direct.history.iterations) - 4


def test_a_solve_started_from_coarser_meshes_preconditions_with_multigrid_over_them(monkeypatch):
    """The 16-ring leaf started from the 8-ring equilibrium, itself started
    from the 4-ring one: its shell keeps the prolongators of both coarser
    meshes (transfer.carry_over), an AMG solve builds its hierarchy on
    them (said in the history) and reaches the equilibrium of the direct
    solve (energy to 1e-9, positions to 1e-6; observed 4e-13 and 2e-7); a
    start from a mesh as fine keeps no levels."""
    import shellritz.linalg as linalg
    monkeypatch.setattr(linalg, "AMG_ONE_LEVEL_BLOCKS", 0)
    r4 = leaf(4).solve(verbose=False)
    r8 = leaf(8).solve(verbose=False, start=r4)
    fine = leaf(16)
    nested = fine.solve(verbose=False, start=r8, linear="amg")
    direct = leaf(16).solve(verbose=False, start=r8)
    assert [P.shape for P in fine.prolongators] == [(9 * fine.mesh.n_nodes, 9 * r8.shell.mesh.n_nodes),
                                                    (9 * r8.shell.mesh.n_nodes, 9 * r4.shell.mesh.n_nodes)]
    assert "AMG: multigrid over the 2 coarser meshes of the start (nested iteration)" in nested.history.notes
    assert nested.converged and nested.energy == pytest.approx(direct.energy, rel=1e-9)
    assert np.abs(nested.r - direct.r).max() < 1e-6
    same = leaf(16)
    same.solve(verbose=False, start=direct)
    assert same.prolongators == ()


def test_the_tolerance_of_a_started_solve_refers_to_the_reference_state():
    """rtol is relative to the gradient of the reference state at the
    start's t (what a solve from the flat disc is held to), not to the
    transferred state's own, already small, gradient: an equilibrium carried
    onto its own mesh needs no Newton step (before: one, to cut its
    round-off gradient by another 1e-9; on the 50k leaf the nested solve's
    last Newton step, 49 AMG-preconditioned CG iterations, was of this kind)."""
    solved = leaf(10).solve(verbose=False)
    again = leaf(10).solve(verbose=False, start=solved)
    assert again.converged and len(again.history.iterations) == 0
    assert np.abs(again.r - solved.r).max() == 0.0


def test_start_needs_a_result_on_the_same_surface():
    coarse = leaf(4).solve(verbose=False)
    with pytest.raises(TypeError, match="Result"):
        leaf(6).solve(verbose=False, start=coarse.r)
    lifted = shapes.disc(6)
    lifted = type(lifted)(lifted.vertices + [0.0, 0.0, 0.5], lifted.triangles)
    shell = Shell(lifted, 0.02, NeoHookean(1.0, nu=0.3))
    with pytest.raises(ValueError, match=r"node 0 at \[0.0, 0.0, 0.5\] is not on the start's"):
        shell.solve(verbose=False, start=coarse)
    strip = PlaneStrainShell.strip(8, 1.0, 0.1, NeoHookean(1.0, nu=0.3))
    with pytest.raises(TypeError, match="triangle engine"):
        strip.solve(verbose=False, start=coarse)
