"""Surface formats in and out with their data arrays, atomic writes."""

import meshio
import numpy as np
import pytest

from shellritz import shapes
from shellritz.meshdata import FORMATS_WITH_DATA, atomic_path, file_format, read_surface, write_mesh


@pytest.mark.parametrize("ext", ["vtu", "xdmf", "msh", "vtk", "ply", "obj", "stl", "off"])
def test_round_trip(tmp_path, ext):
    """Geometry always; point and cell data (3x3 tensors as 9 components) in
    the formats that keep them; PLY keeps scalar point data."""
    m = shapes.disc(3)
    G0 = np.tile(np.diag([1.1, 1.2, 1.0]).ravel(), (m.n_nodes, 1)) + m.vertices[:, :1]
    abar = np.c_[m.areas, 0.5 * m.areas, 2 * m.areas]
    path = tmp_path / f"disc.{ext}"
    write_mesh(path, meshio.Mesh(m.vertices, [("triangle", m.triangles)],
                                 point_data={"G0": G0, "s": m.vertices[:, 0].copy()},
                                 cell_data={"abar": [abar]}))
    s = read_surface(path)
    assert s.mesh.n_triangles == m.n_triangles
    # STL stores every triangle's vertices: merged back, possibly reordered
    order = np.argsort(s.mesh.vertices[:, 0] * 7 + s.mesh.vertices[:, 1])
    ref = np.argsort(m.vertices[:, 0] * 7 + m.vertices[:, 1])
    assert np.allclose(s.mesh.vertices[order], m.vertices[ref], atol=1e-6)
    if file_format(path) in FORMATS_WITH_DATA:
        assert np.array_equal(s.point_data["G0"], G0)
        assert np.array_equal(s.cell_data["abar"], abar)
    if ext == "ply":
        assert np.allclose(s.point_data["s"], m.vertices[:, 0])
    assert not list(tmp_path.glob(".*"))


def test_unused_vertices_keep_their_data_aligned(tmp_path):
    X = np.array([[0, 0, 0], [9, 9, 9], [1, 0, 0], [0, 1, 0.0]])
    meshio.write(tmp_path / "m.vtu", meshio.Mesh(X, [("triangle", np.array([[0, 2, 3]]))],
                                                 point_data={"id": np.arange(4.0)}))
    s = read_surface(tmp_path / "m.vtu")
    assert s.mesh.n_nodes == 3 and list(s.point_data["id"]) == [0.0, 2.0, 3.0]


def test_atomic_write_leaves_nothing_on_failure(tmp_path):
    target = tmp_path / "out.vtu"
    target.write_text("previous complete output")
    with pytest.raises(RuntimeError):
        with atomic_path(target) as tmp:
            tmp.write_text("half")
            raise RuntimeError("killed mid-write")
    assert target.read_text() == "previous complete output"
    assert list(tmp_path.iterdir()) == [target]


def test_unknown_format_and_missing_array_messages(tmp_path):
    with pytest.raises(ValueError, match="unknown mesh format '.docx'"):
        file_format(tmp_path / "x.docx")
    m = shapes.disc(2)
    write_mesh(tmp_path / "d.vtu", meshio.Mesh(m.vertices, [("triangle", m.triangles)]))
    with pytest.raises(KeyError, match="no array 'G0'.*its arrays: none"):
        read_surface(tmp_path / "d.vtu").array("G0")


def test_outputs_get_the_usual_permissions(tmp_path):
    import os
    umask = os.umask(0o022)
    os.umask(umask)
    m = shapes.disc(2)
    write_mesh(tmp_path / "d.vtu", meshio.Mesh(m.vertices, [("triangle", m.triangles)]))
    assert (tmp_path / "d.vtu").stat().st_mode & 0o777 == 0o666 & ~umask
