"""Surface meshes with their data arrays in, result meshes out (atomically).

:func:`read_surface` reads any surface format meshio reads (VTU, VTK, XDMF,
PLY, OBJ, STL, OFF, MSH, ...; trimesh for the formats meshio lacks, e.g.
GLB/GLTF, geometry only) and keeps the point and cell data, mapped onto the
checked :class:`~shellritz.mesh.Mesh` (unused vertices dropped, STL vertices
merged).  :func:`write_mesh` writes a meshio mesh to a temporary file in the
target folder and renames it into place, so a crash or Ctrl-C never leaves a
half-written output.
"""

import hashlib
import io
import os
import tempfile
from contextlib import contextmanager, redirect_stderr, redirect_stdout
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .mesh import Mesh, MeshError, _merge_coincident

__all__ = ["Surface", "read_surface", "write_mesh", "write_text", "atomic_path", "file_format",
           "sha256", "FORMATS_WITH_DATA"]

_UMASK = os.umask(0o022)
os.umask(_UMASK)
# formats whose meshio writers keep (multi-component) point and cell data
FORMATS_WITH_DATA = ("vtu", "vtk", "xdmf", "gmsh")
# meshio writer options: inline XDMF data (no companion .h5 file to keep in step)
_WRITE_OPTIONS = {"xdmf": {"data_format": "XML"}}


@dataclass
class Surface:
    """A checked mesh and the data arrays of its file (keyed by name)."""

    mesh: Mesh
    point_data: dict = field(default_factory=dict)
    cell_data: dict = field(default_factory=dict)

    def array(self, name):
        """(values, "point" | "cell") of a named array; KeyError naming the
        available arrays if absent."""
        if name in self.point_data:
            return self.point_data[name], "point"
        if name in self.cell_data:
            return self.cell_data[name], "cell"
        have = sorted(set(self.point_data) | set(self.cell_data))
        raise KeyError(f"the mesh has no array {name!r} (point or cell data); "
                       f"its arrays: {', '.join(have) if have else 'none'}")


def file_format(path):
    """meshio's format name for a path (by extension)."""
    import meshio
    ext = "".join(Path(path).suffixes[-1:]).lower()
    types = meshio.extension_to_filetypes.get(ext)
    if not types:
        raise ValueError(f"{path}: unknown mesh format {ext!r}; known: "
                         f"{', '.join(sorted(meshio.extension_to_filetypes))}")
    return "gmsh" if "gmsh" in types else types[0]


def read_surface(path, normal=None):
    """Read a triangulated surface with its point and cell data."""
    import meshio
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"{path}: no such file")
    if path.stat().st_size == 0:
        raise MeshError(f"{path}: empty file")
    point_data, cell_data = {}, {}
    said = io.StringIO()                      # what meshio prints before it exits
    try:
        with redirect_stdout(said), redirect_stderr(said):
            m = meshio.read(path)
    except (Exception, SystemExit) as exc:   # no reader, or cannot parse (meshio exits): trimesh
        m = None
        meshio_error = exc
    if m is not None:
        points = np.asarray(m.points, dtype=np.float64)
        if points.ndim == 2 and points.shape[1] == 2:
            points = np.c_[points, np.zeros(len(points))]
        other = {b.type: 0 for b in m.cells if b.type not in ("triangle", "vertex", "line")}
        for b in m.cells:
            if b.type in other:
                other[b.type] += len(b.data)
        if other:
            desc = ", ".join(f"{n} {t}" for t, n in other.items())
            raise MeshError(f"{path}: non-triangle cells ({desc}); triangulate the surface first")
        blocks = [k for k, b in enumerate(m.cells) if b.type == "triangle"]
        if not blocks:
            raise MeshError(f"{path}: no triangle cells")
        triangles = np.concatenate([np.asarray(m.cells[k].data) for k in blocks])
        point_data = {k: np.asarray(v) for k, v in m.point_data.items()}
        cell_data = {k: np.concatenate([np.asarray(v[b]) for b in blocks])
                     for k, v in m.cell_data.items()}
    else:
        import trimesh
        try:
            with redirect_stdout(io.StringIO()), redirect_stderr(io.StringIO()):   # its meshio's prints
                tm = trimesh.load(path, force="mesh", process=False)
        except Exception as exc:
            why = (" ".join(said.getvalue().split()) or "no parse" if isinstance(meshio_error, SystemExit)
                   else f"{type(meshio_error).__name__}: {meshio_error}")
            raise MeshError(f"{path}: cannot read it (meshio: {why}; trimesh: "
                            f"{type(exc).__name__}: {exc})") from None
        points = np.asarray(tm.vertices, dtype=np.float64)
        triangles = np.asarray(tm.faces)
        if not len(triangles):
            raise MeshError(f"{path}: no triangle cells")
    if path.suffix.lower() == ".stl":
        points, triangles = _merge_coincident(points, triangles)
        point_data = {}                 # STL has no point data; its facet normals are not kept
        cell_data = {}
    import warnings
    with warnings.catch_warnings():
        # dropped unused vertices: Mesh.kept says which (other warnings pass)
        warnings.filterwarnings("ignore", message="dropping .* unused vertices")
        mesh = Mesh(points, triangles, normal=normal)
    point_data = {k: v[mesh.kept] for k, v in point_data.items() if len(v) == len(points)}
    return Surface(mesh, point_data, cell_data)


@contextmanager
def atomic_path(path):
    """A temporary path in the folder of ``path`` (same extension); renamed to
    ``path`` when the block ends without an exception, removed otherwise."""
    path = Path(path)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.stem}.", suffix=path.suffix + ".part",
                               dir=path.parent)
    os.close(fd)
    os.chmod(tmp, 0o666 & ~_UMASK)          # mkstemp makes 0600; outputs get the usual mode
    try:
        yield Path(tmp)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def write_mesh(path, mesh):
    """Write a meshio.Mesh atomically; the format follows the extension."""
    import meshio
    fmt = file_format(path)
    with atomic_path(path) as tmp:
        meshio.write(tmp, mesh, file_format=fmt, **_WRITE_OPTIONS.get(fmt, {}))


def write_text(path, text):
    """Write a text file atomically."""
    with atomic_path(path) as tmp:
        tmp.write_text(text)


def sha256(path):
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for chunk in iter(lambda: f.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()
