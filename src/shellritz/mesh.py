"""Triangulated reference surfaces: reading, checking, normals and frames.

A :class:`Mesh` is built from ``(vertices, triangles)`` arrays or read from any
surface format meshio reads (VTU, MSH, OBJ, PLY, STL, OFF, ...; trimesh is
used as a fallback reader).  Construction checks the mesh and raises
:class:`MeshError` naming the offending elements and nodes:

* cells that are not triangles, indices out of range, NaN/inf coordinates;
* degenerate triangles (repeated vertex or zero area) and duplicate triangles;
* non-manifold edges (shared by more than two triangles) and non-manifold
  vertices (triangles around a vertex forming more than one fan);
* inconsistent orientation (an interior edge traversed twice in the same
  direction).

Unused vertices are dropped with a warning (``Mesh.kept`` maps new to old
indices).  Nodal normals come from an analytic function when given,
otherwise they are angle-weighted averages of the facet normals; nodal tangent
frames ``T[i] = (T_i1, T_i2)`` are orthonormal with ``T_i1 x T_i2 = N_i``.
"""

import warnings
from pathlib import Path

import numpy as np

# a boundary node where the boundary turns by more than this is a corner
# (hinged edges fix both derivatives there; coarse meshes keep it)
CORNER_DEG = 30.0

__all__ = ["Mesh", "MeshError"]


class MeshError(ValueError):
    """The mesh cannot be used; the message names the elements/nodes."""


def _list(idx, limit=8):
    idx = [int(i) for i in np.atleast_1d(idx)]
    s = ", ".join(map(str, idx[:limit]))
    return s + (f", ... ({len(idx)} in all)" if len(idx) > limit else "")


# triangle shape quality (Mesh._check_triangles): refused below SLIVER_QUALITY,
# a warning below POOR_QUALITY, and named in the error of a solve that fails
# (measured on a grown 4 x 4 square, h = 0.05, with a thin triangle added on
# its boundary, tests/test_validity.py: converges at quality 4.6e-3 in 18 Newton
# iterations, at 1.4e-3 in 1,326, and fails at 4.6e-4 and below)
SLIVER_QUALITY = 1e-6
POOR_QUALITY = 1e-2


def _worst(quality, below):
    """The triangles of shape quality below ``below``, worst first (only
    those are sorted: a mesh of 2M triangles has few or none)."""
    idx = np.flatnonzero(quality < below)
    return idx[np.argsort(quality[idx], kind="stable")]


def _same_positions(points):
    """np.unique (first, inverse, counts) of the points rounded to 1e-10 of the
    mesh size: points at one position share their entry."""
    key = np.round(points / (1e-10 * max(np.ptp(points, axis=0).max(), 1e-300))).astype(np.int64)
    _, first, inverse, counts = np.unique(key, axis=0, return_index=True, return_inverse=True,
                                          return_counts=True)
    return first, inverse.reshape(-1), counts


def _merge_coincident(points, triangles):
    first, inverse, _ = _same_positions(points)
    return points[first], inverse[triangles]


def _angle_weighted_normals(X, tri):
    n = np.zeros_like(X)
    P = X[tri]
    fn = np.cross(P[:, 1] - P[:, 0], P[:, 2] - P[:, 0])
    fn /= np.linalg.norm(fn, axis=1)[:, None]
    for k in range(3):
        a = P[:, (k + 1) % 3] - P[:, k]
        b = P[:, (k + 2) % 3] - P[:, k]
        cosang = np.einsum("ij,ij->i", a, b) / (np.linalg.norm(a, axis=1) * np.linalg.norm(b, axis=1))
        ang = np.arccos(np.clip(cosang, -1.0, 1.0))
        np.add.at(n, tri[:, k], ang[:, None] * fn)
    return n / np.linalg.norm(n, axis=1)[:, None]


