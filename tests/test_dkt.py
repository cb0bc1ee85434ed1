"""DKT engine: element map, assembled derivatives, zero modes, patch and
rigid-motion tests, exact stress-free growth.

Observed: assembled gradient/Hessian agree with central differences to
2e-10 / 4e-11 relative; a free mesh has exactly 6 zero Hessian eigenvalues
with the 6-point rule (structured, perturbed, flat and curved meshes), while
the 3-point rule has 8-9 on structured flat meshes (hence the default);
uniform stretch is reproduced to 1e-12 (in-plane patch test); rigid motions of
a curved shell cost 1e-17; uniform growth of a sphere and a cylinder is
recovered to 1e-10.
"""

import numpy as np
import pytest
import scipy.sparse as sp

from shellritz import NeoHookean, Shell, shapes
from shellritz.discretize.dkt import apply_map, element_chart, point_map, rule

LAW = NeoHookean(1.0, nu=0.3)


def prepared(mesh, h=0.05, level="consistent", quadrature=6, t=1.0, G0=None, G1=None):
    s = Shell(mesh, h, LAW, level=level, quadrature=quadrature)
    if G0 is not None or G1 is not None:
        s.set_growth(G0=G0, G1=G1)
    s._setup()
    s.set_parameter(t)
    return s


def full(K):
    return (K + sp.tril(K, -1).T).toarray()


def test_element_map_reproduces_affine_fields_and_constant_curvature():
    rng = np.random.default_rng(0)
    Xe = np.array([[0, 0, 0], [1.0, 0.1, 0], [0.3, 0.9, 0]])
    T = np.zeros((3, 3, 2))
    T[:, :, 0] = [1, 0, 0]
    T[:, :, 1] = [0, 1, 0]
    Q, gl, et, el = np.zeros((3, 2, 2)), np.zeros((3, 2)), np.zeros((3, 2)), np.zeros(3)
    area = element_chart(Xe, T, Q, gl, et, el)
    assert area == pytest.approx(0.435)
    E1 = (Xe[1] - Xe[0]) / np.linalg.norm(Xe[1] - Xe[0])
    E2 = np.cross([0, 0, 1.0], E1)
    F = rng.standard_normal((3, 3))
    blocks = np.zeros((9, 3))
    for i in range(3):
        blocks[3 * i], blocks[3 * i + 1], blocks[3 * i + 2] = F @ Xe[i], F @ T[i, :, 0], F @ T[i, :, 1]
    b, C, v = np.zeros((5, 9)), np.zeros((2, 9)), np.zeros(15)
    for lam in rule(6)[0]:
        point_map(lam, Q, gl, et, el, b, C)
        apply_map(b, blocks, v)
        np.testing.assert_allclose(v[:3], F @ E1, atol=1e-14)
        np.testing.assert_allclose(v[3:6], F @ E2, atol=1e-14)
        np.testing.assert_allclose(v[6:], 0, atol=1e-13)
    # quadratic height w = x^2/2 + 0.3 x y + 0.2 y^2 with exact nodal slopes:
    # r_ab is the exact constant Hessian (in the facet frame)
    Hw = np.array([[1.0, 0.3], [0.3, 0.4]])
    for i in range(3):
        x, y = Xe[i, :2]
        blocks[3 * i] = [x, y, 0.5 * x * x + 0.3 * x * y + 0.2 * y * y]
        blocks[3 * i + 1] = [1, 0, x + 0.3 * y]
        blocks[3 * i + 2] = [0, 1, 0.3 * x + 0.4 * y]
    R = np.array([E1[:2], E2[:2]])
    Hc = R @ Hw @ R.T
    for lam in rule(6)[0]:
        point_map(lam, Q, gl, et, el, b, C)
        apply_map(b, blocks, v)
        assert v[8] == pytest.approx(Hc[0, 0]) and v[11] == pytest.approx(Hc[0, 1])
        assert v[14] == pytest.approx(Hc[1, 1])


