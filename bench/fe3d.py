"""3D solid finite-element reference solver for the shellritz benchmark scenes.

A true 3D body, meshed with curved 27-node triquadratic hexahedra (scikit-fem
``MeshHex2`` + ``ElementHex2``, isoparametric), compressible neo-Hookean
material with multiplicative growth, Newton's method with the exact consistent
tangent and load/growth continuation.  It gives 3D reference (and
cost-comparison) solutions for the four scenes the shell engines solve.

Mechanics
---------
Unknown: displacement u (Q2, three components per node), F = I + Grad u.
Energy per reference volume  det(G) W(F G^-1),
    W(Fe) = C/2 (tr Fe^T Fe - 3 - 2 ln J) + D/2 (J - 1)^2,   J = det Fe, C = 1,
minus the work of dead tractions (nominal, per reference area).  With
Gi = G^-1, g = det G, Fe = F Gi and B_a = Gi^T Grad N_a, the residual is
    R_{a i} = int g (P_e B_a)_i dV,   P_e = C Fe + (D (J-1) J - C) Fe^-T
and the tangent (exact, derived by hand and checked against finite
differences, see ``check_tangent``), with v_a = Fe^-1 B_a ... precisely
v_a = Fe^-T B_a:
    K_{ai,bj} = int g [ C (B_a . B_b) d_ij + D (2J-1) J v_ai v_bj
                        + (C - D (J-1) J) v_bi v_aj ] dV.
Growth and loads are ramped together: G_t = I + t (G - I), tractions t q;
t goes 0 -> 1 with an adaptive step (grow after easy steps, halve on Newton
failure), a secant predictor, and backtracking line search on the energy /
residual.  Intermediate steps are converged to a relative residual 1e-6, the
final step (t = 1) to 1e-10, relative to the residual norm of the undeformed
body under the full growth and load.  Linear solves: a SuperLU factorization
of the tangent, kept and reused as the preconditioner of (scipy) GMRES for
the following tangents, refactorized when GMRES needs more than 25
iterations.

Assembly: scikit-fem supplies the mesh, the isoparametric mapping, the
quadrature (3x3x3 Gauss, ``intorder=5``), the basis-function gradients and
the facet integrals of the tractions (``LinearForm``); the hyperelastic
residual and tangent are assembled vectorized over all elements and
quadrature points with batched matrix products (this is ~100x faster than
scikit-fem's generic ``BilinearForm`` loop over the 81 x 81 pairs of vector
basis functions, which matters for a cost comparison).  No Python loops over
elements anywhere.

Meshing (exact geometry at all 27 nodes of every element)
---------------------------------------------------------
A straight-sided hexahedral mesh is built in a parameter space, scikit-fem adds
the edge/face/cell nodes of the Q2 mesh at parameter midpoints
(``MeshHex2.from_mesh``), then every node is mapped by the exact smooth map of
the body, so the curved elements interpolate the true geometry
quadratically.  Radial fibres are node columns.
* tube: (theta, R, z) box, theta in [0, pi/2] with n elements,
  R in [0.95, 1.05] with m elements, one element layer in z.
* sphere: equiangular cube-sphere octant (no degenerate elements on the
  axes).  Cube-surface point p (max |p_i| = 1) and radius rho:
  X = rho tan(pi p / 4) / |tan(pi p / 4)|; three quarter faces (+x, +y, +z),
  each (n/2) x (n/2) elements, so n elements along a quarter great circle.
* invagination (sphere of centre (0, 0, 1), quarter model x, y >= 0): polar
  caps s < 0.2 pi around either pole are O-grids (a square centre patch and
  two side patches), the band between them a structured (s, phi) grid;
  n = elements along the meridian from pole to pole (uniform in s in the
  band), n_phi = 2 max(2, round(n/16)) elements around the quarter circle
  (the solution is axisymmetric: few are needed).
* strip: the box [0, pi/2] x [0, w] x [-h/2, h/2], n elements along X, one
  across the width (w = h), m through the thickness.

Elements through the thickness (the rule used by ``solve``; overridable by
``m=``):  tube m = max(1, n // 8), sphere m = max(1, n // 16),
strip m = 1 (the exact solution is linear through the thickness),
invagination m = 2 + n // 64.

Symmetry / supports
-------------------
tube: quarter, u_x = 0 on x = 0, u_y = 0 on y = 0, plane strain u_z = 0.
sphere: octant, u_x = 0 on x = 0, u_y = 0 on y = 0, u_z = 0 on z = 0.
strip: u_Y = 0 everywhere (plane strain), u_X = 0 on X = 0, u_Z = 0 on the
line X = 0, Z = 0.
invagination: quarter, u_x = 0 on x = 0, u_y = 0 on y = 0, u_z = 0 at the
bottom pole's middle-surface node.

Outputs
-------
tube / sphere: "r0" = mean over all radial fibres (node columns) of the
thickness average (1/h) int r dR along the fibre (5-point Gauss per element
on the Q2 interpolant), "r0_min", "r0_max" = extremes over the fibres.
strip: "s" = X of the node columns (2n + 1 values, vertex and mid nodes) on
Y = 0, "a", "b" = thickness-averaged x and z of those fibres.
invagination: "s" = polar angle from the bottom pole of the node columns on
the meridian y = 0 (2n + 1 values, uniform), "a" = thickness-averaged
distance from the axis, "b" = thickness-averaged z.  The fields are piecewise
quadratic in s (in X for the strip) between consecutive triplets of these
nodes: ``interp_fibre(res["s"], res["a"], s_query)`` evaluates them
anywhere (exact for the FE solution; thickness averages of Q2 fields are
integrated exactly).

Install: pip install scikit-fem   (tested with scikit-fem 12.0.2)
"""

import time
import sys

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from skfem import (MeshHex1, MeshHex2, ElementHex2, CellBasis, FacetBasis,
                   LinearForm)

__all__ = ["solve", "interp_fibre", "check_tangent", "SCENES"]

