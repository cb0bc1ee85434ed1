"""Nested iteration on any mesh: coarser meshes of the same surface are made
automatically, the scene is solved on the coarsest first, and each finer
mesh starts from the coarser equilibrium (``Shell.solve(start=result)``,
transfer.py).  On the 50k- and 100k-triangle leaf this replaces 18 Newton
iterations on the fine mesh by 2-4 (README "Scaling").

Coarsening (gpytoolbox, libigl's decimation and Botsch-Kobbelt remeshing):

1. shortest-edge decimation to the target number of triangles (uniform
   element sizes, but each collapse puts the new vertex at the edge's
   midpoint, so a curved surface or a curved or cornered boundary shrinks:
   the vertices are moved back onto the fine surface);
2. triangles with two boundary edges (ears) are dropped, and the boundary
   is put back: each corner of the fine boundary (Mesh.boundary_corners:
   turning angle above 30 degrees) takes the nearest coarse boundary vertex, every other
   coarse boundary vertex goes to the nearest point of the fine boundary
   polyline;
3. isotropic remeshing at the target edge length with the boundary vertices
   kept (interior shape quality: on the 50k disc the worst triangle's
   4 sqrt(3) A / sum l^2 is 0.46-0.7 at 1/4-1/64 of the triangles, against
   0.01 for quadric-error decimation, which keeps corners but leaves
   slivers on flat parts); the interior vertices go onto the fine surface
   once more (the remeshing projects them onto the decimated one).

Measured against the alternatives in the README ("Nested iteration on your
own mesh").
"""

import time
import warnings

import numpy as np
from scipy.spatial import cKDTree

from .mesh import Mesh, MeshError
from .shell import Shell
from .solve import SolverOptions, solver_options
from .transfer import locate

COARSEST = 1500         # triangles of the coarsest level (the 16-ring leaf: 1,536)
FACTOR = 4              # triangles per level
# relative gradient tolerance of the coarse levels (the given rtol where it is
# looser): a coarse equilibrium is only the next level's start, whose
# gradient the transfer sets (the 100k leaf from its 25k level: |g| 1.2e-7,
# 2.4e-3 of the reference state's, either way); 1e-6 instead of 1e-8 saves
# the 25k level one of its three Newton steps (8.9 -> 7.5 s) and leaves the
# fine level's two steps and its energy (to 3e-13) as they were
COARSE_RTOL = 1e-6


def coarse_rtol(rtol):
    """The relative tolerance of a coarse level where the given mesh's is
    rtol (a value that is not a number is left to Shell.solve to refuse)."""
    if isinstance(rtol, (int, float)) and not isinstance(rtol, bool):
        return max(rtol, COARSE_RTOL)
    return rtol


def _gpytoolbox():
    try:
        with warnings.catch_warnings():       # its modules import deprecated NumPy/SciPy names
            warnings.simplefilter("ignore", DeprecationWarning)
            import gpytoolbox
    except ImportError:
        raise ImportError("nested iteration on a mesh (solve_nested, coarsen) needs gpytoolbox: "
                          "pip install 'shellritz[coarsen]'") from None
    return gpytoolbox


def _boundary_edges(tri):
    e = np.sort(np.concatenate([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [2, 0]]]), axis=1)
    u, count = np.unique(e, axis=0, return_counts=True)
    return u[count == 1]


def _without_ears(V, T):
    """Drop the triangles of vertices in one triangle only (ears: two of
    their edges on the boundary, left by the decimation at a boundary; put
    back on the boundary, the ear's tip would flatten it into a sliver)."""
    T = np.asarray(T, dtype=np.int64)
    while True:
        ear = np.bincount(T.ravel(), minlength=len(V)) == 1
        keep = ~ear[T].any(axis=1)
        if keep.all():
            break
        T = T[keep]
    used = np.unique(T)
    index = np.full(len(V), -1, np.int64)
    index[used] = np.arange(len(used))
    return V[used], index[T]


def _onto(fine, V):
    """The points V moved onto the fine surface (the nearest point of the
    fine triangle that holds their projection, transfer.locate)."""
    t, lam, _, _ = locate(fine.vertices, fine.triangles, V)
    lam = np.clip(lam, 0.0, None)
    lam /= lam.sum(axis=1)[:, None]
    return np.einsum("nk,nkj->nj", lam, fine.vertices[fine.triangles[t]])


