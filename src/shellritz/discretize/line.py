"""Shells described by one curve: the common engine of the axisymmetric and
plane-strain discretizations (DESIGN.md: "model no more than a scene needs").

The unknown curve is (a(s), b(s)) — (radius, height) of a meridian, or
(x, z) of a plane section — in C1 cubic Hermite elements: per node the DOFs
(a, a', b, b'), ' = d/ds for the reference parameter s.  At a quadrature point
(a, a', a'', b, b', b'') is linear in the element DOFs and the subclass maps it
affinely to the 15 local variables v of the point kernel; the reference
geometry comes from the same interpolation of the reference curve, so the
reference state is exactly stress free.  The same point kernel, levels,
Newton-continuation solver and sparse LDL^T solves as the triangle engine.
"""

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from ..kernels.line_assembly import assemble_line
from ..kernels.point import STATUS_TEXT, _reference_geometry
from ..linalg import BlockLayout
from ..materials import Law
from ..model import check_thickness, level_id, pressure_face
from ..solve import EvaluationError, Solvable
from .. import strain_gradient
from ..validity import line_validity

GAUSS_POINTS = 5


def hermite(xi, ell):
    """Values, first and second s-derivatives of the 4 cubic Hermite functions
    (DOF order: value_i, slope_i, value_j, slope_j) at xi in [0, 1]."""
    H = np.array([1 - 3 * xi ** 2 + 2 * xi ** 3, ell * (xi - 2 * xi ** 2 + xi ** 3),
                  3 * xi ** 2 - 2 * xi ** 3, ell * (-xi ** 2 + xi ** 3)])
    dH = np.array([(-6 * xi + 6 * xi ** 2) / ell, 1 - 4 * xi + 3 * xi ** 2,
                   (6 * xi - 6 * xi ** 2) / ell, -2 * xi + 3 * xi ** 2])
    ddH = np.array([(-6 + 12 * xi) / ell ** 2, (-4 + 6 * xi) / ell,
                    (6 - 12 * xi) / ell ** 2, (-2 + 6 * xi) / ell])
    return H, dH, ddH


