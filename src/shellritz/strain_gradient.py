"""The strain-gradient term that keeps the shell energy bounded below at
wavelengths below the thickness (docs/validity.md).

Why it is needed.  The h^3 bracket of MODEL.md section 4, condensed over y2,
gives the surface gradient of the thickness stretch (the normal row of rho)
a stiffness equal to the in-plane stress: under compression the energy of
an in-plane wave of wavenumber k is

    h k^2 |u|^2 [ E' + (c^2 / 12) Sigma (k h)^2 ],     c = nu / (1 - nu),

negative for (k h)^2 > 12 E' / (c^2 |Sigma|) (k h = 36 at 2 % compression).
The 3D slab has no such instability: the truncated expansion does.  No
pointwise change of L can remove it and stay O(h^5) (the k^4 coefficient is
the r_ab block of the point Hessian), so the cure is the next term of the
expansion for in-plane waves, added to the energy per unit reference area:

    R = C_R |grad grad eps|^2,    C_R = (h^5 / 1440) c^2 E'

with eps the elastic membrane strain of the middle surface, (r_a.r_b - G0 R_a.G0 R_b)/2
(measured against the grown metric; components in a locally
orthonormal reference frame, differentiated twice along the surface).  For an
in-plane wave at small strain it is exactly the O(h^5 k^6) term of the 3D
slab (checked in bench/validity.py); for smooth fields it is O(h^5), the
order the model neglects, and it vanishes for uniform strain, rigid
motions and stress-free grown states.  With it the in-plane symbol stays positive for compressive stresses
up to |Sigma| = 0.89 E' / c.

This module holds the coefficient and the line-engine (C1 Hermite) version:
at the Gauss points the second derivatives along the meridian of the
meridional and hoop strains, at interior nodes the jump of the first
derivative of the meridional strain (the Hermite field is only C1), an
interior-penalty form of the same seminorm.  The triangle version is in
kernels/strain_gradient_dkt.py.
"""

import numpy as np

from .discretize import line
from .discretize.dkt import THIN_HEIGHT, rule
from .kernels.strain_gradient_dkt import add_dkt_edge_strain_gradient, add_dkt_strain_gradient


def coefficient(law, h):
    """C_R = (h^5 / 1440) c^2 E' from the law's moduli at the reference state
    (isotropic: lambda = AA[11, 22], mu = AA[12, 12]); E' = 4 mu (lambda + mu) /
    (lambda + 2 mu) the plane-stress modulus, c = lambda / (lambda + 2 mu) the
    thickness Poisson factor (nu / (1 - nu))."""
    AA = law.evaluate(np.eye(3))[2]
    lam, mu = AA[0, 4], AA[1, 1]
    if not (mu > 0 and lam + 2 * mu > 0):
        raise ValueError(f"{law!r}: moduli at the reference state lambda = {lam:g}, mu = {mu:g} "
                         "are not those of a stable isotropic law")
    E_plane = 4 * mu * (lam + mu) / (lam + 2 * mu)
    c = lam / (lam + 2 * mu)
    return h ** 5 / 1440.0 * c * c * E_plane


def _hermite_rows(x, ell):
    """(value, d/ds, d2/ds2, d3/ds3) of the 4 cubic Hermite functions at x in [0, 1]."""
    H, dH, ddH = line.hermite(x, ell)
    d3H = np.array([12 / ell ** 3, 6 / ell ** 2, -12 / ell ** 3, 6 / ell ** 2])
    return np.array([H, dH, ddH, d3H])


# kinematic vector per point: k = (a, a', a'', a''', b, b', b'', b''') (d/ds)
A0, B0 = 0, 4