def interpolate(fine, values, points):
    """Nodal ``values`` (n, ...) of the mesh ``fine`` at ``points`` on its
    surface (a coarse mesh's vertices): linear in the fine triangle that
    holds each point (transfer.locate); integer and boolean values (labels,
    masks) are those of that triangle's nearest vertex, and each fine node
    with a non-zero value gives it to the nearest point if that has none (a
    mask of single nodes, e.g. a pinned point, selects points there too)."""
    values = np.asarray(values)
    t, lam, _, _ = locate(fine.vertices, fine.triangles, points)
    corners = fine.triangles[t]
    if values.dtype.kind not in "biu":
        return np.einsum("nk,nk...->n...", lam, values[corners])
    out = values[corners[np.arange(len(t)), np.argmax(lam, axis=1)]]
    marked = np.where(values.reshape(len(values), -1).any(axis=1))[0]
    if len(marked):
        _, near = cKDTree(points).query(fine.vertices[marked])
        empty = ~out[near].reshape(len(near), -1).any(axis=1)
        out[near[empty]] = values[marked[empty]]
    return out


def _restore_boundary(fine, V, tri):
    """Step 2 of the module docstring, in place on the coarse vertices V."""
    bnd = np.unique(_boundary_edges(tri))
    if not len(bnd):
        return
    fX, fE = fine.vertices, fine.boundary_edges
    free = np.ones(len(bnd), bool)
    tree = cKDTree(V[bnd])
    for c in fine.boundary_corners():
        _, j = tree.query(fX[c])
        if free[j]:
            V[bnd[j]], free[j] = fX[c], False
    P = V[bnd[free]]
    a, d = fX[fE[:, 0]], fX[fE[:, 1]] - fX[fE[:, 0]]
    k = min(8, len(fE))
    _, cand = cKDTree(a + 0.5 * d).query(P, k=k)
    cand = cand.reshape(len(P), k)
    best, dist = P.copy(), np.full(len(P), np.inf)
    for j in range(k):
        e = cand[:, j]
        s = np.clip(np.einsum("ij,ij->i", P - a[e], d[e]) / np.einsum("ij,ij->i", d[e], d[e]), 0.0, 1.0)
        q = a[e] + s[:, None] * d[e]
        r = np.linalg.norm(P - q, axis=1)
        closer = r < dist
        best[closer], dist[closer] = q[closer], r[closer]
    V[bnd[free]] = best


def coarsen(mesh, n_triangles):
    """A mesh of about ``n_triangles`` triangles of the same surface as
    ``mesh`` (module docstring).  Raises MeshError when the result is not a
    valid mesh or has triangles turned against the fine surface's normals."""
    gp = _gpytoolbox()
    n_triangles = int(n_triangles)
    if n_triangles < 8 or n_triangles >= len(mesh.triangles):
        raise ValueError(f"coarsen: {n_triangles} triangles requested of a mesh of {len(mesh.triangles)}")
    X = mesh.vertices
    V, T = gp.decimate(X, mesh.triangles.astype(np.int32), num_faces=n_triangles, method="shortest_edge")[:2]
    V, T = _without_ears(np.asarray(V, dtype=np.float64), T)
    V = _onto(mesh, V)                                      # midpoints of chords lie inside
    _restore_boundary(mesh, V, T)
    edge = np.sqrt(4.0 * mesh.areas.sum() / (np.sqrt(3.0) * n_triangles))   # equilateral, that area
    V, T = gp.remesh_botsch(V, np.asarray(T, np.int32), 10, edge, True)
    inner = np.setdiff1d(np.arange(len(V)), _boundary_edges(T))  # the remeshing kept the boundary
    V[inner] = _onto(mesh, V[inner])
    coarse = Mesh(V, T)
    # orientation against the fine surface: the normal of the fine vertex nearest each centroid
    _, near = cKDTree(X).query(coarse.vertices[coarse.triangles].mean(axis=1))
    turned = np.where(np.einsum("ij,ij->i", coarse.facet_normals, mesh.normals[near]) <= 0.0)[0]
    if len(turned):
        raise MeshError(f"coarsen: {len(turned)} of {len(coarse.triangles)} coarse triangles are turned against "
                        f"the surface (e.g. triangle {turned[0]}); the mesh is too coarse for its shape")
    return coarse