@pytest.mark.parametrize("level", ["membrane", "bending", "consistent"])
def test_assembled_derivatives_against_finite_differences(level):
    mesh = shapes.cylinder(3, 2, radius=1.0, length=0.6, theta=(0, 1.0))
    s = prepared(mesh, h=0.1, level=level, G0=np.diag([1.1, 0.95, 1.0]), G1=np.diag([0.8, 0.3, 0]))
    s.face_tractions(q_plus=[0.01, 0.0, 0.02])
    s._prepared = False
    s._setup()
    s.set_parameter(1.0)
    rng = np.random.default_rng(1)
    x = s.free_state() + 0.02 * rng.standard_normal(len(s.free))
    E, g, K = s.evaluate(x, 2)
    K = full(K)
    eps = 1e-6
    gfd, Kfd = np.zeros_like(g), np.zeros_like(K)
    for i in range(len(x)):
        e = np.zeros_like(x)
        e[i] = eps
        Ep, gp, _ = s.evaluate(x + e, 1)
        Em, gm, _ = s.evaluate(x - e, 1)
        gfd[i] = (Ep - Em) / (2 * eps)
        Kfd[:, i] = (gp - gm) / (2 * eps)
    assert np.abs(gfd - g).max() <= 1e-8 * np.abs(g).max()
    assert np.abs(Kfd - K).max() <= 1e-8 * np.abs(K).max()


MESHES = {
    "flat-structured": lambda: shapes.rectangle(6, 6),
    "flat-right": lambda: shapes.rectangle(6, 6, pattern="right"),
    "flat-perturbed": lambda: shapes.rectangle(6, 6, perturb=0.3),
    "cylinder-patch": lambda: shapes.cylinder(6, 6, theta=(0, 1.2)),
    "sphere": lambda: shapes.sphere(1),
}


def zero_eigenvalues(mesh, quadrature, strain_gradient=True):
    s = prepared(mesh, quadrature=quadrature)
    if not strain_gradient:
        s.strain_gradient = None
    w = np.linalg.eigvalsh(full(s.evaluate(s.free_state(), 2)[2]))
    return int((np.abs(w) < 1e-9 * w.max()).sum())


@pytest.mark.parametrize("name", sorted(MESHES))
def test_free_mesh_has_exactly_six_zero_modes(name):
    assert zero_eigenvalues(MESHES[name](), 6) == 6


def test_three_point_rule_has_spurious_zero_modes():
    """Why the default rule has 6 points: on structured flat meshes the
    3-point rule leaves extra zero-energy modes of the MODEL.md energy (the
    h^5 strain-gradient term of issue 14 gives them a small stiffness, so
    they are counted without it)."""
    assert zero_eigenvalues(MESHES["flat-structured"](), 3, strain_gradient=False) > 6
    assert zero_eigenvalues(MESHES["flat-right"](), 3, strain_gradient=False) > 6


@pytest.mark.parametrize("pattern, perturb", [("alternate", 0.0), ("alternate", 0.35)])
def test_in_plane_patch_test(pattern, perturb):
    """Boundary pinned at F X: the interior must be exactly F X, gradients F T."""
    mesh = shapes.rectangle(5, 4, lx=1.0, ly=0.8, pattern=pattern, perturb=perturb, seed=3)
    F = np.array([[1.3, 0.2, 0.0], [-0.1, 0.9, 0.0], [0.0, 0.0, 1.0]])
    s = Shell(mesh, 0.02, LAW, level="consistent")
    bnd = mesh.boundary_nodes()
    s.pin(bnd, position=mesh.vertices[bnd] @ F.T)
    res = s.solve(steps=2, verbose=False)
    np.testing.assert_allclose(res.r, mesh.vertices @ F.T, atol=1e-11)
    for k in range(2):
        np.testing.assert_allclose(res.derivatives[:, k], s.frames[:, :, k] @ F.T, atol=1e-10)


@pytest.mark.parametrize("mesh", [shapes.sphere(2, radius=1.3), shapes.cylinder(12, 4, radius=0.7)])
def test_rigid_motion_costs_nothing(mesh):
    s = prepared(mesh)
    q, _ = np.linalg.qr(np.random.default_rng(0).standard_normal((3, 3)))
    q *= np.sign(np.linalg.det(q))
    s.U[:] = s.U @ q.T
    s.U[:, 0] += [0.3, -1.0, 2.0]
    E, g, _ = s.evaluate(s.free_state(), 1)
    assert abs(E) < 1e-15 and np.abs(g).max() < 1e-15


