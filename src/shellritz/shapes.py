"""Mesh generators for common reference surfaces (tests, benchmarks, examples).

All return a :class:`~shellritz.mesh.Mesh` with consistently oriented
triangles; curved surfaces get their exact normals.  ``perturb`` moves
interior nodes randomly (fraction of the local spacing, along the surface)
for irregular-mesh studies.
"""

import numpy as np

from .mesh import Mesh

__all__ = ["rectangle", "cylinder", "sphere", "hemisphere", "disc", "revolution"]


def _grid_triangles(nu, nv, pattern="alternate", periodic_u=False):
    """Triangles of an (nu+1) x (nv+1) grid of nodes (u-major)."""
    cols = nu if periodic_u else nu + 1
    idx = lambda i, j: (i % cols) * (nv + 1) + j
    T = []
    for i in range(nu):
        for j in range(nv):
            a, b, c, d = idx(i, j), idx(i + 1, j), idx(i + 1, j + 1), idx(i, j + 1)
            diag = (i + j) % 2 == 0 if pattern == "alternate" else pattern == "right"
            if diag:
                T += [[a, b, c], [a, c, d]]
            else:
                T += [[a, b, d], [b, c, d]]
    return np.array(T)


def _perturb(uv, interior, amount, spacing, seed):
    if not amount:
        return uv
    rng = np.random.default_rng(seed)
    uv = uv.copy()
    uv[interior] += amount * spacing * rng.uniform(-0.5, 0.5, size=(interior.sum(), 2))
    return uv


def rectangle(nx, ny, lx=1.0, ly=1.0, origin=(0.0, 0.0), pattern="alternate", perturb=0.0, seed=0):
    """Flat rectangle [x0, x0+lx] x [y0, y0+ly] in the plane z = 0, normal +z."""
    u = np.linspace(0.0, lx, nx + 1)
    v = np.linspace(0.0, ly, ny + 1)
    U, V = np.meshgrid(u, v, indexing="ij")
    uv = np.c_[U.ravel(), V.ravel()]
    interior = (uv[:, 0] > 1e-12 * lx) & (uv[:, 0] < lx * (1 - 1e-12)) & \
               (uv[:, 1] > 1e-12 * ly) & (uv[:, 1] < ly * (1 - 1e-12))
    uv = _perturb(uv, interior, perturb, np.array([lx / nx, ly / ny]), seed)
    X = np.c_[uv[:, 0] + origin[0], uv[:, 1] + origin[1], np.zeros(len(uv))]
    return Mesh(X, _grid_triangles(nx, ny, pattern), normal=lambda X: np.tile([0.0, 0, 1], (len(X), 1)))


def cylinder(ntheta, nz, radius=1.0, length=1.0, theta=(0.0, 2 * np.pi), z0=0.0,
             pattern="alternate", perturb=0.0, seed=0):
    """Cylinder (axis z) of given radius, outward normal; full when theta spans 2 pi."""
    full = np.isclose(theta[1] - theta[0], 2 * np.pi)
    nu = ntheta
    th = np.linspace(theta[0], theta[1], nu + 1)[: nu if full else nu + 1]
    z = np.linspace(z0, z0 + length, nz + 1)
    TH, Z = np.meshgrid(th, z, indexing="ij")
    uv = np.c_[TH.ravel(), Z.ravel()]
    interior = (uv[:, 1] > z0 + 1e-12) & (uv[:, 1] < z0 + length - 1e-12)
    if not full:
        interior &= (uv[:, 0] > theta[0] + 1e-12) & (uv[:, 0] < theta[1] - 1e-12)
    uv = _perturb(uv, interior, perturb, np.array([(theta[1] - theta[0]) / nu, length / nz]), seed)
    X = np.c_[radius * np.cos(uv[:, 0]), radius * np.sin(uv[:, 0]), uv[:, 1]]
    T = _grid_triangles(nu, nz, pattern, periodic_u=full)
    normal = lambda X: np.c_[X[:, 0], X[:, 1], 0 * X[:, 2]] / np.hypot(X[:, 0], X[:, 1])[:, None]
    return Mesh(X, T, normal=normal)