def levels(mesh, coarsest=COARSEST, factor=FACTOR):
    """Triangle counts of the coarser levels, coarsest first: the fine count
    divided by factor, factor^2, ... while at least ``coarsest``."""
    if factor < 2:
        raise ValueError(f"factor must be at least 2, got {factor}")
    counts, n = [], len(mesh.triangles) // factor
    while n >= coarsest:
        counts.insert(0, n)
        n //= factor
    return counts


def solve_nested(build, mesh, coarsest=COARSEST, factor=FACTOR, verbose=True, **options):
    """Solve the scene ``build(mesh) -> Shell`` on ``mesh`` by nested
    iteration: the same scene on coarsened meshes (``coarsen``; about
    len(triangles) / factor^k triangles, the coarsest at least ``coarsest``)
    solved coarsest first with ``options`` (those of ``Shell.solve``; the
    coarsest from the reference state, with ``steps`` etc.; the coarse levels
    to a relative tolerance of at most COARSE_RTOL; ``monitor``, node indices
    of the given mesh, on the given mesh only), each finer level
    from the previous equilibrium, the given mesh last.  ``build`` must
    place the scene on any mesh of the surface (boundary conditions and
    loads selected geometrically, growth as functions of the position).

    Returns the fine mesh's Result; ``result.history.nested`` lists each
    coarse level (triangles, Newton iterations, factorizations, linear
    solver, wall time, coarsening time).  A mesh too small for a coarser level is solved
    directly.  A failed coarse solve raises its SolveError (the fine mesh
    is then better solved directly).  The coarse levels choose their linear
    solver by size (``linear="auto"``: a factorization where it fits; an
    AMG method asked for the given mesh would meet the coarse levels'
    buckling from the reference state, where it is no match for a
    factorization, README "Scaling").  A ``thickness_path`` (continuation
    in the thickness, Shell.solve) is taken by the first solve only, the
    coarsest level's (the given mesh's if it has no coarser level)."""
    if not isinstance(mesh, Mesh):
        raise TypeError(f"solve_nested: mesh must be a shellritz.Mesh, not {type(mesh).__name__}")
    first = {"thickness_path": options.pop("thickness_path")} if "thickness_path" in options else {}
    # bad options are refused before any coarse level is solved, not by the given mesh's solve
    solver_options(verbose=verbose, **{k: v for k, v in options.items() if k != "monitor"})
    # the linear solver by size, and the monitored nodes (indices of the given mesh) on it only
    coarse_options = {k: v for k, v in options.items() if k not in ("linear", "monitor")}
    coarse_options["rtol"] = coarse_rtol(options.get("rtol", SolverOptions.rtol))
    start, record = None, []
    for n in levels(mesh, coarsest, factor):
        t0 = time.perf_counter()
        coarse = coarsen(mesh, n)
        t1 = time.perf_counter()
        shell = _built(build, coarse)
        if verbose:
            print(f"nested iteration: level of {len(coarse.triangles)} triangles", flush=True)
        start = shell.solve(verbose=verbose, start=start, **coarse_options,
                            **(first if start is None else {}))
        h = start.history
        record.append(dict(n_triangles=int(len(coarse.triangles)), coarsen_s=t1 - t0,
                           wall_s=time.perf_counter() - t1, newton_its=len(h.iterations),
                           factorizations=h.factorizations, linear=h.linear,
                           thickness_stages=h.thickness_stages))
    if verbose and record:
        print(f"nested iteration: the given mesh ({len(mesh.triangles)} triangles)", flush=True)
    result = _built(build, mesh).solve(verbose=verbose, start=start, **options,
                                       **(first if start is None else {}))
    result.history.nested = record
    return result


def _built(build, mesh):
    shell = build(mesh)
    if not isinstance(shell, Shell):
        raise TypeError(f"solve_nested: build(mesh) must return a shellritz.Shell, "
                        f"not {type(shell).__name__}")
    return shell