def _square_parts(ks, kd, first):
    """g = x_0 y_0 - X_0 Y_0 style differences of the products that make up
    f = sum_x x^2 over the components x in ``first`` (offsets into k) and
    their s-derivatives f', f'': values (n, 3) from the sum ks = k + kref and
    difference kd = k - kref (exact zero at the reference), gradients
    (n, 3, 8) and Hessians (3, 8, 8) of f, f', f'' with respect to k."""
    n = len(ks)
    val = np.zeros((n, 3))
    grad = np.zeros((n, 3, 8))
    hess = np.zeros((3, 8, 8))
    k = 0.5 * (ks + kd)
    for o in first:
        x0, x1, x2 = o, o + 1, o + 2
        # f = x0^2, f' = 2 x0 x1, f'' = 2 (x1^2 + x0 x2); u^2 - U^2 = (u - U)(u + U)
        val[:, 0] += kd[:, x0] * ks[:, x0]
        val[:, 1] += kd[:, x0] * ks[:, x1] + ks[:, x0] * kd[:, x1]
        val[:, 2] += 2 * kd[:, x1] * ks[:, x1] + kd[:, x0] * ks[:, x2] + ks[:, x0] * kd[:, x2]
        grad[:, 0, x0] += 2 * k[:, x0]
        grad[:, 1, x0] += 2 * k[:, x1]
        grad[:, 1, x1] += 2 * k[:, x0]
        grad[:, 2, x1] += 4 * k[:, x1]
        grad[:, 2, x0] += 2 * k[:, x2]
        grad[:, 2, x2] += 2 * k[:, x0]
        hess[0, x0, x0] += 2
        hess[1, x0, x1] += 2
        hess[1, x1, x0] += 2
        hess[2, x1, x1] += 4
        hess[2, x0, x2] += 2
        hess[2, x2, x0] += 2
    return val, grad, hess


def _strain_derivative(parts, shift, D, M, second):
    """The elastic strain eps = (f - D) / (2 D) of f = a sum of squares (parts:
    f - F, f' - F', f'' - F'' for its reference value F, with derivatives in
    k) and the natural (grown) value D of f (n, 3: D, D', D''), shift = D - F:
    d eps / dS (second=False) or d2 eps / dS2, S the reference arclength
    (dS/ds = sqrt(M), M (n, 3) the reference metric).  Returns the value
    (n,), gradient (n, 8) and Hessian (n, 8, 8) in k."""
    val, grad, hess = parts
    fd = val - shift                                                        # f - D and derivatives
    D0, D1, D2 = D
    e1 = np.stack([-D1 / (2 * D0 ** 2), 1 / (2 * D0), 0 * D0], 1)           # eps' on (f-D, ...)'
    if not second:
        c = e1 / np.sqrt(M[0])[:, None]
    else:
        e2 = np.stack([-D2 / (2 * D0 ** 2) + D1 ** 2 / D0 ** 3, -D1 / D0 ** 2, 1 / (2 * D0)], 1)
        c = e2 / M[0][:, None] - e1 * (M[1] / (2 * M[0] ** 2))[:, None]     # d2 eps / dS2
    return (np.einsum("nj,nj->n", c, fd), np.einsum("nj,njk->nk", c, grad),
            np.einsum("nj,jkl->nkl", c, hess))


def _squares(u0, u1, u2):
    """|u|^2 and its first two derivatives from u, u', u'' (n, 3): (3, n)."""
    dot = lambda x, y: (x * y).sum(-1)
    return np.stack([dot(u0, u0), 2 * dot(u0, u1), 2 * (dot(u1, u1) + dot(u0, u2))])