SCENES = ("tube", "sphere", "strip", "invagination")
H_SHELL = 0.1
H_STRIP = 0.02
INTORDER = 5      # 3x3x3 Gauss points per hexahedron

# --------------------------------------------------------------------------
# meshing
# --------------------------------------------------------------------------

# MeshHex1 local vertex order (see skfem.MeshHex1): offsets (di, dj, dk)
_HEX_OFFSETS = np.array([[0, 0, 0], [0, 0, 1], [0, 1, 0], [1, 0, 0],
                         [0, 1, 1], [1, 0, 1], [1, 1, 0], [1, 1, 1]])
_MIRROR = np.array([3, 5, 6, 0, 7, 1, 2, 4])   # flip the local i direction


def _grid_hexes(shape):
    """Connectivity (8, n1*n2*n3) of a structured grid of (n1+1)(n2+1)(n3+1)
    vertices numbered C-order by (i, j, k)."""
    n1, n2, n3 = shape
    I, J, K = np.meshgrid(np.arange(n1), np.arange(n2), np.arange(n3),
                          indexing="ij")
    I, J, K = I.ravel(), J.ravel(), K.ravel()
    t = [((I + di) * (n2 + 1) + (J + dj)) * (n3 + 1) + (K + dk)
         for di, dj, dk in _HEX_OFFSETS]
    return np.array(t)


def _build_mesh(patches):
    """Multi-patch curved Q2 hexahedral mesh.

    patches: list of (P, chi): P (n1+1, n2+1, n3+1, 3) structured vertex grid
    in the patch's parameter space, chi the exact map parameter -> reference
    position (vectorized on (3, N)).  Each patch is a straight hexahedral
    mesh in its parameter space; scikit-fem adds the Q2 nodes at parameter
    midpoints (MeshHex2.from_mesh) and all 27 nodes of every element are
    placed by chi.  Patches are glued at coinciding vertices."""
    info, xs, ts, off = [], [], [], 0
    for P, chi in patches:
        shp = np.array(P.shape[:3]) - 1
        p = P.reshape(-1, 3).T.copy()
        t = _grid_hexes(shp)
        x = chi(p)
        e1 = x[:, t[3]] - x[:, t[0]]
        e2 = x[:, t[2]] - x[:, t[0]]
        e3 = x[:, t[1]] - x[:, t[0]]
        neg = np.einsum("ij,ij->j", e1, np.cross(e2, e3, axis=0)) < 0
        t[:, neg] = t[_MIRROR][:, neg]
        m2 = MeshHex2.from_mesh(MeshHex1(p, t.astype(np.int32)))
        info.append((chi(m2.doflocs), m2.dofs.element_dofs))
        xs.append(x)
        ts.append(t + off)
        off += x.shape[1]
    x = np.hstack(xs)
    t = np.hstack(ts)
    key = np.round(x.T * 1e9).astype(np.int64)
    _, first, inv = np.unique(key, axis=0, return_index=True,
                              return_inverse=True)
    M2 = MeshHex2.from_mesh(MeshHex1(x[:, first].copy(),
                                     inv.ravel()[t].astype(np.int32)))
    dofl = M2.doflocs.copy()
    edofs = M2.dofs.element_dofs
    e0 = 0
    for Xp, ed in info:
        ne = ed.shape[1]
        dofl[:, edofs[:, e0:e0 + ne]] = Xp[:, ed]
        e0 += ne
    return MeshHex2(doflocs=dofl, t=M2.t)


def _cube_patch(face, urange, vrange, nu, nv, rho):
    """Vertices of a cube-face patch extruded radially: face is (axis, sign);
    u, v are the other two cube coordinates (in increasing axis order)."""
    ax, sgn = face
    others = [i for i in range(3) if i != ax]
    u = np.linspace(urange[0], urange[1], nu + 1)
    v = np.linspace(vrange[0], vrange[1], nv + 1)
    U, V, Rh = np.meshgrid(u, v, rho, indexing="ij")
    P = np.zeros(U.shape + (3,))
    P[..., ax] = sgn * Rh
    P[..., others[0]] = U * Rh
    P[..., others[1]] = V * Rh
    return P


def _cube_sphere_map(center):
    """Equiangular cube-sphere: cube-space point y = rho p (max |p_i| = 1)
    -> center + rho tan(pi p / 4) / |tan(pi p / 4)|."""
    c = np.asarray(center, float).reshape(3, 1)

    def chi(y):
        rho = np.max(np.abs(y), axis=0)
        w = np.tan(0.25 * np.pi * (y / rho))
        return c + rho * w / np.linalg.norm(w, axis=0)
    return chi


def _grid3(a, b, c):
    return np.stack(np.meshgrid(a, b, c, indexing="ij"), axis=-1)


# quarter-disk O-grid: corners of the central patch (disk radius 1)
_OG_A, _OG_C = 0.5, 0.42


