"""Automatic coarsening and nested iteration on any mesh (nested.py)."""

from importlib.resources import files

import numpy as np
import pytest

from shellritz import MeshError, coarsen, shapes, solve_nested
from shellritz.linalg import pardiso_available
from shellritz.nested import interpolate, levels
from shellritz.meshdata import Surface
from shellritz.scenefile import load_scene
from test_scenefile import BASE      # shell and material of the scene-file tests


def _area(mesh):
    X, T = mesh.vertices, mesh.triangles
    return 0.5 * np.linalg.norm(np.cross(X[T[:, 1]] - X[T[:, 0]], X[T[:, 2]] - X[T[:, 0]]), axis=1).sum()


def _shape_quality(mesh):
    """4 sqrt(3) A / sum of squared edge lengths per triangle (1: equilateral)."""
    P = mesh.vertices[mesh.triangles]
    a = 0.5 * np.linalg.norm(np.cross(P[:, 1] - P[:, 0], P[:, 2] - P[:, 0]), axis=1)
    s = sum(np.sum((P[:, i] - P[:, j]) ** 2, axis=1) for i, j in ((0, 1), (1, 2), (2, 0)))
    return 4 * np.sqrt(3) * a / s


def test_coarse_disc_keeps_its_boundary_and_shape_quality():
    fine = shapes.disc(40)                                  # 9,600 triangles
    for n in (2400, 1500, 600):     # at 1,500 the decimation leaves an ear (0.027 if kept)
        c = coarsen(fine, n)
        assert 0.8 * n <= len(c.triangles) <= 1.2 * n
        b = c.boundary_nodes()
        # boundary vertices on the fine boundary polygon (radius 1 at its
        # vertices, cos(pi / 240) between them)
        r = np.linalg.norm(c.vertices[b, :2], axis=1)
        assert np.all(r <= 1 + 1e-12) and np.all(r >= np.cos(np.pi / 240) - 1e-12)
        assert np.abs(c.vertices[:, 2]).max() < 1e-12
        assert abs(_area(c) / _area(fine) - 1) < 2e-3
        assert _shape_quality(c).min() > 0.4                # quadric decimation: 0.01