class LineStrainGradient:
    """R of the module docstring for a LineShell (axisymmetric or plane strain)."""

    def __init__(self, engine):
        e = engine
        self.engine = e
        self.C = coefficient(e.law, e.h)
        npt = line.GAUSS_POINTS
        xg, _ = np.polynomial.legendre.leggauss(npt)
        xi = 0.5 * (xg + 1)
        ne = e.n_elements
        ell = np.diff(e.s)
        self.Kq = np.zeros((ne * npt, 8, 8))       # k = Kq u_e at the Gauss points
        for el in range(ne):
            for g, x in enumerate(xi):
                self.Kq[el * npt + g] = self._rows(x, ell[el])
        # interior nodes: the element on the left (at x = 1) and on the right (x = 0)
        nodes = np.arange(ne) if e.closed else np.arange(1, ne)
        self.left, self.right = (nodes - 1) % ne, nodes % ne
        self.Kl = np.array([self._rows(1.0, ell[el]) for el in self.left]).reshape(-1, 8, 8)
        self.Kr = np.array([self._rows(0.0, ell[el]) for el in self.right]).reshape(-1, 8, 8)
        Uref = e.ref_nodes.reshape(-1)
        self.kq_ref = np.einsum("qrd,qd->qr", self.Kq, Uref[e.elem_dofs[e.qelem]])
        self.kl_ref = np.einsum("qrd,qd->qr", self.Kl, Uref[e.elem_dofs[self.left]])
        self.kr_ref = np.einsum("qrd,qd->qr", self.Kr, Uref[e.elem_dofs[self.right]])
        # jump weight: (ring length or unit width) / (mean element length in arclength)
        jac = np.sqrt(e.ref_nodes[nodes % e.n_nodes, 1] ** 2 + e.ref_nodes[nodes % e.n_nodes, 3] ** 2)
        width = 2 * np.pi * np.abs(e.ref_nodes[nodes % e.n_nodes, 0]) if e.azimuthal else np.ones(len(nodes))
        self.w_node = self.C * width / (0.5 * (ell[self.left] + ell[self.right]) * jac)
        self.w_q = self.C * e.W

    @staticmethod
    def _rows(x, ell):
        R = _hermite_rows(x, ell)
        K = np.zeros((8, 8))
        K[A0:A0 + 4][:, [0, 1, 4, 5]] = R          # a: DOFs a_i, a'_i, a_j, a'_j
        K[B0:B0 + 4][:, [2, 3, 6, 7]] = R          # b
        return K

    def _metrics(self, kref, s):
        """Reference and natural (grown) values, with two s-derivatives, of
        |r_s|^2 and |r_phi|^2 at the parameters s: {name: (F, D)} with F, D
        (3, n).  The natural tangents are G0 R_s and G0 R_phi, G0 = G0(t, s) of
        the engine (its current t), s-derivatives of G0 by central differences
        of the growth field (as the engine's dG0)."""
        e = self.engine
        A, dA, ddA, dddA, B, dB, ddB, dddB = kref.T
        z = np.zeros_like(A)
        ds = 1e-4 * (e.s[-1] - e.s[0])
        G, Gp, Gm = (e._growth_at(e._t, s + d)[0] for d in (0.0, ds, -ds))
        G1, G2 = (Gp - Gm) / (2 * ds), (Gp - 2 * G + Gm) / ds ** 2
        grown = lambda R0, R1, R2: (np.einsum("nij,nj->ni", G, R0),
                                    np.einsum("nij,nj->ni", G1, R0) + np.einsum("nij,nj->ni", G, R1),
                                    np.einsum("nij,nj->ni", G2, R0) + 2 * np.einsum("nij,nj->ni", G1, R1)
                                    + np.einsum("nij,nj->ni", G, R2))
        Rs = (np.stack([dA, z, dB], 1), np.stack([ddA, z, ddB], 1), np.stack([dddA, z, dddB], 1))
        out = {"mer": (_squares(*Rs), _squares(*grown(*Rs)))}
        if e.azimuthal:
            Rp = (np.stack([z, A, z], 1), np.stack([z, dA, z], 1), np.stack([z, ddA, z], 1))
            out["hoop"] = (_squares(*Rp), _squares(*grown(*Rp)))
        return out

    def _natural_state(self):
        """The metrics at the Gauss points and both sides of the nodes, for the
        engine's current t (recomputed when t changes)."""
        e = self.engine
        if getattr(self, "_t", None) != e._t:
            self._t = e._t
            s_node = e.s[self.right]
            self._nat = (self._metrics(self.kq_ref, e.sq), self._metrics(self.kl_ref, s_node),
                         self._metrics(self.kr_ref, s_node))
        return self._nat

    def _components(self, k, kref, metrics, second):
        """[(value, grad, hess)] of d^n eps/dS^n for the meridional elastic
        strain and, on a surface of revolution (second derivatives), the hoop
        strain."""
        ks, kd = k + kref, k - kref
        F, D = metrics["mer"]
        out = [_strain_derivative(_square_parts(ks, kd, (A0 + 1, B0 + 1)), (D - F).T, D, F, second)]
        if second and "hoop" in metrics:
            Fh, Dh = metrics["hoop"]
            out.append(_strain_derivative(_square_parts(ks, kd, (A0,)), (Dh - Fh).T, Dh, F, second))
        return out

    def evaluate(self, U, mode):
        """R, and (mode >= 1) its gradient over all DOFs, (mode >= 2) the lower
        triangle of its Hessian on the free DOFs (CSR, the engine's numbering).
        Sets ``per_element`` (R of each element; a node's jump term is shared
        by its two elements)."""
        e = self.engine
        nat_q, nat_l, nat_r = self._natural_state()
        ue = U[e.elem_dofs]
        kq = np.einsum("qrd,qd->qr", self.Kq, ue[e.qelem])
        terms = [(self.w_q, v, g, H, self.Kq, e.elem_dofs[e.qelem])
                 for v, g, H in self._components(kq, self.kq_ref, nat_q, True)]
        per = np.zeros(e.n_elements)
        for w, v, *_ in terms:
            per += np.bincount(e.qelem, w * v * v, minlength=e.n_elements)
        if len(self.left):
            kl = np.einsum("qrd,qd->qr", self.Kl, ue[self.left])
            kr = np.einsum("qrd,qd->qr", self.Kr, ue[self.right])
            (vl, gl, Hl), = self._components(kl, self.kl_ref, nat_l, False)
            (vr, gr, Hr), = self._components(kr, self.kr_ref, nat_r, False)
            nj = len(vl)
            Kj = np.zeros((nj, 16, 16))
            Kj[:, 0:8, 0:8] = self.Kl
            Kj[:, 8:16, 8:16] = self.Kr
            gj = np.zeros((nj, 16))
            gj[:, 0:8], gj[:, 8:16] = gl, -gr
            Hj = np.zeros((nj, 16, 16))
            Hj[:, 0:8, 0:8], Hj[:, 8:16, 8:16] = Hl, -Hr
            vj = vl - vr
            terms.append((self.w_node, vj, gj, Hj, Kj,
                          np.c_[e.elem_dofs[self.left], e.elem_dofs[self.right]]))
            half = 0.5 * self.w_node * vj * vj
            per += np.bincount(self.left, half, minlength=e.n_elements)
            per += np.bincount(self.right, half, minlength=e.n_elements)
        self.per_element = per
        R = float(per.sum())
        if mode == 0:
            return R, None, None
        g = np.zeros(4 * e.n_nodes)
        rows, cols, vals = [], [], []
        for w, v, gk, Hk, Kk, dofs in terms:
            J = (gk[:, None, :] @ Kk)[:, 0]                     # d value / d element DOFs
            np.add.at(g, dofs, 2 * (w * v)[:, None] * J)
            if mode >= 2:
                # batched matmuls: a three-operand einsum without a contraction
                # order was most of the 1D engines' time on small meshes
                Hd = 2 * w[:, None, None] * (J[:, :, None] * J[:, None, :]
                                             + v[:, None, None] * (Kk.transpose(0, 2, 1) @ Hk @ Kk))
                rows.append(np.broadcast_to(dofs[:, :, None], Hd.shape).ravel())
                cols.append(np.broadcast_to(dofs[:, None, :], Hd.shape).ravel())
                vals.append(Hd.ravel())
        if mode == 1:
            return R, g, None
        # triplets (free row, free column, value) of the lower triangle: the
        # engine assembles them with its own into one matrix, so that the
        # pattern stays the same at every evaluation (the linear solver keeps
        # the pattern of the first Hessian; adding two CSR matrices drops the
        # entries that happen to cancel)
        fr, fc = e._fidx[np.concatenate(rows)], e._fidx[np.concatenate(cols)]
        keep = (fr >= 0) & (fc >= 0) & (fr >= fc)
        return R, g, (fr[keep], fc[keep], np.concatenate(vals)[keep])