def _ogrid_map(which, s1, center, sign):
    """Map of one O-grid patch of a quarter polar cap (phi in [0, pi/2],
    polar angle s in [0, s1] from the pole at center + (0, 0, sign)):
    parameters (xi, eta, R) in [0,1]^2 x [R0, R1].  The planar quarter disk
    is split into a central quadrilateral O-A-C-B and two outer patches
    A-(1,0)-D-C and C-D-(0,1)-B (D at 45 degrees on the arc), each mapped
    by transfinite (Coons) interpolation of straight edges and the arc; the
    disk is mapped to the sphere by the azimuthal equidistant map
    (disk radius r -> s = s1 r)."""
    a, cc = _OG_A, _OG_C
    O, A, B, C = (np.array(v, float) for v in
                  ([0, 0], [a, 0], [0, a], [cc, cc]))
    c0 = np.asarray(center, float).reshape(3, 1)

    def lin(P0, P1, s):
        return P0[:, None] + (P1 - P0)[:, None] * s[None]

    def arc(th0, th1, s):
        th = th0 + (th1 - th0) * s
        return np.array([np.cos(th), np.sin(th)])

    def coons(bot, top, left, right, xi, eta):
        # bot(xi) at eta=0, top(xi) at eta=1, left(eta) at xi=0, right(eta)
        z = np.zeros_like(xi)
        o = np.ones_like(xi)
        return ((1 - eta) * bot(xi) + eta * top(xi) + (1 - xi) * left(eta)
                + xi * right(eta)
                - ((1 - xi) * (1 - eta) * bot(z) + xi * (1 - eta) * bot(o)
                   + (1 - xi) * eta * top(z) + xi * eta * top(o)))

    def disk(xi, eta):
        if which == 0:      # central: O (0,0), A (1,0), B (0,1), C (1,1)
            return coons(lambda s: lin(O, A, s), lambda s: lin(B, C, s),
                         lambda s: lin(O, B, s), lambda s: lin(A, C, s),
                         xi, eta)
        if which == 1:      # A -> (1,0) along xi, A -> C along eta
            E1 = np.array([1.0, 0.0])
            return coons(lambda s: lin(A, E1, s),
                         lambda s: lin(C, np.array([np.sqrt(.5)] * 2), s),
                         lambda s: lin(A, C, s),
                         lambda s: arc(0.0, np.pi / 4, s), xi, eta)
        # which == 2: B -> (0,1) along xi, B -> C along eta
        E2 = np.array([0.0, 1.0])
        return coons(lambda s: lin(B, E2, s),
                     lambda s: lin(C, np.array([np.sqrt(.5)] * 2), s),
                     lambda s: lin(B, C, s),
                     lambda s: arc(np.pi / 2, np.pi / 4, s), xi, eta)

    def chi(q):
        d = disk(q[0], q[1])
        r = np.hypot(d[0], d[1])
        s = s1 * r
        sinc = np.where(r > 1e-14, np.sin(s) / np.where(r > 0, r, 1), s1)
        e = np.array([sinc * d[0], sinc * d[1], -sign * np.cos(s)])
        return c0 + q[2] * e
    return chi


def _band_map(center):
    c0 = np.asarray(center, float).reshape(3, 1)

    def chi(q):       # q = (s, phi, R), s from the bottom pole
        s, ph, R = q
        return c0 + R * np.array([np.sin(s) * np.cos(ph),
                                  np.sin(s) * np.sin(ph), -np.cos(s)])
    return chi


# invagination: polar caps s < S_CAP (from either pole) are O-grids, the band
# between them a structured (s, phi) grid
S_CAP = 0.2 * np.pi


def _invagination_sizes(n):
    """(n_phi, n_cap, n_band): elements around the quarter circle, along the
    meridian in each cap, and along the meridian in the band
    (n = 2 n_cap + n_band)."""
    n_phi = 2 * max(2, int(round(n / 16)))
    n_cap = n_phi
    return n_phi, n_cap, n - 2 * n_cap


def _mesh_scene(scene, n, m):
    h = H_SHELL
    if scene == "tube":
        th = np.linspace(0, np.pi / 2, n + 1)
        R = np.linspace(1 - h / 2, 1 + h / 2, m + 1)
        z = np.array([0.0, h / m])

        def chi(q):
            return np.array([q[1] * np.cos(q[0]), q[1] * np.sin(q[0]), q[2]])
        return _build_mesh([(_grid3(th, R, z), chi)])
    if scene == "strip":
        X = np.linspace(0, np.pi / 2, n + 1)
        Y = np.array([0.0, H_STRIP])
        Z = np.linspace(-H_STRIP / 2, H_STRIP / 2, m + 1)
        return _build_mesh([(_grid3(X, Y, Z), lambda q: q.copy())])
    rho = np.linspace(1 - h / 2, 1 + h / 2, m + 1)
    if scene == "sphere":
        assert n % 2 == 0, "sphere: n must be even"
        k = n // 2
        chi = _cube_sphere_map((0, 0, 0))
        return _build_mesh([
            (_cube_patch((0, 1), (0, 1), (0, 1), k, k, rho), chi),
            (_cube_patch((1, 1), (0, 1), (0, 1), k, k, rho), chi),
            (_cube_patch((2, 1), (0, 1), (0, 1), k, k, rho), chi)])
    if scene == "invagination":
        c = (0.0, 0.0, 1.0)
        n_phi, n_cap, n_band = _invagination_sizes(n)
        assert n_band >= 4, "invagination: n too small"
        k = n_phi // 2
        patches = []
        for sign in (1, -1):            # bottom cap (pole at c - e_z), top
            xi = np.linspace(0, 1, k + 1)
            xr = np.linspace(0, 1, n_cap - k + 1)
            patches.append((_grid3(xi, xi, rho),
                            _ogrid_map(0, S_CAP, c, sign)))
            for w in (1, 2):
                patches.append((_grid3(xr, xi, rho),
                                _ogrid_map(w, S_CAP, c, sign)))
        s = np.linspace(S_CAP, np.pi - S_CAP, n_band + 1)
        ph = np.linspace(0, np.pi / 2, n_phi + 1)
        patches.append((_grid3(s, ph, rho), _band_map(c)))
        return _build_mesh(patches)
    raise ValueError(f"unknown scene {scene!r}")