def test_coarse_rectangle_keeps_corners_and_straight_sides():
    fine = shapes.rectangle(96, 24, lx=4.0, ly=1.0)
    c = coarsen(fine, len(fine.triangles) // 16)
    X = c.vertices
    for corner in ([0, 0], [4, 0], [0, 1], [4, 1]):
        assert np.linalg.norm(X[:, :2] - corner, axis=1).min() < 1e-12
    B = X[c.boundary_nodes()]
    on_side = (np.abs(B[:, 0]) < 1e-12) | (np.abs(B[:, 0] - 4) < 1e-12) | \
              (np.abs(B[:, 1]) < 1e-12) | (np.abs(B[:, 1] - 1) < 1e-12)
    assert on_side.all()
    assert abs(_area(c) - 4.0) < 1e-9


def test_boundary_corners():
    rect = shapes.rectangle(6, 3, lx=2.0, ly=1.0)
    X = rect.vertices[rect.boundary_corners()]
    assert sorted(map(tuple, X[:, :2].round(12))) == [(0, 0), (0, 1), (2, 0), (2, 1)]
    assert len(shapes.disc(8).boundary_corners()) == 0          # turns by 7.5 degrees per node


def test_coarse_sphere_is_closed_and_outward():
    fine = shapes.sphere(5)                                 # 20,480 triangles
    c = coarsen(fine, 1280)
    assert len(c.boundary_edges) == 0
    r = np.linalg.norm(c.vertices, axis=1)
    assert r.min() > 0.999 and r.max() < 1 + 1e-9           # on the fine sphere (chord sag 9e-4)
    P = c.vertices[c.triangles]
    fn = np.cross(P[:, 1] - P[:, 0], P[:, 2] - P[:, 0])
    assert np.all(np.einsum("ij,ij->i", fn, P.mean(axis=1)) > 0)


def test_interpolate_linear_fields_and_point_masks():
    """Float data: exact for fields linear on the flat fine mesh; an integer
    mask of one node: kept at the coarse vertex nearest it."""
    fine = shapes.disc(20)
    coarse = coarsen(fine, 600)
    X, Y = fine.vertices, coarse.vertices
    lin = np.stack([2 * X[:, 0] - 3 * X[:, 1] + 1, X[:, 1]], axis=1)
    assert np.allclose(interpolate(fine, lin, Y), np.stack([2 * Y[:, 0] - 3 * Y[:, 1] + 1, Y[:, 1]], axis=1),
                       atol=1e-12)
    mask = np.zeros(fine.n_nodes, np.int32)
    off_centre = np.argmin(np.linalg.norm(X - [0.31, 0.17, 0], axis=1))
    mask[off_centre] = 3
    out = interpolate(fine, mask, Y)
    assert out.dtype == mask.dtype
    assert np.flatnonzero(out).tolist() == [np.argmin(np.linalg.norm(Y - X[off_centre], axis=1))]
    assert out.max() == 3


def test_levels_and_bad_requests():
    fine = shapes.disc(40)
    assert levels(fine, coarsest=500, factor=4) == [600, 2400]
    assert levels(fine, coarsest=20000) == []
    with pytest.raises(ValueError, match="factor"):
        levels(fine, factor=1)
    with pytest.raises(ValueError, match="requested"):
        coarsen(fine, len(fine.triangles))


def test_solve_nested_bad_arguments():
    with pytest.raises(TypeError, match="must be a shellritz.Mesh"):
        solve_nested(lambda m: None, shapes.disc(40).vertices)
    with pytest.raises(TypeError, match="must return a shellritz.Shell, not NoneType"):
        solve_nested(lambda m: None, shapes.disc(40), verbose=False)
    # bad solver options: refused before any level is built (build would raise)
    for bad, match in (({"rtol": -1.0}, "rtol"), ({"linear": "lu"}, "linear"),
                       ({"steps": 0}, "steps"), ({"tolerance": 1e-8}, "unknown option")):
        with pytest.raises((TypeError, ValueError), match=match):
            solve_nested(lambda m: 1 / 0, shapes.disc(40), verbose=False, **bad)


def test_turned_triangles_are_an_error(monkeypatch):
    """A coarse mesh turned against the fine surface's normals is refused
    (forced here: the remeshing's triangles reversed)."""
    import gpytoolbox
    remesh = gpytoolbox.remesh_botsch
    monkeypatch.setattr(gpytoolbox, "remesh_botsch", lambda *a: (lambda V, T: (V, T[:, ::-1]))(*remesh(*a)))
    with pytest.raises(MeshError, match="turned against the surface"):
        coarsen(shapes.disc(20), 600)


def test_nested_leaf_reaches_the_direct_equilibrium(monkeypatch):
    """The default scene on a 24-ring disc (3,456 triangles) through a coarse
    level of 864 (857 made), solved to COARSE_RTOL there and to the given
    rtol on the given mesh: the same energy as the direct solve (observed
    2e-14 relative), in fewer Newton iterations on the given mesh (observed 7
    against 18)."""
    from shellritz import Shell
    from shellritz.nested import COARSE_RTOL
    scene = load_scene(files("shellritz.meshes") / "leaf.toml")

    def build(mesh):
        return scene.build(Surface(mesh), membrane="dkt")[0]     # as counted (test_solver.dkt_leaf)

    fine = shapes.disc(24)
    direct = build(fine).solve(verbose=False, rtol=1e-8, linear="superlu")
    tolerances, solve = [], Shell.solve
    monkeypatch.setattr(Shell, "solve", lambda self, **kw: tolerances.append(kw["rtol"]) or solve(self, **kw))
    nested = solve_nested(build, fine, coarsest=800, verbose=False, rtol=1e-8, linear="superlu")
    assert tolerances == [COARSE_RTOL, 1e-8]
    # the linear solver asked for is the given mesh's; the coarse level's is chosen by size
    assert nested.history.linear == "superlu"
    assert nested.history.nested[0]["linear"] == ("pardiso" if pardiso_available() else "superlu")
    assert len(nested.history.nested) == 1
    assert 0.8 * 864 <= nested.history.nested[0]["n_triangles"] <= 1.2 * 864
    assert nested.shell.mesh is fine
    assert abs(nested.energy / direct.energy - 1) < 1e-9
    assert len(nested.history.iterations) < len(direct.history.iterations)
    assert nested.history.stable


def test_nested_monitors_the_given_mesh_only():
    """monitor= names nodes of the given mesh: the coarse levels do not get
    it (its last node is outside the coarse mesh: a ValueError there before)."""
    scene = load_scene(files("shellritz.meshes") / "leaf.toml")
    fine = shapes.disc(12)
    res = solve_nested(lambda m: scene.build(Surface(m))[0], fine, coarsest=200, verbose=False,
                       monitor=[fine.n_nodes - 1])
    assert [lvl["n_triangles"] < 300 for lvl in res.history.nested] == [True]
    assert res.converged


def test_nested_without_coarser_level_is_the_direct_solve():
    scene = load_scene(files("shellritz.meshes") / "leaf.toml")
    fine = shapes.disc(6)
    res = solve_nested(lambda m: scene.build(Surface(m))[0], fine, verbose=False)
    assert res.history.nested == []
    assert res.converged


def test_nested_gives_the_thickness_path_to_the_coarsest_level_only():
    """solve_nested(thickness_path=...): the coarsest level (600 triangles of
    a 2,400-triangle disc) is solved by continuation in the thickness, the
    given mesh from the coarse equilibrium at its own thickness.  (At
    h = 0.005 the given mesh fails from the coarse equilibrium: a coarse
    level this coarse does not carry the thin leaf's shape, README
    Scaling.)"""
    scene = load_scene(files("shellritz.meshes") / "leaf.toml")
    res = solve_nested(lambda m: scene.build(Surface(m), thickness=0.01)[0], shapes.disc(20),
                       coarsest=500, verbose=False, thickness_path=[0.04, 0.02])
    assert [lv["n_triangles"] > 0 for lv in res.history.nested] == [True]
    assert [s["thickness"] for s in res.history.nested[0]["thickness_stages"]] == [0.04, 0.02]
    assert res.history.thickness_stages == [] and res.shell.h == 0.01
    assert res.converged and res.history.stable


NESTED_SCENE = """
[mesh]
file = "disc.vtu"
""" + BASE + """
[growth]
G0 = {array = "G0"}
G1 = {array = "G1"}
[[boundary.clamp]]
nodes = { mask = "centre" }
[loads]
face_tractions = { q_minus = {array = "q"} }
[solver]
rtol = 1e-8
nested = NESTED
"""


def test_scene_file_nested_carries_point_and_cell_data(tmp_path):
    """A scene file with ``nested = true``: growth (point data G0, G1 of the
    leaf), a clamp by an integer mask and face tractions from cell data are
    carried onto the coarse level (2,400 triangles of a 9,600-triangle disc);
    the equilibrium is that of the solve without nesting (observed 7e-14
    relative), in fewer Newton iterations on the input mesh (observed 8
    against 18)."""
    import meshio
    from shellritz.meshdata import read_surface
    from shellritz.scenefile import loads_scene
    leaf = load_scene(files("shellritz.meshes") / "leaf.toml")
    mesh = shapes.disc(40)
    G0, G1, _ = leaf.growth(Surface(mesh))
    centre = np.zeros(mesh.n_nodes, np.int32)
    centre[np.argmin(np.linalg.norm(mesh.vertices, axis=1))] = 1
    xc = mesh.vertices[mesh.triangles].mean(axis=1)
    q = np.stack([0 * xc[:, 0], 0 * xc[:, 0], -1e-8 * xc[:, 0]], axis=1)
    meshio.write(tmp_path / "disc.vtu", meshio.Mesh(
        mesh.vertices, [("triangle", mesh.triangles)],
        point_data={"G0": G0.reshape(-1, 9), "G1": G1.reshape(-1, 9), "centre": centre},
        cell_data={"q": [q]}))
    results = {}
    for nested in ("false", "true"):
        scene = loads_scene(NESTED_SCENE.replace("NESTED", nested), tmp_path)
        surf = read_surface(tmp_path / "disc.vtu")
        shell, source = scene.build(surf)
        results[nested] = scene.solve(surf, shell)
    direct, nested = results["false"], results["true"]
    assert [lv["n_triangles"] for lv in direct.history.nested] == []
    assert len(nested.history.nested) == 1
    assert 0.8 * 2400 <= nested.history.nested[0]["n_triangles"] <= 1.2 * 2400
    assert abs(nested.energy / direct.energy - 1) < 1e-9
    assert len(nested.history.iterations) < len(direct.history.iterations)
    assert len(nested.history.iterations) < len(direct.history.iterations)