def dkt_active_elements(mesh, h):
    """The triangles that carry the term: longest edge shorter than h, or
    height (twice the area over the longest edge) below h / 2.  A coarser
    element cannot hold the short in-plane waves the term stabilizes (their
    energy becomes negative only beyond k h = 19 at 5 % compression, k h = 8
    near 30 %; an element of size h resolves k h up to about 10): clamped
    compressed plates with elements of size h have no negative Hessian
    eigenvalue without the term up to 25 % compression (docs/validity.md;
    plates of side 2 h), but a clamped plate of side 5 h does, from 10-15 %
    at nu >= 0.4 and at 25 % at nu = 0.3 (README, Validity limits: a mode of
    the nodal tangent derivatives, which this term does not address).
    Skipping them keeps the cost and the Hessian pattern of thin-shell meshes
    (elements larger than h) unchanged.  The height covers elements long but
    thin against h, which hold such waves across: a boundary triangle of
    height 0.15 h on a grown square made the energy unbounded below without
    it (tests/test_validity.py).  For right isosceles triangles the two
    criteria coincide, and an element short by its height only has an
    aspect ratio of 2 or more.  The regge membrane metric gives the same thin
    triangles (discretize/dkt.THIN_HEIGHT) the conforming field's own metric."""
    tri, X = mesh.triangles, mesh.vertices
    edges = np.stack([X[tri[:, (k + 1) % 3]] - X[tri[:, k]] for k in range(3)], axis=1)
    longest = np.linalg.norm(edges, axis=2).max(axis=1)
    return (longest < h) | (2.0 * mesh.areas / longest < THIN_HEIGHT * h)