class LineShell(Solvable):
    """Base class; subclasses define the kinematic map (see _kinematics)."""

    azimuthal = False          # True: the second coordinate is an azimuth (rotation about z)
    weight_factor = 1.0        # 2 pi for a surface of revolution

    def __init__(self, s, curve, thickness, material, level="consistent", closed=False):
        """s: node parameters (increasing); curve(s) -> (a, b, da/ds, db/ds)
        of the reference curve (arrays).  closed: periodic curve (a ring)."""
        if not isinstance(material, Law):
            raise TypeError("material must be a shellritz material law")
        s = np.asarray(s, dtype=np.float64)
        if s.ndim != 1 or len(s) < 2 or not np.all(np.diff(s) > 0):
            raise ValueError("s must be an increasing sequence of at least 2 node parameters")
        self.s = s
        self.h = check_thickness(thickness)
        self.law = material
        self.level = level
        self._level = level_id(level)
        self.closed = closed
        a, b, da, db = (np.asarray(x, dtype=np.float64) for x in curve(s))
        if not all(np.all(np.isfinite(x)) for x in (a, b, da, db)):
            raise ValueError("the reference curve must be finite at every node")
        if closed and (abs(a[0] - a[-1]) > 1e-9 * np.ptp(a) or abs(b[0] - b[-1]) > 1e-9 * np.ptp(b)):
            raise ValueError("closed=True but the curve does not close (first and last node differ)")
        self.n_nodes = len(s) - 1 if closed else len(s)
        self.n_elements = len(s) - 1
        self.ref_nodes = np.stack([a, da, b, db], axis=1)[: self.n_nodes]
        self._growth = lambda s: (np.broadcast_to(np.eye(3), (len(s), 3, 3)), np.zeros((len(s), 3, 3)))
        self._growth_ramp = True
        self._q_plus = self._q_minus = None
        self._pressure = 0.0
        self._pressure_z = None
        self._edge_forces = np.zeros((self.n_nodes, 2))
        self._fixed = np.zeros((self.n_nodes, 4), bool)
        self._bc = []
        self._build_points()
        # the h^5 strain-gradient term that keeps the bending levels bounded
        # below on fine meshes (strain_gradient.py, docs/validity.md)
        self.strain_gradient = (None if level == "membrane" or strain_gradient.coefficient(material, self.h) == 0.0
                                else strain_gradient.LineStrainGradient(self))       # nu = 0: R = 0

    # ----------------------------------------------------------------- geometry
    def _kinematics(self, kin):
        """Map (a, a', a'', b, b', b'') (6) to v (15): returns (K (15, 6), c (15))."""
        raise NotImplementedError

    def _build_points(self):
        xg, wg = np.polynomial.legendre.leggauss(GAUSS_POINTS)
        xi = 0.5 * (xg + 1)
        wg = 0.5 * wg
        ne = self.n_elements
        nodes = np.arange(ne + 1) % self.n_nodes if self.closed else np.arange(ne + 1)
        self.elem_dofs = np.zeros((ne, 8), np.int64)
        for e in range(ne):
            i, j = nodes[e], nodes[e + 1]
            self.elem_dofs[e] = [4 * i, 4 * i + 1, 4 * i + 2, 4 * i + 3,
                                 4 * j, 4 * j + 1, 4 * j + 2, 4 * j + 3]
        nq = ne * GAUSS_POINTS
        self.qelem = np.repeat(np.arange(ne), GAUSS_POINTS)
        self.sq = np.zeros(nq)
        Hk = np.zeros((nq, 6, 8))
        for e in range(ne):
            ell = self.s[e + 1] - self.s[e]
            for k, x in enumerate(xi):
                q = e * GAUSS_POINTS + k
                self.sq[q] = self.s[e] + x * ell
                H, dH, ddH = hermite(x, ell)
                for comp, off in ((0, 0), (3, 2)):          # a -> rows 0..2, b -> rows 3..5
                    for m, col in enumerate((off, off + 1, off + 4, off + 5)):
                        Hk[q, comp, col] = H[m]
                        Hk[q, comp + 1, col] = dH[m]
                        Hk[q, comp + 2, col] = ddH[m]
        K, c = self._kinematics(None)
        self.B = np.ascontiguousarray(np.einsum("rk,qkd->qrd", K, Hk))
        self.c = np.ascontiguousarray(np.broadcast_to(c, (nq, 15)))
        Uref = self.ref_nodes.reshape(-1)
        self.REF = np.ascontiguousarray(np.einsum("qrd,qd->qr", self.B, Uref[self.elem_dofs[self.qelem]])
                                        + self.c)
        geo = (np.zeros((3, 3)), np.zeros((2, 3)), np.zeros((2, 2, 3)), np.zeros((2, 3)),
               np.zeros((3, 3)), np.zeros((2, 3)))
        self.Hq = np.zeros(nq)
        self.Kq = np.zeros(nq)
        self.Nq = np.zeros((nq, 3))
        self.W = np.zeros(nq)
        for q in range(nq):
            H, Kc, ok = _reference_geometry(self.REF[q], *geo)
            if not ok:
                raise ValueError(f"degenerate reference curve at s = {self.sq[q]:g} (zero tangent or "
                                 "zero radius at a quadrature point)")
            self.Hq[q], self.Kq[q] = H, Kc
            self.Nq[q] = geo[0][:, 2]
            jac = np.linalg.norm(np.cross(self.REF[q, 0:3], self.REF[q, 3:6]))
            e = self.qelem[q]
            self.W[q] = self.weight_factor * wg[q % GAUSS_POINTS] * (self.s[e + 1] - self.s[e]) * jac

    # ------------------------------------------------------------------ inputs
    def _field(self, value, shape, name):
        """A function of s from a constant of the given shape, a function of
        s, or nodal values (n_nodes, *shape) — interpolated by a C2 cubic
        spline through the nodes (periodic on a closed curve)."""
        if callable(value):
            return lambda s: np.asarray(value(s), dtype=np.float64).reshape((len(s),) + shape)
        v = np.asarray(value, dtype=np.float64)
        if v.shape == shape:
            return lambda s: np.broadcast_to(v, (len(s),) + shape)
        if v.shape != (self.n_nodes,) + shape:
            raise ValueError(f"{name}: give a constant of shape {shape}, a function of s or nodal "
                             f"values of shape {(self.n_nodes,) + shape}; got shape {v.shape}")
        if not np.all(np.isfinite(v)):
            raise ValueError(f"{name}: non-finite nodal values at nodes "
                             f"{np.unique(np.where(~np.isfinite(v))[0]).tolist()}")
        from scipy.interpolate import CubicSpline
        if self.closed:
            spline = CubicSpline(self.s, np.concatenate([v, v[:1]]), bc_type="periodic")
        else:
            spline = CubicSpline(self.s, v)
        return spline

    def set_growth(self, G0=None, G1=None, function=None):
        """Growth G(Z) = G0 + Z G1 in the global components of the section
        plane: 3x3 constants, functions of s -> (n, 3, 3) or nodal arrays
        (n_nodes, 3, 3); ramped G(t) = I + t (G - I).  Or function(t, s) ->
        (G0, G1) for any path."""
        if function is not None:
            self._growth_ramp = False
            self._growth = function
            return self
        f0 = self._field(np.eye(3) if G0 is None else G0, (3, 3), "G0")
        f1 = self._field(np.zeros((3, 3)) if G1 is None else G1, (3, 3), "G1")
        self._growth = lambda s: (f0(s), f1(s))
        self._growth_ramp = True
        self._check_growth(*self._growth(self.sq))
        return self

    def set_stretch_growth(self, gamma1, gamma2, gamma_n=1.0, gamma1_z=0.0, gamma2_z=0.0):
        """Growth along the reference directions (the paper's eq:gg):
        G = gamma1 e1 (x) e1 + gamma2 e2 (x) e2 + gamma_n n (x) n with
        gamma_k(s, Z) = gamma_k(s) + Z gamma_k_z(s); e1 = the second coordinate
        direction (azimuth or the straight generator), e2 = the curve tangent.
        Each argument: a number, a function of s or nodal values."""
        names = ("gamma1", "gamma2", "gamma_n", "gamma1_z", "gamma2_z")
        f = [self._field(g, (), name) for g, name in zip((gamma1, gamma2, gamma_n, gamma1_z, gamma2_z), names)]

        def growth(s):
            a, b, da, db = self._ref_at(s)
            t = np.stack([da, np.zeros_like(da), db], axis=1)
            t /= np.linalg.norm(t, axis=1)[:, None]
            e1 = np.tile([0.0, 1.0, 0.0], (len(s), 1))
            n = np.cross(e1, t) if self.azimuthal else np.cross(t, e1)
            out = []
            for g1, g2, gn in ((f[0](s), f[1](s), f[2](s)), (f[3](s), f[4](s), np.zeros(len(s)))):
                out.append(g1[:, None, None] * np.einsum("ni,nj->nij", e1, e1)
                           + g2[:, None, None] * np.einsum("ni,nj->nij", t, t)
                           + gn[:, None, None] * np.einsum("ni,nj->nij", n, n))
            return out[0], out[1]
        self._growth = growth
        self._growth_ramp = True
        self._check_growth(*growth(self.sq))
        return self

    def _ref_at(self, s):
        """Reference (a, b, a', b') at parameters s by Hermite interpolation."""
        e = np.clip(np.searchsorted(self.s, s, side="right") - 1, 0, self.n_elements - 1)
        ell = self.s[e + 1] - self.s[e]
        xi = (s - self.s[e]) / ell
        H, dH, _ = hermite(xi, ell)
        U = self.ref_nodes.reshape(-1)[self.elem_dofs[e]]
        a = H[0] * U[:, 0] + H[1] * U[:, 1] + H[2] * U[:, 4] + H[3] * U[:, 5]
        da = dH[0] * U[:, 0] + dH[1] * U[:, 1] + dH[2] * U[:, 4] + dH[3] * U[:, 5]
        b = H[0] * U[:, 2] + H[1] * U[:, 3] + H[2] * U[:, 6] + H[3] * U[:, 7]
        db = dH[0] * U[:, 2] + dH[1] * U[:, 3] + dH[2] * U[:, 6] + dH[3] * U[:, 7]
        return a, b, da, db

    def _check_growth(self, G0, G1):
        G0 = np.asarray(G0)
        if not (np.all(np.isfinite(G0)) and np.all(np.isfinite(G1))):
            raise ValueError("non-finite growth")
        det = np.linalg.det(G0)
        if np.any(det <= 0):
            k = int(np.argmin(det))
            raise ValueError(f"det G0 <= 0 at s = {self.sq[k] if len(det) == len(self.sq) else k:g}")

    def face_tractions(self, q_plus=None, q_minus=None):
        """Dead tractions per reference face area on Z = +h/2, -h/2: (3,)
        constants or functions of s -> (n, 3), global components of the
        section plane (for a surface of revolution: (q_r, 0, q_z))."""
        def as_fn(q):
            if q is None:
                return None
            if callable(q):
                return lambda s: np.asarray(q(s), dtype=np.float64).reshape(len(s), 3)
            qc = np.asarray(q, dtype=np.float64)
            return lambda s: np.broadcast_to(qc, (len(s), 3))
        self._q_plus, self._q_minus = as_fn(q_plus), as_fn(q_minus)
        return self

    def pressure(self, p, face="middle"):
        """Follower pressure p on a face (docs/pressure.md): the potential -p V,
        V the volume (per unit width for plane strain) enclosed by the face
        ``"inner"`` (Z = -h/2) or ``"outer"`` (Z = +h/2), to the order of the
        model; ``"middle"``: by the middle surface (first order in h).  p > 0
        pushes along the normal."""
        if not np.isfinite(p):
            raise ValueError("pressure must be finite")
        self._pressure = float(p)
        self._pressure_z = pressure_face(face, self.h)
        return self

    def edge_load(self, end, force):
        """Dead force per unit length of the edge at an end (0 or -1): (f_a, f_b)."""
        i = self._end_node(end)
        self._edge_forces[i] += np.asarray(force, float) * self._edge_length(i)
        return self

    # -------------------------------------------------------------- constraints
    def _end_node(self, end):
        if self.closed:
            raise ValueError("a closed curve has no ends")
        if end not in (0, -1):
            raise ValueError("end must be 0 (first node) or -1 (last node)")
        return 0 if end == 0 else self.n_nodes - 1

    def _edge_length(self, i):
        return 1.0

    def _fix(self, i, cols, values=None):
        mask = np.zeros_like(self._fixed)
        mask[i, cols] = True
        self._fixed |= mask
        ref = self.ref_nodes[i, cols].copy()
        vals = ref if values is None else np.asarray(values, float)

        def apply(t, U):
            U[4 * i + np.asarray(cols)] = ref + t * (vals - ref)
        self._bc.append(apply)

    def clamp(self, end):
        """Position and slope of the end fixed at their reference values."""
        self._fix(self._end_node(end), [0, 1, 2, 3])
        return self

    def pin(self, end):
        """Position of the end fixed."""
        self._fix(self._end_node(end), [0, 2])
        return self

    def fix_coordinate(self, end, which, value=None):
        """Fix one coordinate ('a' or 'b') of the end, optionally moved to value at t = 1."""
        col = {"a": 0, "b": 2}[which]
        self._fix(self._end_node(end), [col], None if value is None else [value])
        return self

    def fix_node(self, node, dofs, values=None):
        """Fix DOFs of any node: dofs a sequence of "a", "a'", "b", "b'",
        optionally moved to values (same length) at t = 1."""
        names = ("a", "a'", "b", "b'")
        if not 0 <= node < self.n_nodes:
            raise ValueError(f"node {node} out of range (the curve has {self.n_nodes} nodes)")
        bad = [d for d in dofs if d not in names]
        if bad or not dofs:
            raise ValueError(f"dofs {list(dofs)!r}: give a non-empty sequence of {', '.join(names)}")
        if values is not None and len(values) != len(dofs):
            raise ValueError(f"values: {len(values)} given for {len(dofs)} dofs")
        self._fix(node, [names.index(d) for d in dofs], values)
        return self

    def end_reaction(self, end):
        """Force (f_a, f_b) that the support exerts on the end at the current
        state: the derivative of the total energy with respect to the end
        position (a, b) (plane strain: per unit width; surface of revolution:
        the resultant over the circle)."""
        i = self._end_node(end)
        self.evaluate(self.free_state(), 1)
        g = np.zeros(4 * self.n_nodes)
        np.add.at(g, self.elem_dofs[self.qelem], self._Gq)
        g -= self._f
        if self._p_t:
            g -= self._p_t * self._volume(self.U, 1)[1]
        return g[4 * i], g[4 * i + 2]

    def symmetry(self, end, plane):
        """Mirror symmetry at an end about the plane 'a' = const (fix a and b')
        or 'b' = const (fix b and a')."""
        cols = {"a": [0, 3], "b": [2, 1]}[plane]
        self._fix(self._end_node(end), cols)
        return self

    # ------------------------------------------------------------ solver protocol
    def _setup(self):
        free = ~self._fixed.reshape(-1)
        self.free = np.where(free)[0]
        nq = len(self.sq)
        self.U = self.ref_nodes.reshape(-1).copy()
        self.Y1 = np.zeros((nq, 3))
        self.Y2 = np.zeros((nq, 3))
        self._Lq = np.zeros(nq)
        self._Gq = np.zeros((nq, 8))
        self._Hq = np.zeros((nq, 8, 8))
        self._status = np.zeros(nq, np.int64)
        self._dG0 = np.zeros((nq, 2, 3, 3))
        # sparse pattern of the element Hessians (lower triangle of free DOFs)
        fidx = -np.ones(4 * self.n_nodes, np.int64)
        fidx[self.free] = np.arange(len(self.free))
        self._fidx = fidx

    def _growth_at(self, t, s):
        G0, G1 = self._growth(s) if self._growth_ramp else self._growth(t, s)
        G0, G1 = np.asarray(G0, float), np.asarray(G1, float)
        if self._growth_ramp:
            G0 = np.eye(3) + t * (G0 - np.eye(3))
            G1 = t * G1
        return G0, G1

    def set_parameter(self, t):
        self._t = t
        sq = self.sq
        G0, G1 = self._growth_at(t, sq)
        self._check_growth(G0, G1)
        # surface derivatives of G0: along s by central differences of the
        # input field, along the azimuth exactly (the frame turns about z)
        ds = 1e-6 * (self.s[-1] - self.s[0])
        Gp, _ = self._growth_at(t, sq + ds)
        Gm, _ = self._growth_at(t, sq - ds)
        dG = np.zeros((len(sq), 2, 3, 3))
        sd = self._s_direction
        dG[:, sd] = (Gp - Gm) / (2 * ds)
        if self.azimuthal:
            Wz = np.array([[0, -1.0, 0], [1.0, 0, 0], [0, 0, 0]])
            dG[:, 1 - sd] = Wz @ G0 - G0 @ Wz
        self._G0q = np.ascontiguousarray(G0)
        self._G1q = np.ascontiguousarray(G1)
        self._dG0 = np.ascontiguousarray(dG)
        self._loads(t)
        for apply in self._bc:
            apply(t, self.U)

    def _loads(self, t):
        sq, h = self.sq, self.h
        nq = len(sq)
        mup = 1 - self.Hq * h + 0.25 * self.Kq * h * h
        mum = 1 + self.Hq * h + 0.25 * self.Kq * h * h
        qp = t * (self._q_plus(sq) if self._q_plus else np.zeros((nq, 3)))
        qm = t * (self._q_minus(sq) if self._q_minus else np.zeros((nq, 3)))
        self._QB = np.ascontiguousarray((mup[:, None] * qp + mum[:, None] * qm) / h)
        self._M = np.ascontiguousarray(0.5 * (mup[:, None] * qp - mum[:, None] * qm))
        dm = np.zeros((nq, 2, 3))
        ds = 1e-6 * (self.s[-1] - self.s[0])
        sd = self._s_direction
        for q_fn, mu, sign in ((self._q_plus, mup, 1.0), (self._q_minus, mum, -1.0)):
            if q_fn is not None:
                dm[:, sd] += sign * 0.5 * t * mu[:, None] * (q_fn(sq + ds) - q_fn(sq - ds)) / (2 * ds)
        if self.azimuthal:
            Wz = np.array([[0, -1.0, 0], [1.0, 0, 0], [0, 0, 0]])
            dm[:, 1 - sd] = self._M @ Wz.T
        self._DM = np.ascontiguousarray(dm)
        # work of the dead face loads on the positions: h qbar . r
        f = np.zeros(4 * self.n_nodes)
        for q in range(nq):
            cols = self.elem_dofs[self.qelem[q]]
            r_coef = self._position_rows(q)                 # (3, 8): r = R u
            np.add.at(f, cols, self.W[q] * h * (self._QB[q] @ r_coef))
        np.add.at(f, 4 * np.arange(self.n_nodes), t * self._edge_forces[:, 0])
        np.add.at(f, 4 * np.arange(self.n_nodes) + 2, t * self._edge_forces[:, 1])
        self._f = f
        self._p_t = t * self._pressure

    def _position_rows(self, q):
        """r at point q as rows (3, 8) over the element DOFs (a in x, b in z)."""
        e = self.qelem[q]
        ell = self.s[e + 1] - self.s[e]
        xi = (self.sq[q] - self.s[e]) / ell
        H, _, _ = hermite(xi, ell)
        R = np.zeros((3, 8))
        R[0, [0, 1, 4, 5]] = H
        R[2, [2, 3, 6, 7]] = H
        return R

    def load_scale(self):
        return float(np.linalg.norm(self._f)) + abs(self._p_t)

    def size_scale(self):
        return float(max(np.ptp(self.ref_nodes[:, 0]), np.ptp(self.ref_nodes[:, 2]), 1e-300))

    def energy_magnitude(self):
        return self._E_magnitude

    def free_state(self):
        return self.U[self.free].copy()

    def set_free_state(self, x):
        self.U[self.free] = x

    def save_point(self):
        return (self.U.copy(), self.Y1.copy(), self.Y2.copy())

    def restore_point(self, saved):
        self.U[:], self.Y1[:], self.Y2[:] = saved

    def evaluate(self, x, mode):
        U = self.U.copy()
        U[self.free] = x
        Y1 = self.Y1 if mode > 0 else self.Y1.copy()
        face = self._pressure_z
        assemble_line(mode, self._level, self.law.kind, self.law.psi, self.law.params, self.h,
                      self.elem_dofs, self.qelem, self.B, self.c, self.REF, self.W, U,
                      self._G0q, self._G1q, self._dG0, self._QB, self._M, self._DM,
                      0.0 if face is None else self._p_t, 0.0 if face is None else face,
                      Y1, self.Y2, self._Lq, self._Gq, self._Hq, self._status)
        if self._status.any():
            q = int(np.argmax(self._status != 0))
            raise EvaluationError(f"point s = {self.sq[q]:.6g} (element {self.qelem[q]}): "
                                  f"{STATUS_TEXT[int(self._status[q])]}")
        E = self._Lq.sum() - self._f @ U
        self._E_magnitude = np.abs(self._Lq).sum() + np.abs(self._f * U).sum()
        if self.strain_gradient is not None:
            R, gR, KR = self.strain_gradient.evaluate(U, mode)
            E += R
            self._E_magnitude += R
        if self._p_t:
            V, gV, HV = self._volume(U, mode)
            E -= self._p_t * V
        if mode == 0:
            return E, None, None
        g = np.zeros(4 * self.n_nodes)
        np.add.at(g, self.elem_dofs[self.qelem], self._Gq)
        g -= self._f
        if self._p_t:
            g -= self._p_t * gV
        if self.strain_gradient is not None:
            g += gR
        if mode == 1:
            return E, g[self.free], None
        rows = np.broadcast_to(self.elem_dofs[self.qelem][:, :, None], self._Hq.shape)
        cols = np.broadcast_to(self.elem_dofs[self.qelem][:, None, :], self._Hq.shape)
        vals = self._Hq
        if self._p_t:
            vals = vals - self._p_t * HV
        fr, fc = self._fidx[rows], self._fidx[cols]
        keep = (fr >= 0) & (fc >= 0) & (fr >= fc)
        fr, fc, vals = fr[keep], fc[keep], vals[keep]
        if self.strain_gradient is not None:
            fr, fc, vals = np.r_[fr, KR[0]], np.r_[fc, KR[1]], np.r_[vals, KR[2]]
        nf = len(self.free)
        K = sp.csr_matrix((vals, (fr, fc)), shape=(nf, nf))
        K.sum_duplicates()
        return E, g[self.free], K

    def _volume(self, U, mode):
        """Enclosed volume and its derivatives (per point, element DOFs)."""
        raise NotImplementedError

    def block_layout(self):
        """Nodal blocks (a, a', b, b') and the rigid motions of the curve
        (``_rigid_modes``), for the solver (linalg.free_rigid_modes)."""
        n = self.n_nodes
        rigid = lambda: self._rigid_modes(self.U.reshape(n, 4))
        return BlockLayout(4, self.free, 4 * n, rigid, rigid)

    def _node_positions(self, nodes):
        """(a, b) of the nodes."""
        return self.U.reshape(-1, 4)[nodes][:, [0, 2]]

    def _describe(self):
        return (f"shellritz: {type(self).__name__}, {self.n_elements} elements, "
                f"{len(self.free)} free DOFs, level {self.level}")

    def _result(self, history, wall_s, converged, t):
        return LineResult(self, history, wall_s, converged, t)


