"""Mesh reading and checks: every defect is reported with the elements and
nodes concerned; unused vertices are dropped with a warning."""

import numpy as np
import pytest

from shellritz import Mesh, MeshError, shapes

SQUARE = (np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0.0]]), np.array([[0, 1, 2], [0, 2, 3]]))


@pytest.mark.parametrize("ext", ["vtu", "obj", "ply", "stl", "off", "msh"])
def test_read_formats(tmp_path, ext):
    import meshio
    m = shapes.sphere(1)
    path = tmp_path / f"s.{ext}"
    kw = {"file_format": "gmsh22", "binary": False} if ext == "msh" else {}
    meshio.write_points_cells(path, m.vertices, [("triangle", m.triangles)], **kw)
    r = Mesh.read(path)
    assert r.n_triangles == m.n_triangles
    assert r.n_nodes == m.n_nodes          # STL: coincident vertices merged
    assert r.areas.sum() == pytest.approx(m.areas.sum(), rel=1e-6)


def test_non_triangle_cells_are_named(tmp_path):
    import meshio
    path = tmp_path / "q.vtu"
    meshio.write_points_cells(path, SQUARE[0], [("quad", np.array([[0, 1, 2, 3]]))])
    with pytest.raises(MeshError, match="non-triangle cells.*1 quad"):
        Mesh.read(path)


def test_empty_zero_normals_and_corrupt_files(tmp_path):
    with pytest.raises(MeshError, match="the mesh has no triangles"):
        Mesh(np.zeros((0, 3)), np.zeros((0, 3), int))
    with pytest.raises(MeshError, match="normal\\(X\\) is the zero vector at vertices 0, 1, 2, 3"):
        Mesh(*SQUARE, normal=lambda X: np.zeros_like(X))
    for name, content, message in (("garbage.vtu", b"not a mesh at all", "cannot read it \\(meshio: .*garbage"),
                                   ("empty.vtu", b"", "empty file"),
                                   ("garbage.stl", b"solid x\nfacet broken\n", "no triangle cells")):
        path = tmp_path / name
        path.write_bytes(content)
        with pytest.raises(MeshError, match=f"{name}: {message}"):
            Mesh.read(path)          # meshio's sys.exit on some of them must not end the caller


def test_slivers_are_refused_poor_triangles_and_coincident_vertices_warned():
    X = np.array([[0, 0, 0], [1, 0, 0], [0.5, 1e-8, 0], [0.5, -1, 0.0]])
    with pytest.raises(MeshError, match=r"nearly degenerate triangles 0: shape quality 2.31e-08"):
        Mesh(X, [[0, 1, 2], [0, 3, 1]])
    X[2, 1] = 1e-3
    with pytest.warns(UserWarning, match=r"1 poorly shaped triangles \(0\), shape quality down to 2.31e-03"):
        Mesh(X, [[0, 1, 2], [0, 3, 1]])
    V, T = SQUARE
    with pytest.warns(UserWarning, match=r"4 vertices share a position with another \(0, 2, 3, 4\)"):
        Mesh(V[T.ravel()], np.arange(6).reshape(2, 3))      # two triangles, not connected


def test_nan_coordinates():
    X = SQUARE[0].copy()
    X[2, 1] = np.nan
    with pytest.raises(MeshError, match="non-finite coordinates at vertices 2"):
        Mesh(X, SQUARE[1])


def test_index_out_of_range():
    with pytest.raises(MeshError, match="triangles 1 reference vertices outside"):
        Mesh(SQUARE[0], np.array([[0, 1, 2], [0, 2, 7]]))


def test_degenerate_triangles():
    with pytest.raises(MeshError, match="degenerate triangles 1: a vertex is repeated"):
        Mesh(SQUARE[0], np.array([[0, 1, 2], [0, 2, 2]]))
    X = np.array([[0, 0, 0], [1, 0, 0], [2, 0, 0], [0, 1, 0.0]])
    with pytest.raises(MeshError, match=r"degenerate triangles 0: zero area \(vertices 0, 1, 2"):
        Mesh(X, np.array([[0, 1, 2], [0, 1, 3]]))


def test_duplicate_triangles():
    with pytest.raises(MeshError, match="duplicate triangles 0, 1"):
        Mesh(SQUARE[0], np.array([[0, 1, 2], [1, 2, 0]]))


def test_non_manifold_edge():
    X = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1.0]])
    T = np.array([[0, 1, 2], [1, 0, 3], [0, 1, 4]])
    with pytest.raises(MeshError, match=r"non-manifold edges.*edge \(0, 1\) in triangles 0, 1, 2"):
        Mesh(X, T)


def test_inconsistent_orientation():
    with pytest.raises(MeshError, match="inconsistent orientation.*triangles 0 and 1"):
        Mesh(SQUARE[0], np.array([[0, 1, 2], [0, 3, 2]]))


def test_non_manifold_vertex():
    """Two triangles touching only at vertex 0 (a bow tie)."""
    X = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [-1, 0, 0], [-1, -1, 0.0]])
    with pytest.raises(MeshError, match="non-manifold vertices 0"):
        Mesh(X, np.array([[0, 1, 2], [0, 3, 4]]))


def test_unused_vertices_dropped_with_warning():
    X = np.vstack([SQUARE[0], [[5, 5, 5]]])
    with pytest.warns(UserWarning, match="dropping 1 unused vertices \\(4\\)"):
        m = Mesh(X, SQUARE[1])
    assert m.n_nodes == 4 and list(m.kept) == [0, 1, 2, 3]


def test_angle_weighted_normals_approximate_the_sphere():
    """Observed max error 8.9e-3, 4.6e-3, 2.3e-3 on icospheres of level 2, 3, 4:
    first order in the mesh size (the valence-5 vertices limit it)."""
    errors = []
    for levels in (2, 3, 4):
        X = shapes.sphere(levels).vertices
        m = Mesh(X, shapes.sphere(levels).triangles)
        assert not m.analytic_normals
        errors.append(np.abs(m.normals - X).max())
    assert errors[0] < 1e-2
    assert all(1.8 < errors[k] / errors[k + 1] < 2.2 for k in range(2)), errors
    T = m.frames
    np.testing.assert_allclose(np.cross(T[:, :, 0], T[:, :, 1]), m.normals, atol=1e-14)
    np.testing.assert_allclose(np.einsum("nia,nib->nab", T, T), np.broadcast_to(np.eye(2), (m.n_nodes, 2, 2)),
                               atol=1e-14)


def test_analytic_normals_must_match_orientation():
    s = shapes.sphere(1)
    with pytest.raises(MeshError, match="point against the orientation"):
        Mesh(s.vertices, s.triangles, normal=lambda X: -X)


def test_boundary_loops_and_selections():
    assert len(shapes.rectangle(3, 2).boundary_loops()) == 1
    assert len(shapes.cylinder(8, 3).boundary_loops()) == 2
    assert len(shapes.sphere(1).boundary_loops()) == 0
    r = shapes.rectangle(4, 4)
    assert len(r.boundary_nodes()) == 16
    assert len(r.nodes_on_plane("x", 0.0)) == 5
    assert len(r.nodes_where(lambda X: X[:, 1] > 0.99)) == 5