def tangent_frames(N):
    """Orthonormal T (n, 3, 2) with T[:, :, 0] x T[:, :, 1] = N."""
    axis = np.argmin(np.abs(N), axis=1)
    e = np.zeros_like(N)
    e[np.arange(len(N)), axis] = 1.0
    t1 = e - np.einsum("ij,ij->i", e, N)[:, None] * N
    t1 /= np.linalg.norm(t1, axis=1)[:, None]
    t2 = np.cross(N, t1)
    return np.stack([t1, t2], axis=2)


class Mesh:
    """A checked triangulated reference surface.

    Parameters
    ----------
    vertices, triangles : arrays (n, 3) float and (m, 3) int, or
    path : a mesh file (use :meth:`Mesh.read`).
    normal : optional callable ``normal(X) -> (n, 3)`` giving the exact unit
        normals of the reference surface at the vertices (a sphere:
        ``lambda X: X / norm(X)``); default: angle-weighted facet normals.
    """

    def __init__(self, vertices, triangles, normal=None):
        X = np.asarray(vertices, dtype=np.float64)
        tri = np.asarray(triangles)
        if X.ndim != 2 or X.shape[1] != 3:
            raise MeshError(f"vertices must have shape (n, 3), got {X.shape}")
        if tri.ndim != 2 or tri.shape[1] != 3:
            raise MeshError(f"triangles must have shape (m, 3), got {tri.shape}; only triangle cells are supported")
        if not np.issubdtype(tri.dtype, np.integer):
            if not np.issubdtype(tri.dtype, np.number) or not np.all(tri == np.round(tri)):
                raise MeshError("triangle indices must be integers")
        tri = tri.astype(np.int64)
        if len(tri) == 0:
            raise MeshError("the mesh has no triangles")
        bad = np.where(~np.all(np.isfinite(X), axis=1))[0]
        if len(bad):
            raise MeshError(f"non-finite coordinates at vertices {_list(bad)}")
        out = np.where((tri < 0).any(axis=1) | (tri >= len(X)).any(axis=1))[0]
        if len(out):
            raise MeshError(f"triangles {_list(out)} reference vertices outside 0..{len(X) - 1}")
        used = np.zeros(len(X), bool)
        used[tri.ravel()] = True
        if not used.all():
            unused = np.where(~used)[0]
            warnings.warn(f"dropping {len(unused)} unused vertices ({_list(unused)})", stacklevel=2)
            newidx = -np.ones(len(X), np.int64)
            newidx[used] = np.arange(used.sum())
            self.kept = np.where(used)[0]
            X = X[used]
            tri = newidx[tri]
        else:
            self.kept = np.arange(len(X))
        self.vertices = X
        self.triangles = tri
        self._check_triangles()
        self._warn_coincident()
        self._build_edges()
        self._check_vertex_fans()
        if normal is None:
            self.normals = _angle_weighted_normals(X, tri)
            self.analytic_normals = False
        else:
            N = np.asarray(normal(X), dtype=np.float64)
            if N.shape != X.shape or not np.all(np.isfinite(N)):
                raise MeshError("normal(X) must return finite (n, 3) normals")
            length = np.linalg.norm(N, axis=1)
            zero = np.where(~(length > 0))[0]
            if len(zero):
                raise MeshError(f"normal(X) is the zero vector at vertices {_list(zero)}")
            N = N / length[:, None]
            P = X[tri]
            fn = np.cross(P[:, 1] - P[:, 0], P[:, 2] - P[:, 0])
            flipped = np.where((np.einsum("ij,ij->i", fn, N[tri].mean(axis=1)) <= 0))[0]
            if len(flipped):
                raise MeshError(f"analytic normals point against the orientation of triangles "
                                f"{_list(flipped)}; reverse the triangle order or the normal")
            self.normals = N
            self.analytic_normals = True
        self.frames = tangent_frames(self.normals)

    @classmethod
    def read(cls, path, normal=None):
        """The triangulated surface in the file (any format meshio or trimesh
        reads: meshdata.read_surface; STL vertices merged, unused vertices
        dropped: ``kept`` says which remain)."""
        from .meshdata import read_surface
        return read_surface(path, normal=normal).mesh

    # -- checks -----------------------------------------------------------
    def _check_triangles(self):
        X, tri = self.vertices, self.triangles
        rep = np.where((tri[:, 0] == tri[:, 1]) | (tri[:, 1] == tri[:, 2]) | (tri[:, 0] == tri[:, 2]))[0]
        if len(rep):
            raise MeshError(f"degenerate triangles {_list(rep)}: a vertex is repeated")
        P = X[tri]
        cr = np.cross(P[:, 1] - P[:, 0], P[:, 2] - P[:, 0])
        area2 = np.linalg.norm(cr, axis=1)
        edges2 = np.array([np.sum((P[:, (k + 1) % 3] - P[:, k]) ** 2, axis=1) for k in range(3)])
        lmax2 = edges2.max(axis=0)
        flat = np.where(area2 <= 1e-12 * lmax2)[0]
        if len(flat):
            raise MeshError(f"degenerate triangles {_list(flat)}: zero area "
                            f"(vertices {_list(tri[flat[0]])} are collinear)")
        # shape quality 4 sqrt(3) area / (sum of squared edges): 1 equilateral, 0 degenerate
        quality = 2.0 * np.sqrt(3.0) * area2 / edges2.sum(axis=0)
        sliver = _worst(quality, SLIVER_QUALITY)
        if len(sliver):
            raise MeshError(f"nearly degenerate triangles {_list(sliver)}: shape quality "
                            f"{quality[sliver[0]]:.2e} (1 for an equilateral triangle; below "
                            f"{SLIVER_QUALITY:g} the element's equations are singular to round-off)")
        self.quality = quality
        poor = self.poor_triangles()
        if poor:
            warnings.warn(f"{poor}: the DKT element is ill-conditioned on them and Newton may fail; "
                          f"remesh them", stacklevel=3)
        key = np.sort(tri, axis=1)
        _, first, inv, cnt = np.unique(key, axis=0, return_index=True, return_inverse=True,
                                       return_counts=True)
        dup = np.where(cnt[inv.ravel()] > 1)[0]
        if len(dup):
            raise MeshError(f"duplicate triangles {_list(dup)} (same three vertices)")
        self.facet_normals = cr / area2[:, None]
        self.areas = 0.5 * area2

    def poor_triangles(self):
        """The triangles of shape quality below POOR_QUALITY, worst first, in
        words ('' if none)."""
        poor = _worst(self.quality, POOR_QUALITY)
        if not len(poor):
            return ""
        return (f"{len(poor)} poorly shaped triangles ({_list(poor)}), shape quality down to "
                f"{self.quality[poor[0]]:.2e} (1 for an equilateral triangle)")

    def _warn_coincident(self):
        """Distinct vertices at one position leave the surface cut there (a
        seam not merged): a warning, since a cut may be meant."""
        _, inverse, counts = _same_positions(self.vertices)
        same = np.where(counts[inverse] > 1)[0]
        if len(same):
            warnings.warn(f"{len(same)} vertices share a position with another ({_list(same)}): the "
                          f"surface is cut there; merge them if it is continuous", stacklevel=3)

    def _build_edges(self):
        tri = self.triangles
        m = len(tri)
        he = np.stack([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [2, 0]]], axis=1).reshape(-1, 2)
        key = np.sort(he, axis=1)
        edges, inv, cnt = np.unique(key, axis=0, return_inverse=True, return_counts=True)
        inv = inv.ravel()
        bad = np.where(cnt > 2)[0]
        if len(bad):
            e = edges[bad[0]]
            owners = np.where(inv == bad[0])[0] // 3
            raise MeshError(f"non-manifold edges: {len(bad)} edges shared by more than two triangles, "
                            f"e.g. edge ({e[0]}, {e[1]}) in triangles {_list(owners)}")
        # orientation: the two half-edges of an interior edge must be opposite
        order = np.argsort(inv, kind="stable")
        s_inv = inv[order]
        pair = np.where(s_inv[1:] == s_inv[:-1])[0]
        h1, h2 = order[pair], order[pair + 1]
        same = np.where(np.all(he[h1] == he[h2], axis=1))[0]
        if len(same):
            t1, t2 = h1[same] // 3, h2[same] // 3
            raise MeshError(f"inconsistent orientation: {len(same)} interior edges traversed in the same "
                            f"direction, e.g. triangles {t1[0]} and {t2[0]} across edge "
                            f"({he[h1[same[0]], 0]}, {he[h1[same[0]], 1]}); orient the triangles consistently")
        self.edges = edges
        self.edge_of_halfedge = inv.reshape(m, 3)   # edge k of triangle: vertices (k, k+1)
        bmask = cnt == 1
        bhe = np.where(bmask[inv])[0]
        self.boundary_edges = he[bhe]               # oriented as in their triangle
        self.boundary_edge_triangles = bhe // 3

    def _check_vertex_fans(self):
        """Each vertex's triangles must form one edge-connected fan: the link
        graph of every vertex (its neighbours, joined across each of its
        triangles) is connected.  All links at once, as one sparse graph whose
        nodes are the (vertex, neighbour) pairs."""
        from scipy.sparse import coo_matrix
        from scipy.sparse.csgraph import connected_components
        tri = self.triangles.astype(np.int64)
        n = len(self.vertices)
        corner = tri.ravel()
        a = np.roll(tri, -1, axis=1).ravel()
        b = np.roll(tri, -2, axis=1).ravel()
        keys, inv = np.unique(np.r_[corner * n + a, corner * n + b], return_inverse=True)
        m = len(corner)
        graph = coo_matrix((np.ones(m), (inv[:m], inv[m:])), shape=(len(keys), len(keys)))
        _, label = connected_components(graph, directed=False)
        owner = keys // n
        fans = np.bincount(np.unique(owner * len(keys) + label) // len(keys), minlength=n)
        bad = np.where(fans > 1)[0]
        if len(bad):
            raise MeshError(f"non-manifold vertices {_list(bad)}: their triangles form more than one fan")

    # -- node selections ----------------------------------------------------
    @property
    def n_nodes(self):
        return len(self.vertices)

    @property
    def n_triangles(self):
        return len(self.triangles)

    def boundary_loops(self):
        """Boundary loops as ordered node arrays (following the orientation)."""
        nxt = {int(a): int(b) for a, b in self.boundary_edges}
        loops, seen = [], set()
        for start in sorted(nxt):
            if start in seen:
                continue
            loop, v = [], start
            while v not in seen:
                seen.add(v)
                loop.append(v)
                v = nxt[v]
            loops.append(np.array(loop))
        return loops

    def boundary_corners(self):
        """Boundary nodes where the boundary turns by more than CORNER_DEG."""
        X, corners = self.vertices, []
        for loop in self.boundary_loops():
            back, ahead = X[loop] - X[np.roll(loop, 1)], X[np.roll(loop, -1)] - X[loop]
            cos = np.einsum("ij,ij->i", back, ahead) / (np.linalg.norm(back, axis=1)
                                                        * np.linalg.norm(ahead, axis=1))
            corners.extend(loop[cos < np.cos(np.radians(CORNER_DEG))])
        return np.asarray(corners, dtype=np.int64)

    def boundary_nodes(self, loop=None):
        """Nodes on the boundary (all loops, or loop number ``loop``)."""
        loops = self.boundary_loops()
        if loop is None:
            return np.unique(np.concatenate(loops)) if loops else np.zeros(0, np.int64)
        return loops[loop]

    def nodes_on_plane(self, axis, value, tol=None):
        """Nodes with X[axis] == value (within tol, default 1e-9 of the mesh size)."""
        ax = "xyz".index(axis) if isinstance(axis, str) else int(axis)
        tol = 1e-9 * np.ptp(self.vertices, axis=0).max() if tol is None else tol
        return np.where(np.abs(self.vertices[:, ax] - value) <= tol)[0]

    def nodes_where(self, predicate):
        """Nodes whose reference position satisfies predicate(X) -> bool array."""
        return np.where(np.asarray(predicate(self.vertices), bool))[0]