@dataclass
class LineResult:
    """Equilibrium curve: nodal (a, a', b, b'), directors at quadrature points."""

    engine: LineShell
    history: object
    wall_s: float
    converged: bool
    t: float

    def __post_init__(self):
        e = self.engine
        nodes = e.U.reshape(-1, 4)
        self.s = e.s[: e.n_nodes]
        self.a, self.da, self.b, self.db = nodes.T.copy()
        self.y1 = e.Y1.copy()
        self.y2 = e.Y2.copy()
        self.energy = float(e.evaluate(e.free_state(), 0)[0]) if self.t is not None else np.nan
        # per-element measures of the model's range (validity.py); warns for a converged state
        self.validity = line_validity(e) if self.t is not None else None
        if self.converged:
            self.validity.warn()

    def at(self, s):
        """(a, b) of the solved curve at parameters s (Hermite interpolation)."""
        e = self.engine
        idx = np.clip(np.searchsorted(e.s, s, side="right") - 1, 0, e.n_elements - 1)
        ell = e.s[idx + 1] - e.s[idx]
        H, _, _ = hermite((np.asarray(s) - e.s[idx]) / ell, ell)
        U = e.U[e.elem_dofs[idx]]
        return (H[0] * U[:, 0] + H[1] * U[:, 1] + H[2] * U[:, 4] + H[3] * U[:, 5],
                H[0] * U[:, 2] + H[1] * U[:, 3] + H[2] * U[:, 6] + H[3] * U[:, 7])

    def save(self, path):
        """The curve as a polyline (meshio) with the nodal DOFs as point data."""
        import meshio
        pts = np.c_[self.a, np.zeros_like(self.a), self.b]
        n = len(pts)
        cells = np.c_[np.arange(n - 1), np.arange(1, n)]
        if self.engine.closed:
            cells = np.vstack([cells, [n - 1, 0]])
        meshio.Mesh(pts, [("line", cells)],
                    point_data={"s": self.s, "slope_a": self.da, "slope_b": self.db}).write(str(path))