class DKTStrainGradient:
    """R of the module docstring for a DKT Shell: interiors of the active
    elements (dkt_active_elements) and the jumps across the interior edges
    between two of them (kernels/strain_gradient_dkt.py).

    The jump terms couple the two vertices opposite an edge, which share no
    triangle: ``virtual_triangles`` lists, per such edge, a triangle
    (opposite 1, opposite 2, a shared vertex) that the Hessian pattern must
    include; ``set_pattern`` takes their element map.

    The interiors are integrated by the 3-point rule (degree 2), not the
    shell's 6-point one: on a flat facet |grad grad e|^2 is of degree 4, but
    the term only stabilizes waves shorter than the thickness, and the
    degree-2 rule does so as well at half the cost (the 100k leaf's Hessian
    6.0 -> 5.0 s).  Measured against the 6-point rule (2026-12-06): the
    energies of both scenes of issue 14 (bench/validity.py --dkt, h = 0.05 ...
    0.2, l = h ... h/16) change by at most 1.1e-4 at l = h and 2e-7 at l <=
    h/4, the invagination meridian not in three digits; the clamped
    compressed strip and plate stay positive definite down to l = h/16 and
    the thin-flap square stable (tests/test_validity.py)."""

    EDGE_POINTS = 2
    INTERIOR_POINTS = 3

    def __init__(self, mesh, law, h, active):
        self.C = coefficient(law, h)
        self.bary, self.wts = rule(self.INTERIOR_POINTS)
        self.active = np.ascontiguousarray(active, dtype=np.bool_)
        tri, X = mesh.triangles, mesh.vertices
        eoh = mesh.edge_of_halfedge.ravel()
        order = np.argsort(eoh, kind="stable")
        pair = np.where(eoh[order][1:] == eoh[order][:-1])[0]
        h1, h2 = order[pair], order[pair + 1]          # the two half-edges of each interior edge
        both = self.active[h1 // 3] & self.active[h2 // 3]
        h1, h2 = h1[both], h2[both]
        self.edge_tri = np.ascontiguousarray(np.c_[h1 // 3, h2 // 3])
        k1, k2 = h1 % 3, h2 % 3                        # half-edge k joins local vertices k, k+1
        nE = len(h1)
        xg, wg = np.polynomial.legendre.leggauss(self.EDGE_POINTS)
        tg, wg = 0.5 * (xg + 1), 0.5 * wg
        lam = np.zeros((nE, 2, self.EDGE_POINTS, 3))
        for side, k in ((0, k1), (1, k2)):
            t = tg[None, :] if side == 0 else 1 - tg[None, :]   # same points, opposite direction
            rows = np.arange(nE)
            lam[rows[:, None], side, np.arange(self.EDGE_POINTS)[None, :], k[:, None]] = 1 - t
            lam[rows[:, None], side, np.arange(self.EDGE_POINTS)[None, :], ((k + 1) % 3)[:, None]] = t
        self.edge_lam = np.ascontiguousarray(lam)
        a, b = tri[h1 // 3, k1], tri[h1 // 3, (k1 + 1) % 3]
        length = np.linalg.norm(X[b] - X[a], axis=1)
        height = (mesh.areas[h1 // 3] + mesh.areas[h2 // 3]) / length
        self.edge_w = np.ascontiguousarray(wg[None, :] * (length / height)[:, None])
        t = (X[b] - X[a]) / length[:, None]
        nu = np.cross(mesh.facet_normals[h1 // 3], t) + np.cross(mesh.facet_normals[h2 // 3], t)
        nu /= np.linalg.norm(nu, axis=1)[:, None]
        self.edge_frame = np.ascontiguousarray(np.stack([t, nu], axis=1))
        # edge nodes: side 0's vertices (0, 1, 2 in its order), then side 1's opposite (3)
        opp1 = tri[h1 // 3, (k1 + 2) % 3]
        opp2 = tri[h2 // 3, (k2 + 2) % 3]
        nodes4 = np.c_[tri[h1 // 3], opp2]
        self.edge_node = np.zeros((nE, 2, 3), np.int64)
        self.edge_node[:, 0] = np.arange(3)
        for i in range(3):
            self.edge_node[:, 1, i] = np.argmax(nodes4 == tri[h2 // 3, i][:, None], axis=1)
        self.edge_local = -np.ones((nE, 4, 2), np.int64)
        for side in range(2):
            for i in range(3):
                self.edge_local[np.arange(nE), self.edge_node[:, side, i], side] = i
        self._virtual = np.c_[opp1, opp2, a]
        self.edge_order, self.edge_colour_start = _colour(nodes4, mesh.n_nodes)
        self.edge_oo = None            # set_pattern
        self.per_element = np.zeros(len(tri))
        self._RE = np.zeros(nE)

    def virtual_triangles(self):
        return self._virtual

    def set_pattern(self, eoff_virtual):
        """The block offsets of the (opposite 1, opposite 2) node pairs
        (kernels/assembly.hessian_pattern) from those of the virtual
        triangles (local vertices 0, 1)."""
        self.edge_oo = np.ascontiguousarray(eoff_virtual[:, 0, 1])

    def add(self, mode, shell, U, Le, G, data):
        """Add R to the element energies Le, the gradient G (n, 3, 3) and the
        Hessian values data of the shell's assembly; sets ``per_element``
        (interior term plus half of each adjacent edge term)."""
        tri, X, T, G0 = shell.mesh.triangles, shell.X, shell.frames, shell._Gt0
        Re = self.per_element
        add_dkt_strain_gradient(mode, self.C, self.active, tri, X, T, U, G0, self.bary, self.wts,
                                shell._order, shell._colour_start, shell._hmap, Re, Le, G, data)
        add_dkt_edge_strain_gradient(mode, self.C, tri, X, T, U, G0, self.edge_tri, self.edge_lam,
                                     self.edge_w, self.edge_frame, self.edge_node, self.edge_local,
                                     self.edge_oo, self.edge_order, self.edge_colour_start,
                                     shell._hmap, self._RE, G, data)
        half = 0.5 * self._RE
        for side in range(2):
            np.add.at(Re, self.edge_tri[:, side], half)
            np.add.at(Le, self.edge_tri[:, side], half)


def _colour(groups, n_nodes):
    """Greedy colouring of node groups (rows): no two groups of a colour share
    a node.  Returns (order by colour, start of each colour)."""
    colour = -np.ones(len(groups), np.int64)
    node_colours = [set() for _ in range(n_nodes)]
    for j, g in enumerate(groups):
        taken = set().union(*(node_colours[v] for v in g))
        c = 0
        while c in taken:
            c += 1
        colour[j] = c
        for v in g:
            node_colours[v].add(c)
    order = np.argsort(colour, kind="stable")
    start = np.searchsorted(colour[order], np.arange(colour.max() + 2 if len(colour) else 1))
    return order, start