def _default_layers(scene, n):
    return {"tube": max(1, n // 8), "sphere": max(1, n // 16),
            "strip": 1, "invagination": 2 + n // 64}[scene]


# --------------------------------------------------------------------------
# growth fields and scene data (X: (3, ...) reference positions)
# --------------------------------------------------------------------------

def _outer(a, b):
    return a[:, None] * b[None, :]


def _growth(scene, X):
    """Growth tensor G, shape (3, 3, ...)."""
    I = np.eye(3).reshape((3, 3) + (1,) * (X.ndim - 1))
    if scene == "tube":
        g = np.diag([1.2, 1.2, 1.0]).reshape(I.shape)
        return g + 0 * X[0]
    if scene == "strip":
        G = I + 0 * X[0]
        G = G.copy()
        G[0, 0] = 1.2 + 2.0 * X[2]
        return G
    if scene == "sphere":
        R = np.linalg.norm(X, axis=0)
        eR = X / R
        gam = 1.05 + 0.9 * (R - 1)
        return gam * I + (1 - gam) * _outer(eR, eR)
    if scene == "invagination":
        Xc = X - np.array([0, 0, 1.0]).reshape((3,) + (1,) * (X.ndim - 1))
        R = np.linalg.norm(Xc, axis=0)
        Z = R - 1
        eR = Xc / R
        s = np.arccos(np.clip(-eR[2], -1, 1))
        phi = np.arctan2(X[1], X[0])
        es = np.array([np.cos(s) * np.cos(phi), np.cos(s) * np.sin(phi),
                       np.sin(s)])
        ep = np.array([-np.sin(phi), np.cos(phi), 0 * phi])
        b = np.exp(-((s - 0.45 * np.pi) / (0.08 * np.pi)) ** 2)
        g1 = 1 - 0.4 * b
        g2 = 1 + 0.2 * b - 1.0 * Z * b
        return I + (g1 - 1) * _outer(ep, ep) + (g2 - 1) * _outer(es, es)
    raise ValueError(scene)


_D = {"tube": 4.0, "sphere": 4.0, "strip": 2.0, "invagination": 4.0}


# --------------------------------------------------------------------------
# the hyperelastic problem
# --------------------------------------------------------------------------

class _Solid:
    """Vectorized residual / tangent / energy on a Q2 hexahedral mesh.
    Global dof of component i at node a: 3 a + i."""

    def __init__(self, mesh, G, C, D, chunk=1500):
        self.mesh, self.C, self.D = mesh, C, D
        basis = CellBasis(mesh, ElementHex2(), intorder=INTORDER)
        self.basis = basis
        nb = len(basis.basis)
        dN = np.array([basis.basis[a][0].grad for a in range(nb)])  # (a,K,e,q)
        self.dN = np.ascontiguousarray(dN.transpose(2, 3, 0, 1))     # (e,q,a,K)
        self.dx = np.asarray(basis.dx)                               # (e,q)
        self.E, self.Q = self.dx.shape
        self.nb = nb
        self.nodes = basis.element_dofs.T                             # (e,a)
        self.N = mesh.doflocs.shape[1]
        self.ndof = 3 * self.N
        self.gdof = (3 * self.nodes[:, :, None] + np.arange(3)).reshape(self.E, -1)
        Xq = basis.mapping.F(basis.X)                                 # (3,e,q)
        self.Xq = Xq
        self.Gfull = np.ascontiguousarray(np.moveaxis(G(Xq), (0, 1), (2, 3)))
        self.chunk = chunk
        self.fext = np.zeros(self.ndof)
        self._pattern()
        self.set_t(1.0)

    # sparse pattern: CSR data = bincount(inv, element entries)
    def _pattern(self):
        nd = self.gdof.shape[1]
        rows = np.repeat(self.gdof, nd, axis=1).ravel().astype(np.int64)
        cols = np.tile(self.gdof, (1, nd)).ravel().astype(np.int64)
        keys = rows * self.ndof + cols
        ukeys, inv = np.unique(keys, return_inverse=True)
        self.inv = inv.astype(np.int64)
        r = (ukeys // self.ndof).astype(np.int32)
        self.indices = (ukeys % self.ndof).astype(np.int32)
        self.indptr = np.zeros(self.ndof + 1, dtype=np.int64)
        np.cumsum(np.bincount(r, minlength=self.ndof), out=self.indptr[1:])
        self.nnz = len(ukeys)
        self._rows = r

    def set_bc(self, fixed):
        self.fixed = np.unique(np.asarray(fixed, dtype=np.int64))
        mask = np.zeros(self.ndof, bool)
        mask[self.fixed] = True
        self.free_mask = ~mask
        rfix = mask[self._rows]
        cfix = mask[self.indices]
        self._zero = rfix | cfix
        self._diag1 = rfix & (self._rows == self.indices)

    def set_t(self, t):
        self.t = t
        I = np.eye(3)
        Gt = I + t * (self.Gfull - I)
        self.Gi = np.linalg.inv(Gt)
        self.g = np.linalg.det(Gt)
        self.B = self.dN @ self.Gi                                    # (e,q,a,M)
        self.c = self.g * self.dx

    def _kin(self, U, sl):
        Ue = U[self.nodes[sl]].reshape(-1, self.nb, 3)               # (e,a,i)
        Fe = self.Gi[sl] + np.swapaxes(Ue, 1, 2)[:, None] @ self.B[sl]
        J = np.linalg.det(Fe)
        return Fe, J

    def _slices(self):
        for s in range(0, self.E, self.chunk):
            yield slice(s, min(s + self.chunk, self.E))

    def energy_residual(self, U, want_residual=True):
        """(energy, residual); energy = inf if some J <= 0."""
        U3 = U.reshape(-1, 3)
        C, D = self.C, self.D
        Ein = 0.0
        Wabs = 0.0
        r = np.zeros((self.E, self.nb, 3)) if want_residual else None
        for sl in self._slices():
            Fe, J = self._kin(U3, sl)
            if np.any(J <= 0) or not np.all(np.isfinite(J)):
                return np.inf, None
            I1 = np.einsum("eqij,eqij->eq", Fe, Fe)
            W = 0.5 * C * (I1 - 3 - 2 * np.log(J)) + 0.5 * D * (J - 1) ** 2
            Ein += np.sum(W * self.c[sl])
            Wabs += np.sum((0.5 * C * (I1 + 3 + 2 * np.abs(np.log(J)))
                            + 0.5 * D * (J * J + 1)) * self.c[sl])
            if want_residual:
                Fit = np.linalg.inv(Fe).swapaxes(-1, -2)
                Pe = C * Fe + ((D * (J - 1) * J - C))[..., None, None] * Fit
                cP = Pe * self.c[sl][..., None, None]
                # r[e,a,i] = sum_q sum_M B[e,q,a,M] cP[e,q,i,M]
                Bm = self.B[sl].transpose(0, 2, 1, 3).reshape(
                    Fe.shape[0], self.nb, -1)
                Pm = cP.transpose(0, 1, 3, 2).reshape(Fe.shape[0], -1, 3)
                r[sl] = Bm @ Pm
        Etot = Ein - self.t * np.dot(self.fext, U)
        self.Escale = Wabs + abs(self.t * np.dot(self.fext, U))
        if not want_residual:
            return Etot, None
        R = np.bincount(self.gdof.ravel(), weights=r.ravel(),
                        minlength=self.ndof) - self.t * self.fext
        return Etot, R

    def tangent(self, U):
        U3 = U.reshape(-1, 3)
        C, D = self.C, self.D
        nb, nd = self.nb, 3 * self.nb
        data = np.zeros(self.nnz)
        I3 = np.eye(3)
        for sl in self._slices():
            Fe, J = self._kin(U3, sl)
            ne = Fe.shape[0]
            Fit = np.linalg.inv(Fe).swapaxes(-1, -2)
            c = self.c[sl]
            alpha = D * (2 * J - 1) * J * c
            beta = (C - D * (J - 1) * J) * c
            B = self.B[sl]
            V = B @ Fit.swapaxes(-1, -2)                          # (e,q,a,i)
            Vm = V.transpose(0, 2, 3, 1).reshape(ne, nd, -1)      # (e,(a,i),q)
            VmT = Vm.transpose(0, 2, 1)
            K = (Vm * alpha[:, None, :]) @ VmT
            M3 = (Vm * beta[:, None, :]) @ VmT
            K += M3.reshape(ne, nb, 3, nb, 3).transpose(0, 1, 4, 3, 2).reshape(ne, nd, nd)
            Bm = B.transpose(0, 2, 1, 3).reshape(ne, nb, -1)      # (e,a,(q,M))
            cw = np.repeat(C * c, 3, axis=1)
            K1 = (Bm * cw[:, None, :]) @ Bm.transpose(0, 2, 1)
            K = K.reshape(ne, nb, 3, nb, 3) + K1[:, :, None, :, None] * I3[None, None, :, None, :]
            lo = sl.start * nd * nd
            hi = sl.stop * nd * nd
            data += np.bincount(self.inv[lo:hi], weights=K.ravel(),
                                minlength=self.nnz)
        return data

    def system(self, data):
        d = data.copy()
        d[self._zero] = 0.0
        d[self._diag1] = 1.0
        return sp.csr_matrix((d, self.indices, self.indptr),
                             shape=(self.ndof, self.ndof))


def _factor(K):
    """Factorize the (symmetric, possibly indefinite) sparse matrix K; returns
    a solve function.  SuperLU with the MMD(A^T + A) ordering: the fastest of
    the scipy / cholespy options measured on these 3D quadratic-element
    matrices (CHOLMOD also needs K positive definite, which the tangent is
    not always during continuation)."""
    return spla.splu(K.tocsc(), permc_spec="MMD_AT_PLUS_A").solve


class _LinearSolver:
    """Solves K x = b for the successive exact tangents K of a continuation
    run.  The last sparse factorization is kept and re-used as the
    preconditioner of GMRES for the following tangents; a new factorization
    is made whenever GMRES does not reach the requested relative residual
    within ``max_krylov`` iterations.  The Newton loop asks for a relative
    accuracy 0.1 |R| / ref (clipped to [1e-12, 1e-3]): the linear error
    stays below the quadratic Newton error, so the convergence is that of
    the exact Newton method with the exact tangent."""

    def __init__(self, max_krylov=25):
        self.max_krylov = max_krylov
        self.fsolve = None
        self.nfact = 0
        self.nkrylov = 0

    def __call__(self, K, b, rtol=1e-12):
        bn = np.linalg.norm(b)
        if bn == 0:
            return np.zeros_like(b)
        if self.fsolve is not None:
            its = [0]

            def count(_):
                its[0] += 1
            M = spla.LinearOperator(K.shape, matvec=self.fsolve)
            x, _ = spla.gmres(K, b, rtol=rtol, atol=0.0, restart=self.max_krylov,
                              maxiter=1, M=M, callback=count,
                              callback_type="pr_norm")
            self.nkrylov += its[0]
            if np.linalg.norm(K @ x - b) <= 2 * rtol * bn:
                return x
        self.fsolve = _factor(K)
        self.nfact += 1
        x = self.fsolve(b)
        return x


# --------------------------------------------------------------------------
# continuation + Newton
# --------------------------------------------------------------------------

def _newton(solid, U, tol, ref, lin, maxit=25, verbose=False):
    """Newton with line search.  Returns (U, iterations, converged)."""
    fm = solid.free_mask
    E0, R = solid.energy_residual(U)
    if R is None:
        return U, 0, False
    its = 0
    for its in range(1, maxit + 1):
        rn = np.linalg.norm(R[fm])
        if rn <= tol * ref and its > 1:
            return U, its - 1, True
        rhs = -R
        rhs[~fm] = 0.0
        eta = min(1e-3, max(1e-12, 0.1 * rn / ref))
        dU = lin(solid.system(solid.tangent(U)), rhs, eta)
        # backtracking line search on the energy (Armijo, quadratic
        # interpolation); where the Newton direction is not a descent
        # direction (indefinite tangent) on the residual norm instead
        g0 = float(R @ dU)
        descent = g0 < 0
        a = 1.0
        ok = False
        for _ in range(20):
            Un = U + a * dU
            En, Rn = solid.energy_residual(Un)
            if Rn is not None:
                rnn = np.linalg.norm(Rn[fm])
                if descent:
                    if En <= E0 + 1e-4 * a * g0 + 1e-13 * solid.Escale or \
                            (a == 1.0 and rnn < 0.5 * rn):
                        ok = True
                        break
                    den = 2 * (En - E0 - g0 * a)
                    a_new = -g0 * a * a / den if den > 0 else 0.5 * a
                    a = min(0.5 * a, max(0.1 * a, a_new))
                    continue
                elif rnn < rn:
                    ok = True
                    break
            a *= 0.5
        if not ok:
            return U, its, False
        U, E0, R = Un, En, Rn
        if verbose:
            print(f"      it {its}: |R|/ref = {rnn / ref:.3e}  step {a:g}")
        if rnn <= tol * ref:
            return U, its, True
    return U, its, False


def _continuation(solid, dt0, dt_max, lin, verbose=False, tol_final=1e-10,
                  tol_mid=1e-6):
    """Continuation in t.  Predictor: the linear (tangent) response of the
    stress-free body for the first step, the secant extrapolation of the
    last two converged states afterwards."""
    fm = solid.free_mask
    U = np.zeros(solid.ndof)
    solid.set_t(1.0)
    _, R1 = solid.energy_residual(U)
    ref = np.linalg.norm(R1[fm])
    t, dt = 0.0, dt0
    U_prev, t_prev = None, None
    total, steps, cuts = 0, 0, 0
    while t < 1.0 - 1e-14:
        tn = min(1.0, t + dt)
        if 1.0 - tn < 0.1 * dt:
            tn = 1.0
        U0 = U
        if U_prev is None:
            solid.set_t(0.0)
            K0 = solid.system(solid.tangent(U))
            solid.set_t(tn)
            _, R = solid.energy_residual(U)
            R[~fm] = 0.0
            dU = lin(K0, -R)
        else:
            solid.set_t(tn)
            dU = (tn - t) / (t - t_prev) * (U - U_prev)
        for _ in range(6):
            E, _ = solid.energy_residual(U + dU, want_residual=False)
            if np.isfinite(E):
                U0 = U + dU
                break
            dU *= 0.5
        tol = tol_final if tn == 1.0 else tol_mid
        Un, its, ok = _newton(solid, U0, tol, ref, lin, verbose=verbose)
        total += its
        if verbose:
            print(f"   t = {tn:.4f} (dt {tn - t:.4f}): {its} its, "
                  f"{'ok' if ok else 'FAILED'}")
        if not ok:
            cuts += 1
            dt = 0.5 * (tn - t)
            if dt < 1e-5:
                raise RuntimeError("continuation failed: step too small")
            continue
        U_prev, t_prev = U, t
        U, t = Un, tn
        steps += 1
        if its <= 4:
            dt = min(dt_max, 1.5 * (t - t_prev))
        elif its >= 10:
            dt = 0.7 * (t - t_prev)
    return U, total, steps, cuts


# --------------------------------------------------------------------------
# fibres (node columns) and outputs
# --------------------------------------------------------------------------

def _fibres(key, coord):
    """Group nodes into fibres: key (k, N) identifies the fibre, coord (N,)
    the position along it.  Returns an index array (nfib, npts) sorted by
    coord, and the unique keys."""
    kk = np.round(key.T * 1e9).astype(np.int64)
    uk, inv = np.unique(kk, axis=0, return_inverse=True)
    inv = inv.ravel()
    order = np.lexsort((coord, inv))
    npts = len(coord) // len(uk)
    idx = order.reshape(len(uk), npts)
    return idx, uk / 1e9


def _thickness_average(vals):
    """vals (nfib, 2m+1[, ...]) at equally spaced nodes of a piecewise
    quadratic interpolant on [coord0, coord_end]: exact Simpson average."""
    w = np.zeros(vals.shape[1])
    w[0:-1:2] += 1
    w[1::2] += 4
    w[2::2] += 1
    w /= w.sum()
    return np.tensordot(vals, w, axes=([1], [0])) if vals.ndim == 2 else \
        np.einsum("fp...,p->f...", vals, w)


def _fibre_norm_average(xf):
    """xf: (nfib, 2m+1, d) nodal positions along fibres (quadratic per
    element, uniform parameter); thickness average of |x| by 5-point Gauss."""
    nf, npts, d = xf.shape
    m = (npts - 1) // 2
    gp, gw = np.polynomial.legendre.leggauss(5)
    xi = 0.5 * (gp + 1)
    L = np.array([2 * (xi - 0.5) * (xi - 1), -4 * xi * (xi - 1),
                  2 * xi * (xi - 0.5)])                 # (3, 5)
    tot = np.zeros(nf)
    for e in range(m):                                  # loop over layers only
        xe = xf[:, 2 * e:2 * e + 3, :]                  # (nf,3,d)
        xg = np.einsum("fnd,ng->fgd", xe, L)
        tot += np.linalg.norm(xg, axis=2) @ (0.5 * gw)
    return tot / m


def interp_fibre(s_nodes, vals, s_query):
    """Evaluate the piecewise quadratic (between node triplets 2k, 2k+1,
    2k+2) through (s_nodes, vals) at s_query."""
    s_nodes = np.asarray(s_nodes)
    vals = np.asarray(vals)
    sq = np.atleast_1d(np.asarray(s_query, float))
    ne = (len(s_nodes) - 1) // 2
    e = np.clip(np.searchsorted(s_nodes[::2], sq, side="right") - 1, 0, ne - 1)
    s0, s1, s2 = s_nodes[2 * e], s_nodes[2 * e + 1], s_nodes[2 * e + 2]
    v0, v1, v2 = vals[2 * e], vals[2 * e + 1], vals[2 * e + 2]
    l0 = (sq - s1) * (sq - s2) / ((s0 - s1) * (s0 - s2))
    l1 = (sq - s0) * (sq - s2) / ((s1 - s0) * (s1 - s2))
    l2 = (sq - s0) * (sq - s1) / ((s2 - s0) * (s2 - s1))
    return l0 * v0 + l1 * v1 + l2 * v2


# --------------------------------------------------------------------------
# scene setup
# --------------------------------------------------------------------------

def _traction_load(mesh, facets, q):
    """Dead nominal traction q e_R(X) (e_R from the origin, cylindrical for
    'cyl') on the given facets: load vector (3 N,)."""
    fb = FacetBasis(mesh, ElementHex2(), facets=facets, intorder=INTORDER)
    kind, mag = q
    f = np.zeros((mesh.doflocs.shape[1], 3))
    for i in range(3):
        @LinearForm
        def lf(v, w, i=i):
            x = w.x
            if kind == "cyl":
                if i == 2:
                    return 0 * v
                return v * mag * x[i] / np.sqrt(x[0] ** 2 + x[1] ** 2)
            return v * mag * x[i] / np.sqrt(x[0] ** 2 + x[1] ** 2 + x[2] ** 2)
        f[:, i] = lf.assemble(fb)
    return f.ravel()


def _facets_where(mesh, pred):
    """Facets whose four vertices all satisfy pred (on (3, ...) positions)."""
    ok = np.all(pred(mesh.doflocs[:, mesh.facets]), axis=0)
    return np.nonzero(ok)[0].astype(np.int32)


_CENTER = {"tube": None, "sphere": (0, 0, 0), "strip": None,
           "invagination": (0, 0, 1.0)}


def _setup(scene, n, m):
    mesh = _mesh_scene(scene, n, m)
    solid = _Solid(mesh, lambda X: _growth(scene, X), 1.0, _D[scene])
    x = mesh.doflocs
    tol = 1e-10
    fixed = []
    h = H_SHELL
    if scene == "tube":
        fixed += list(3 * np.nonzero(np.abs(x[0]) < tol)[0])
        fixed += list(3 * np.nonzero(np.abs(x[1]) < tol)[0] + 1)
        fixed += list(3 * np.arange(solid.N) + 2)
        fac = _facets_where(
            mesh, lambda q: np.abs(np.hypot(q[0], q[1]) - (1 + h / 2)) < 1e-9)
        solid.fext = _traction_load(mesh, fac, ("cyl", 0.03))
    elif scene == "sphere":
        for i in range(3):
            fixed += list(3 * np.nonzero(np.abs(x[i]) < tol)[0] + i)
        fac = _facets_where(
            mesh, lambda q: np.abs(np.linalg.norm(q, axis=0) - (1 - h / 2)) < 1e-9)
        solid.fext = _traction_load(mesh, fac, ("sph", 0.03))
    elif scene == "strip":
        fixed += list(3 * np.arange(solid.N) + 1)
        fixed += list(3 * np.nonzero(np.abs(x[0]) < tol)[0])
        fixed += list(3 * np.nonzero((np.abs(x[0]) < tol) & (np.abs(x[2]) < tol))[0] + 2)
    elif scene == "invagination":
        fixed += list(3 * np.nonzero(np.abs(x[0]) < tol)[0])
        fixed += list(3 * np.nonzero(np.abs(x[1]) < tol)[0] + 1)
        pole = np.nonzero(np.linalg.norm(x, axis=0) < tol)[0]
        assert len(pole) == 1
        fixed += [3 * pole[0] + 2]
    solid.set_bc(fixed)
    return solid, mesh


def _outputs(scene, solid, mesh, U):
    X = mesh.doflocs
    x = X + U.reshape(-1, 3).T      # current node positions
    out = {}
    if scene == "tube":
        idx, _ = _fibres(np.array([np.arctan2(X[1], X[0]), X[2]]),
                         np.hypot(X[0], X[1]))
        r0f = _fibre_norm_average(x[:2].T[idx])
    elif scene == "sphere":
        R = np.linalg.norm(X, axis=0)
        idx, _ = _fibres(X / R, R)
        r0f = _fibre_norm_average(x.T[idx])
    if scene in ("tube", "sphere"):
        out["r0"] = float(np.mean(r0f))
        out["r0_min"] = float(np.min(r0f))
        out["r0_max"] = float(np.max(r0f))
        return out
    sel = np.nonzero(np.abs(X[1]) < 1e-12)[0]       # fibres on the plane y = 0
    if scene == "strip":
        idx, _ = _fibres(X[[0]][:, sel], X[2, sel])
        s = X[0, sel[idx[:, 0]]]
    else:
        d = X[:, sel] - np.array([[0], [0], [1.0]])
        R = np.linalg.norm(d, axis=0)
        idx, _ = _fibres(d / R, R)
        s = np.arctan2(d[0, idx[:, 0]], -d[2, idx[:, 0]])
    idx = sel[idx]
    o = np.argsort(s)
    out["s"] = s[o]
    out["a"] = _thickness_average(x[0][idx])[o]
    out["b"] = _thickness_average(x[2][idx])[o]
    return out


_STEPS = {"tube": (0.5, 1.0), "sphere": (0.5, 1.0), "strip": (0.1, 0.25),
          "invagination": (0.1, 0.25)}


def solve(scene: str, n: int, verbose: bool = False, m: int = None) -> dict:
    """Solve one scene on the mesh of resolution n.

    n = number of elements along: the quarter arc (tube), a quarter great
    circle (sphere; n even), the strip length (strip), the meridian from
    pole to pole (invagination; n >= 16).  Elements through the thickness m:
    see the module docstring.  One element layer across the tube height /
    strip width (plane strain).
    """
    t0 = time.perf_counter()
    if m is None:
        m = _default_layers(scene, n)
    solid, mesh = _setup(scene, n, m)
    t_setup = time.perf_counter() - t0
    dt0, dtmax = _STEPS[scene]
    lin = _LinearSolver()
    U, its, steps, cuts = _continuation(solid, dt0, dtmax, lin,
                                        verbose=verbose)
    out = _outputs(scene, solid, mesh, U)
    wall = time.perf_counter() - t0
    res = {"scene": scene, "n": n, "m": m,
           "dofs": int(solid.free_mask.sum()), "wall_s": wall,
           "setup_s": t_setup, "iterations": int(its), "steps": steps,
           "cuts": cuts, "factorizations": lin.nfact,
           "krylov_iterations": lin.nkrylov,
           "element": "Q2 hexahedron, 27-node triquadratic isoparametric "
                      "(skfem ElementHex2 on MeshHex2)",
           "n_elements": int(mesh.nelements),
           "linear_solver": "scipy SuperLU (MMD_AT_PLUS_A), reused as the "
                            "GMRES preconditioner"}
    res.update(out)
    if verbose:
        print(f"  {scene} n={n} m={m}: {res['dofs']} dofs, "
              f"{res['n_elements']} el, {its} its in {steps} steps, "
              f"{lin.nfact} factorizations, {lin.nkrylov} GMRES its, "
              f"{wall:.2f} s (setup {t_setup:.2f} s)")
    return res


# --------------------------------------------------------------------------
# development check of the tangent
# --------------------------------------------------------------------------

def check_tangent(scene="invagination", n=None, m=1, eps=1e-6, seed=0):
    """Finite-difference check of the consistent tangent at a random
    state; returns the relative error of K v vs central differences."""
    if n is None:
        n = 16 if scene == "invagination" else 4
    solid, mesh = _setup(scene, n, m)
    rng = np.random.default_rng(seed)
    solid.set_t(0.7)
    amp = 0.03 * (H_STRIP if scene == "strip" else H_SHELL) / m
    U = amp * rng.standard_normal(solid.ndof)
    v = rng.standard_normal(solid.ndof)
    K = sp.csr_matrix((solid.tangent(U), solid.indices, solid.indptr),
                      shape=(solid.ndof, solid.ndof))
    _, Rp = solid.energy_residual(U + eps * v)
    _, Rm = solid.energy_residual(U - eps * v)
    fd = (Rp - Rm) / (2 * eps)
    Kv = K @ v
    err_t = np.linalg.norm(Kv - fd) / np.linalg.norm(fd)
    Ep, _ = solid.energy_residual(U + eps * v, want_residual=False)
    Em, _ = solid.energy_residual(U - eps * v, want_residual=False)
    _, R = solid.energy_residual(U)
    err_r = abs((Ep - Em) / (2 * eps) - R @ v) / abs(R @ v)
    sym = abs(v @ (K @ U) - U @ (K @ v)) / abs(v @ (K @ U))
    return err_t, err_r, sym


# --------------------------------------------------------------------------
# convergence study
# --------------------------------------------------------------------------

def _exact_r0(scene):
    from shellritz.reference import thick_shell_r0
    if scene == "tube":
        return thick_shell_r0("tube", 0.1, 1.0, 4.0, 1.2, 1.2, q_outer=0.03)
    return thick_shell_r0("sphere", 0.1, 1.0, 4.0, 1.0, 1.05, 0.9,
                          q_inner=0.03)


def _study(scene, ns, verbose=False):
    print(f"\n== {scene} ==")
    rows = []
    if scene in ("tube", "sphere"):
        ex = _exact_r0(scene)
        print(f"exact r0 = {ex:.12f}")
        print(f"{'n':>5} {'m':>3} {'elems':>7} {'dofs':>8} {'its':>4} "
              f"{'wall_s':>8} {'r0':>16} {'rel.err':>10} {'spread':>9}")
        for n in ns:
            r = solve(scene, n, verbose=verbose)
            err = abs(r["r0"] - ex) / ex
            print(f"{n:5d} {r['m']:3d} {r['n_elements']:7d} {r['dofs']:8d} "
                  f"{r['iterations']:4d} {r['wall_s']:8.2f} {r['r0']:16.12f} "
                  f"{err:10.2e} {r['r0_max'] - r['r0_min']:9.1e}", flush=True)
            rows.append((r, err))
    elif scene == "strip":
        print(f"{'n':>5} {'m':>3} {'elems':>7} {'dofs':>8} {'its':>4} "
              f"{'wall_s':>8} {'max|x-x*|/0.6':>14}")
        for n in ns:
            r = solve(scene, n, verbose=verbose)
            s = r["s"]
            err = np.max(np.hypot(r["a"] - 0.6 * np.sin(2 * s),
                                  r["b"] - 0.6 * (np.cos(2 * s) - 1))) / 0.6
            print(f"{n:5d} {r['m']:3d} {r['n_elements']:7d} {r['dofs']:8d} "
                  f"{r['iterations']:4d} {r['wall_s']:8.2f} {err:14.2e}",
                  flush=True)
            rows.append((r, err))
    else:
        sq = np.linspace(0, np.pi, 721)
        res = []
        print(f"{'n':>5} {'m':>3} {'elems':>7} {'dofs':>8} {'its':>4} "
              f"{'wall_s':>8} {'a(pi/2)':>10} {'b(pi)':>10} "
              f"{'chg_prev':>9} ")
        prev = None
        for n in ns:
            r = solve(scene, n, verbose=verbose)
            a = interp_fibre(r["s"], r["a"], sq)
            b = interp_fibre(r["s"], r["b"], sq)
            chg = np.nan if prev is None else np.max(np.hypot(a - prev[0], b - prev[1]))
            prev = (a, b)
            res.append((r, a, b))
            print(f"{n:5d} {r['m']:3d} {r['n_elements']:7d} {r['dofs']:8d} "
                  f"{r['iterations']:4d} {r['wall_s']:8.2f} "
                  f"{interp_fibre(r['s'], r['a'], np.pi / 2)[0]:10.6f} "
                  f"{r['b'][-1]:10.6f} {chg:9.2e}", flush=True)
        af, bf = res[-1][1], res[-1][2]
        print("max distance to the finest mesh (s in [0, pi]):")
        for r, a, b in res[:-1]:
            print(f"   n = {r['n']:4d}: {np.max(np.hypot(a - af, b - bf)):.2e}")
        i = np.argmin(af[(sq > 0.3) & (sq < 2.5)])
        print(f"finest: min a = {af[(sq > 0.3) & (sq < 2.5)][i]:.6f}, "
              f"top pole z = {bf[-1]:.6f}")
    return rows


_STUDY = {"tube": [8, 16, 32, 64], "sphere": [4, 8, 16, 32],
          "strip": [8, 16, 32, 64, 128], "invagination": [16, 32, 48]}

if __name__ == "__main__":
    args = sys.argv[1:]
    verbose = "-v" in args
    args = [a for a in args if a != "-v"]
    if args and args[0] == "--check":
        for sc in SCENES:
            print(sc, "tangent / residual FD rel. errors, asymmetry:",
                  check_tangent(sc))
        sys.exit(0)
    scenes = args or list(SCENES)
    for sc in scenes:
        _study(sc, _STUDY[sc], verbose=verbose)