def test_uniform_growth_of_a_sphere_is_exact_scaling():
    mesh = shapes.sphere(2)
    s = Shell(mesh, 0.05, LAW).set_growth(G0=1.3 * np.eye(3))
    res = s.solve(steps=2, verbose=False)
    # no supports: the answer is 1.3 X up to a rigid motion (here none is excited)
    np.testing.assert_allclose(res.r, 1.3 * mesh.vertices, atol=1e-9)


def test_uniform_growth_of_a_cylinder_is_exact_scaling():
    mesh = shapes.cylinder(8, 2, radius=1.0, length=0.5, theta=(0, np.pi / 2))
    s = Shell(mesh, 0.05, LAW).set_growth(G0=1.3 * np.eye(3))
    s.symmetry("x").symmetry("y").symmetry("z", 0.0)
    res = s.solve(steps=2, verbose=False)
    np.testing.assert_allclose(res.r, 1.3 * mesh.vertices, atol=1e-10)


@pytest.mark.parametrize("name", ["flat-perturbed", "sphere"])
def test_colouring_makes_parallel_assembly_race_free(name):
    """Elements of one colour share no node, so the parallel assembly adds
    each colour's contributions without races: the gradient and Hessian are
    bitwise identical on 1 and 2 threads (observed: 8 and 9 colours here)."""
    import numba
    from shellritz.kernels.assembly import color_elements
    mesh = MESHES[name]()
    colour = color_elements(mesh.triangles, mesh.n_nodes)
    assert colour.min() == 0 and colour.max() < 12
    for c in range(colour.max() + 1):
        nodes = mesh.triangles[colour == c].ravel()
        assert len(np.unique(nodes)) == len(nodes), f"colour {c} shares a node"
    s = prepared(mesh, G0=np.diag([1.1, 0.95, 1.0]), G1=np.diag([0.8, 0.3, 0]))
    x = s.free_state() + 0.02 * np.random.default_rng(2).standard_normal(len(s.free))
    threads = numba.get_num_threads()
    start = s.save_point()              # same y1 warm starts for both runs
    try:
        out = []
        for n in (1, min(2, numba.config.NUMBA_NUM_THREADS)):
            numba.set_num_threads(n)
            s.restore_point(start)
            out.append(s.evaluate(x, 2))
    finally:
        numba.set_num_threads(threads)
    (E1, g1, K1), (E2, g2, K2) = out
    assert E1 == E2 and np.array_equal(g1, g2) and np.array_equal(K1.data, K2.data)


def test_hessian_pattern_matches_a_coo_assembly():
    """The node-by-node CSR pattern and element map give the same lower
    triangle as scipy's COO assembly of random symmetric element matrices,
    restricted to the free DOFs (about a third of the DOFs fixed at random)."""
    from shellritz.kernels.assembly import hessian_pattern
    mesh = shapes.rectangle(5, 4, perturb=0.2)
    rng = np.random.default_rng(5)
    ndof = 9 * mesh.n_nodes
    free = np.where(rng.random(ndof) > 0.35)[0]
    fidx = -np.ones(ndof, np.int64)
    fidx[free] = np.arange(len(free))
    indptr, indices, emap = hessian_pattern(mesh.triangles, fidx.reshape(-1, 9))
    tri = mesh.triangles
    Ke = rng.standard_normal((len(tri), 27, 27))
    Ke = Ke + Ke.transpose(0, 2, 1)
    p, q = np.tril_indices(27)
    data = np.zeros(len(indices))
    np.add.at(data, emap[emap >= 0], Ke[:, p, q][emap >= 0])
    K = sp.csr_matrix((data, indices, indptr), shape=(len(free), len(free)))
    assert K.has_canonical_format                     # sorted, no duplicates
    ldof = (9 * tri[:, :, None] + np.arange(9)).reshape(len(tri), 27)
    rows = np.broadcast_to(ldof[:, :, None], Ke.shape).ravel()
    cols = np.broadcast_to(ldof[:, None, :], Ke.shape).ravel()
    full = sp.coo_matrix((Ke.ravel(), (rows, cols)), shape=(ndof, ndof)).tocsr()
    ref = sp.tril(full[free][:, free]).toarray()
    assert np.abs(K.toarray() - ref).max() <= 1e-12 * np.abs(ref).max()
    assert K.nnz == np.count_nonzero(ref)