def _subdivide(X, T):
    edges = {}
    newT = []
    Xl = list(X)

    def mid(a, b):
        key = (min(a, b), max(a, b))
        if key not in edges:
            Xl.append(0.5 * (Xl[a] + Xl[b]))
            edges[key] = len(Xl) - 1
        return edges[key]
    for a, b, c in T:
        ab, bc, ca = mid(a, b), mid(b, c), mid(c, a)
        newT += [[a, ab, ca], [ab, b, bc], [ca, bc, c], [ab, bc, ca]]
    return np.array(Xl), np.array(newT)


def sphere(levels=3, radius=1.0, center=(0.0, 0.0, 0.0)):
    """Icosphere (closed, outward normal) with 20 * 4**levels triangles."""
    p = (1 + np.sqrt(5)) / 2
    X = np.array([[-1, p, 0], [1, p, 0], [-1, -p, 0], [1, -p, 0], [0, -1, p], [0, 1, p],
                  [0, -1, -p], [0, 1, -p], [p, 0, -1], [p, 0, 1], [-p, 0, -1], [-p, 0, 1]], float)
    T = np.array([[0, 11, 5], [0, 5, 1], [0, 1, 7], [0, 7, 10], [0, 10, 11], [1, 5, 9], [5, 11, 4],
                  [11, 10, 2], [10, 7, 6], [7, 1, 8], [3, 9, 4], [3, 4, 2], [3, 2, 6], [3, 6, 8],
                  [3, 8, 9], [4, 9, 5], [2, 4, 11], [6, 2, 10], [8, 6, 7], [9, 8, 1]])
    X /= np.linalg.norm(X, axis=1)[:, None]
    for _ in range(levels):
        X, T = _subdivide(X, T)
        X /= np.linalg.norm(X, axis=1)[:, None]
    c = np.asarray(center, float)
    return Mesh(radius * X + c, T, normal=lambda Y: (Y - c) / np.linalg.norm(Y - c, axis=1)[:, None])


def hemisphere(nphi, ntheta, radius=1.0, hole_deg=18.0, phi=(0.0, 2 * np.pi), pattern="alternate"):
    """Hemisphere z >= 0 with a polar hole of half-angle hole_deg (the
    pinched-hemisphere benchmark); coordinates: polar angle from hole_deg to
    90 degrees (equator), azimuth over the range phi.  Outward normal."""
    full = np.isclose(phi[1] - phi[0], 2 * np.pi)
    th = np.linspace(np.radians(hole_deg), np.pi / 2, ntheta + 1)
    ph = np.linspace(phi[0], phi[1], nphi + 1)[: nphi if full else nphi + 1]
    PH, TH = np.meshgrid(ph, th, indexing="ij")
    X = radius * np.c_[(np.sin(TH) * np.cos(PH)).ravel(), (np.sin(TH) * np.sin(PH)).ravel(),
                       np.cos(TH).ravel()]
    T = _grid_triangles(nphi, ntheta, pattern, periodic_u=full)
    # (phi, theta) grid is left-handed w.r.t. the outward normal: flip
    T = T[:, [0, 2, 1]]
    return Mesh(X, T, normal=lambda Y: Y / np.linalg.norm(Y, axis=1)[:, None])


def disc(nr, radius=1.0, perturb=0.0, seed=0):
    """Flat disc (normal +z): rings of 6 k nodes, Delaunay triangulated."""
    from scipy.spatial import Delaunay
    pts = [np.zeros((1, 2))]
    for k in range(1, nr + 1):
        m = 6 * k
        a = 2 * np.pi * (np.arange(m) + 0.5 * (k % 2)) / m
        pts.append(radius * k / nr * np.c_[np.cos(a), np.sin(a)])
    uv = np.concatenate(pts)
    interior = np.linalg.norm(uv, axis=1) < radius * (1 - 1e-9)
    uv = _perturb(uv, interior, perturb, radius / nr, seed)
    T = Delaunay(uv).simplices
    P = uv[T]
    cr = (P[:, 1, 0] - P[:, 0, 0]) * (P[:, 2, 1] - P[:, 0, 1]) - (P[:, 1, 1] - P[:, 0, 1]) * (P[:, 2, 0] - P[:, 0, 0])
    T[cr < 0] = T[cr < 0][:, [0, 2, 1]]
    X = np.c_[uv, np.zeros(len(uv))]
    return Mesh(X, T, normal=lambda Y: np.tile([0.0, 0, 1], (len(Y), 1)))


def revolution(curve, s, nphi, phi=(0.0, np.pi / 2)):
    """Surface of revolution about z of the meridian curve(s) -> (r, z, r', z')
    with node rings at the parameters s and azimuth over the range phi.

    The widest ring gets nphi intervals; every other ring gets a number
    proportional to its radius (at least one), so elements stay nearly
    isotropic down to a pole (r = 0, a single node).  Returns the mesh, with
    exact normals r_phi x r_s (outward for a meridian running upward), and the
    meridian parameter s of every node.
    """
    s = np.asarray(s, dtype=np.float64)
    r, z, dr, dz = (np.asarray(v, dtype=np.float64) for v in curve(s))
    span = phi[1] - phi[0]
    full = np.isclose(span, 2 * np.pi)
    pole = np.abs(r) <= 1e-12 * np.ptp(np.r_[r, z])
    counts = np.where(pole, 0, np.maximum(1 if not full else 3, np.ceil(nphi * r / r.max() - 1e-9))).astype(int)
    X, N, S, rings = [], [], [], []
    for i in range(len(s)):
        m = counts[i]
        nodes = 1 if pole[i] else m if full else m + 1
        ang = phi[0] + span * np.arange(nodes) / max(m, 1)
        nvec = np.array([dz[i], -dr[i]]) / np.hypot(dz[i], dr[i])
        rings.append((len(X) + np.arange(len(ang)), ang))
        X += [[r[i] * np.cos(a), r[i] * np.sin(a), z[i]] for a in ang]
        N += [[nvec[0] * np.cos(a), nvec[0] * np.sin(a), nvec[1]] for a in ang]
        S += [s[i]] * len(ang)
    T = []
    for (ia, aa), (ib, ab) in zip(rings[:-1], rings[1:]):
        T += _stitch(ia, aa, ib, ab, full, span)
    N = np.array(N)
    return Mesh(np.array(X), np.array(T), normal=lambda Y: N), np.array(S)


def _stitch(ia, aa, ib, ab, full, span):
    """Triangles between two node rings (ids ia, ib at azimuths aa, ab; the
    second at the larger s), advancing on whichever ring has the nearer next
    azimuth.  Orientation (phi, s): (a_j, a_j+1, b_k) and (a_j, b_k+1, b_k)."""
    if full:      # close the rings: repeat the first node at phi + 2 pi
        ia, aa = np.r_[ia, ia[:1]], np.r_[aa, aa[:1] + span]
        ib, ab = np.r_[ib, ib[:1]], np.r_[ab, ab[:1] + span]
    T, j, k = [], 0, 0
    while j < len(ia) - 1 or k < len(ib) - 1:
        advance_a = k == len(ib) - 1 or (j < len(ia) - 1 and aa[j + 1] <= ab[k + 1])
        if advance_a:
            T.append((ia[j], ia[j + 1], ib[k]))
            j += 1
        else:
            T.append((ia[j], ib[k + 1], ib[k]))
            k += 1
    return [t for t in T if len(set(t)) == 3]
