"""The general shell: DKT triangles on any triangulated surface.

Example
-------
>>> mesh = Mesh.read("meshes/disc.obj")
>>> shell = Shell(mesh, thickness=0.02, material=NeoHookean(1.0, nu=0.4))
>>> shell.set_growth(G0=..., G1=...)          # growth F = A G, G(Z) = G0 + Z G1
>>> shell.clamp(mesh.nodes_where(lambda X: X[:, 0] < -0.99))
>>> result = shell.solve(steps=10)
>>> result.save("grown.vtu")

Units are the user's: lengths (mesh, thickness, loads per length/area) and
stresses (moduli, tractions) in one consistent system.  Growth tensors are
dimensionless, in global Cartesian components; ``G1`` has units 1/length.
The continuation parameter t in [0, 1] ramps the growth
(``G(t) = I + t (G - I)``, unless a function of t is given), the loads
(``t * load``) and prescribed motions.
"""

import copy
import warnings
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from .discretize.dkt import rule
from .kernels.assembly import (ELEMENT_STATUS_TEXT, add_position_blocks, assemble_dkt,
                               color_elements, hessian_pattern)
from .kernels.point import ERR_INVERTED
from .linalg import BlockLayout
from .materials import Law
from .mesh import CORNER_DEG, Mesh, MeshError
from .model import check_thickness, level_id, pressure_face
from .solve import EvaluationError, Solvable
from .strain_gradient import DKTStrainGradient, coefficient, dkt_active_elements
from .transfer import carry_over
from .validity import dkt_validity

__all__ = ["Shell", "Result"]


def _nodes(nodes, n):
    """Node indices (integers) or a boolean mask over the n nodes -> sorted indices."""
    a = np.asarray(nodes)
    if a.dtype == bool:
        if a.shape != (n,):
            raise ValueError(f"a boolean node mask must have one entry per node ({n}), got shape {a.shape}")
        return np.flatnonzero(a)
    if a.size and not np.issubdtype(a.dtype, np.integer):
        if not (np.issubdtype(a.dtype, np.number) and np.all(np.isfinite(a)) and np.all(a == np.round(a))):
            raise ValueError(f"node indices must be integers (or a boolean mask), got {a.ravel()[:8]}")
    idx = np.unique(a.astype(np.int64).ravel())
    if len(idx) and (idx.min() < 0 or idx.max() >= n):
        raise ValueError(f"node indices outside 0..{n - 1}: {idx[(idx < 0) | (idx >= n)][:8]}")
    return idx


def _finite(value, shape, name):
    """``value`` as a float array broadcast to ``shape``, every entry finite."""
    try:
        a = np.broadcast_to(np.asarray(value, dtype=np.float64), shape)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name}: expected numbers broadcastable to shape {shape} ({exc})") from None
    bad = np.argwhere(~np.isfinite(a))
    if len(bad) and a.ndim == 0:
        raise ValueError(f"{name} must be finite, got {value!r}")
    if len(bad):
        raise ValueError(f"{name}: non-finite value at index {tuple(int(i) for i in bad[0])} "
                         f"({len(bad)} in all)")
    return a


def _rotvec_to_matrix(w):
    th = np.linalg.norm(w)
    if th < 1e-300:
        return np.eye(3)
    k = w / th
    Kx = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + np.sin(th) * Kx + (1 - np.cos(th)) * Kx @ Kx


def _field(value, n, shape, name):
    """Constant, nodal array or callable(X, N) -> nodal array."""
    a = np.asarray(value, dtype=np.float64)
    if a.shape == shape:
        return np.broadcast_to(a, (n,) + shape).copy()
    if a.shape == (n,) + shape:
        return a.copy()
    raise ValueError(f"{name}: expected shape {shape} or {(n,) + shape}, got {a.shape}")


class Shell(Solvable):
    """A thin shell on a triangulated reference surface (DKT discretization).

    Parameters
    ----------
    mesh : Mesh (reference middle surface)
    thickness : h (length)
    material : a materials.Law
    level : "membrane" | "bending" | "consistent" (MODEL.md section 4)
    quadrature : points of the triangle rule (default 6, see README)
    membrane : "dkt" (the metric of the DKT gradient field) or "regge" (the
        assumed, locking-free metric of discretize/regge.py, quadrature 6 or 7;
        README, Membrane locking)
    """

    MEMBRANES = ("dkt", "regge")
    # the rules the regge metric takes: the blend's zero element mean needs the
    # quartic metric integrated exactly (a 3-point variant was tried: README,
    # Membrane locking)
    REGGE_RULES = (6, 7)

    def __init__(self, mesh, thickness, material, level="consistent", quadrature=6,
                 membrane="dkt"):
        if not isinstance(mesh, Mesh):
            raise TypeError("mesh must be a shellritz.Mesh")
        if not isinstance(material, Law):
            raise TypeError("material must be a shellritz material law")
        self.mesh = mesh
        self.h = check_thickness(thickness)
        self.law = material
        self.level = level
        self._level = level_id(level)
        self.bary, self.wts = rule(quadrature)
        if membrane not in self.MEMBRANES:
            raise ValueError(f"membrane={membrane!r}: choose one of {self.MEMBRANES}")
        if membrane == "regge" and quadrature not in self.REGGE_RULES:
            raise ValueError(f"membrane='regge' needs a rule of "
                             f"{' or '.join(map(str, self.REGGE_RULES))} points, got quadrature="
                             f"{quadrature} (discretize/regge.py)")
        self.membrane = membrane
        self.strain_gradient = self._strain_gradient_term()
        n = mesh.n_nodes
        self.X = mesh.vertices
        self.frames = mesh.frames.copy()
        self.prolongators = ()          # of the coarser meshes of the last start (transfer.carry_over)
        # growth: G(t) from (G0, G1) by a linear ramp, or a user function of t
        self._G0 = np.broadcast_to(np.eye(3), (n, 3, 3)).copy()
        self._G1 = np.zeros((n, 3, 3))
        self._growth_fn = None
        # boundary conditions: list of (node, slot, comp) masks with values(t)
        self._fixed_user = np.zeros((n, 3, 3), bool)
        self._bc = []          # (mask, values(t, U)) applied in order
        self._moving_bc = False   # some prescribed value changes with t
        self._frame_plane = {}  # node -> symmetry plane axes (frames)
        self._symmetry = []       # (nodes, axis, value)
        self._edges = []          # (kind, nodes, axis): hinges and diaphragms
        # loads at t = 1
        self._f_nodes = np.zeros((n, 3))
        self._q_plus = np.zeros((n, 3))
        self._q_minus = np.zeros((n, 3))
        self._pressure = 0.0
        self._pressure_face = "middle"    # face of the follower pressure (pressure())
        self._prepared = False

    def _strain_gradient_term(self):
        """The h^5 strain-gradient term that keeps the bending levels bounded
        below on fine meshes (strain_gradient.py, docs/validity.md), on the
        elements shorter than h; None where there are none."""
        active = dkt_active_elements(self.mesh, self.h)
        if self.level == "membrane" or not active.any() or coefficient(self.law, self.h) == 0.0:
            return None                   # (nu = 0: R = 0)
        return DKTStrainGradient(self.mesh, self.law, self.h, active)

    def with_thickness(self, thickness):
        """This shell (mesh, material, growth, boundary conditions, loads) at
        another thickness: a new Shell for continuation in the thickness
        (``solve(thickness_path=...)``); a pressure keeps its face."""
        other = copy.copy(self)
        other.h = check_thickness(thickness)
        other.strain_gradient = other._strain_gradient_term()
        other._prepared = False
        return other

    # ------------------------------------------------------------------ growth
    def set_growth(self, G0=None, G1=None, function=None):
        """Growth G(Z) = G0 + Z G1 at t = 1 (constant 3x3, nodal (n,3,3), or
        callable(X, N) -> nodal arrays); ramped as G0(t) = I + t (G0 - I),
        G1(t) = t G1.  Or ``function(t) -> (G0, G1)`` nodal arrays for any path.
        """
        n = self.mesh.n_nodes
        if function is not None:
            if G0 is not None or G1 is not None:
                raise ValueError("give either G0/G1 or function, not both")
            self._growth_fn = function
            try:
                G0_1, G1_1 = function(1.0)
            except (TypeError, ValueError) as exc:
                raise ValueError(f"set_growth: function(t) must return (G0, G1) nodal arrays "
                                 f"(n, 3, 3); at t = 1: {exc}") from None
            self._check_growth(np.asarray(G0_1), np.asarray(G1_1))
            return self
        if callable(G0):
            G0 = G0(self.X, self.mesh.normals)
        if callable(G1):
            G1 = G1(self.X, self.mesh.normals)
        if G0 is not None:
            self._G0 = _field(G0, n, (3, 3), "G0")
        if G1 is not None:
            self._G1 = _field(G1, n, (3, 3), "G1")
        self._check_growth(self._G0, self._G1)
        return self

    def _check_growth(self, G0, G1, warn=True):
        if G0.shape != (self.mesh.n_nodes, 3, 3) or G1.shape != (self.mesh.n_nodes, 3, 3):
            raise ValueError("growth arrays must have shape (n_nodes, 3, 3)")
        for name, G in (("G0", G0), ("G1", G1)):
            bad = np.where(~np.all(np.isfinite(G), axis=(1, 2)))[0]
            if len(bad):
                raise ValueError(f"{name}: non-finite growth at nodes {bad[:8].tolist()}")
        det = np.linalg.det(G0)
        bad = np.where(det <= 0)[0]
        if len(bad):
            raise ValueError(f"G0: det G0 <= 0 at nodes {bad[:8].tolist()} (det = {det[bad[0]]:g})")
        # the grown stress-free state through the thickness, G0 + Z G1 (|Z| <=
        # h/2), must not fold: det(G0 + Z G1) = det G0 prod(1 + Z mu_i), mu_i
        # the eigenvalues of G0^-1 G1, vanishes there iff a real mu_i has
        # h |mu_i| / 2 >= 1; no state of finite energy exists then
        fold = np.zeros(len(G0))
        if G1.any():              # (checked at every t of a path: no work without G1)
            mu = np.linalg.eigvals(np.linalg.solve(G0, G1))
            real = np.abs(mu.imag) <= 1e-12 * np.maximum(np.abs(mu), 1e-300)
            fold = 0.5 * self.h * np.where(real, np.abs(mu.real), 0.0).max(axis=1)
        bad = np.where(fold >= 1.0)[0]
        if len(bad):
            raise ValueError(f"G1: the grown state folds through the thickness at nodes {bad[:8].tolist()}: "
                             f"det(G0 + Z G1) <= 0 at a face Z = -+h/2 (h |mu| / 2 = {fold[bad[0]]:.3g} "
                             f">= 1, mu a real eigenvalue of G0^-1 G1); no state of finite energy "
                             f"exists (MODEL.md section 8 asks h |G1| << |G0|)")
        if warn:
            ratio = self.h * np.linalg.norm(G1, ord=2, axis=(1, 2)) / np.linalg.svd(G0, compute_uv=False)[:, -1]
            if ratio.max() > 0.2:
                k = int(np.argmax(ratio))
                warnings.warn(f"h |G1| / |G0| = {ratio[k]:.3g} at node {k}: through-thickness growth "
                              "gradients should satisfy h |G1| << |G0| (MODEL.md section 8)",
                              stacklevel=3)

    def growth_at(self, t):
        if self._growth_fn is not None:
            G0, G1 = self._growth_fn(t)
            return (np.ascontiguousarray(G0, dtype=np.float64),
                    np.ascontiguousarray(G1, dtype=np.float64))
        I = np.eye(3)
        return I + t * (self._G0 - I), t * self._G1

    # --------------------------------------------------------- boundary conditions
    def _add_bc(self, mask, values):
        self._fixed_user |= mask
        self._bc.append((mask, values))
        self._prepared = False

    def clamp(self, nodes, position=None, rotation=None):
        """Fix positions and both tangent derivatives (a clamped edge).

        ``position``: target positions (k, 3) (default: reference), reached at
        t = 1 linearly; ``rotation``: a rotation vector (3,) (axis * angle) or
        a function t -> 3x3 rotation applied to the reference frames.
        """
        return self._prescribe(nodes, position, rotation, slots=(0, 1, 2))

    def pin(self, nodes, position=None, components="xyz"):
        """Fix the positions of these nodes (point supports), or only some of
        their components (e.g. components="z": a roller free in x and y).

        Only the nodes are held: with membrane="regge" the edges between
        pinned boundary nodes may bow under in-plane tension, as a membrane
        pinned at points does.  To hold a whole edge (a hinge: positions
        along it fixed, rotation about it free) use simply_support (a warning
        names boundary edges pinned at both ends); README, Membrane locking."""
        return self._prescribe(nodes, position, None, slots=(0,), components=components)

    def rotate(self, nodes, rotation):
        """Prescribe only the tangent derivatives: a_i = R(t) T_i (positions free)."""
        return self._prescribe(nodes, None, rotation, slots=(1, 2))

    def _prescribe(self, nodes, position, rotation, slots, components="xyz"):
        n = self.mesh.n_nodes
        idx = _nodes(nodes, n)
        X0 = self.X[idx]
        target = X0 if position is None else _finite(position, X0.shape, "position")
        if rotation is None:
            rot = lambda t: np.eye(3)
        elif callable(rotation):
            rot = rotation
        else:
            w = _finite(rotation, (3,), "rotation").copy()
            rot = lambda t: _rotvec_to_matrix(t * w)
        if not components or set(components) - set("xyz") or len(set(components)) != len(components):
            raise ValueError(f"components must be distinct letters of 'xyz', got {components!r}")
        comp = ["xyz".index(c) for c in components]
        mask = np.zeros((n, 3, 3), bool)
        for s in slots:
            mask[np.ix_(idx, [s], comp if s == 0 else [0, 1, 2])] = True

        if rotation is not None or not np.array_equal(target, X0):
            self._moving_bc = True

        def values(t, U):
            if 0 in slots:
                U[np.ix_(idx, [0], comp)] = (X0 + t * (target - X0))[:, None, comp]
            R = rot(t)
            for s in slots:
                if s > 0:
                    U[idx, s] = self.frames[idx, :, s - 1] @ R.T
        self._add_bc(mask, values)
        return self

    def remove_rigid_motions(self):
        """Remove exactly the six rigid motions of a free body: statically
        determinate 3-2-1 supports on three node positions, which carry no
        force when the loads are self-equilibrated (growth, a pressure on a
        closed surface), so they can never induce stress.  Returns the nodes
        (A, B, C).

        A, the node nearest the centroid, is pinned; B, a far node whose
        direction from A is closest to a coordinate axis e_a, is held on the
        line through A along e_a (its two other components); C, far from that
        line and closest to a coordinate plane through A containing e_a (normal
        e_c), is held in that plane (one component).  Global components are
        enough for any mesh because these targets are *homogeneous*: every
        configuration can be rotated and translated into them (A fixed, AB along
        e_a, ABC in the plane -- a QR decomposition), so the constrained
        equilibrium is the free one, moved rigidly, with zero reactions.  Holding
        B and C at their reference components instead would not be: a shrinking
        body could not reach them.  When AB is not exactly along e_a the body
        turns by that angle (small: B is chosen best aligned) during the
        continuation; prescribed motions are reached at t = 1.
        """
        X = self.X
        D = X - X.mean(axis=0)
        a = int(np.argmin(np.einsum("ij,ij->i", D, D)))
        D = X - X[a]
        dist = np.linalg.norm(D, axis=1)
        far = dist >= 0.5 * dist.max()
        align = np.where(far[:, None], np.abs(D) / np.where(far, dist, 1.0)[:, None], -1.0)
        # best aligned; among equally well aligned nodes (1e-12) the farthest
        score = np.round(align, 12) + 1e-13 * (dist / dist.max())[:, None]
        b, ax = (int(i) for i in np.unravel_index(np.argmax(score), score.shape))
        others = [k for k in range(3) if k != ax]
        u = D[b] / dist[b]
        perp = np.linalg.norm(D - np.outer(D @ u, u), axis=1)
        far = perp >= 0.5 * perp.max()
        offplane = np.where(far[:, None], np.abs(D[:, others]) / np.where(far, dist, 1.0)[:, None], np.inf)
        score = np.round(offplane, 12) - 1e-13 * (perp / perp.max())[:, None]
        c, k = (int(i) for i in np.unravel_index(np.argmin(score), score.shape))
        normal = others[k]
        self.pin([a])
        target = X[b].copy()
        target[others] = X[a, others]
        self.pin([b], position=target, components="".join("xyz"[i] for i in others))
        target = X[c].copy()
        target[normal] = X[a, normal]
        self.pin([c], position=target, components="xyz"[normal])
        return a, b, c

    def simply_support(self, nodes):
        """Hinged edge: positions fixed and the derivative along the boundary
        tangent fixed (the conormal derivative is free); at corners both
        derivatives are fixed.  The nodes must lie on the boundary."""
        self._edges.append(("hinge", _nodes(nodes, self.mesh.n_nodes), None))
        self._prepared = False
        return self

    @staticmethod
    def _axis(axis):
        """0, 1, 2 from 'x', 'y', 'z' or an index."""
        if axis in ("x", "y", "z"):
            return "xyz".index(axis)
        if isinstance(axis, (int, np.integer)) and not isinstance(axis, bool) and 0 <= axis <= 2:
            return int(axis)
        raise ValueError(f"axis must be 'x', 'y', 'z' or 0, 1, 2, got {axis!r}")

    def diaphragm(self, nodes, axis):
        """Rigid diaphragm in the plane normal to ``axis`` (e.g. the end of a
        cylindrical roof, axis 'z'): the displacement components in that plane
        and their derivative along the edge vanish; the normal component and the
        rotation about the edge are free.  The nodes must lie on the boundary."""
        ax = self._axis(axis)
        self._edges.append(("diaphragm", _nodes(nodes, self.mesh.n_nodes), ax))
        self._prepared = False
        return self

    def _edge_tangents(self, idx):
        """Unit tangent along the boundary edges joining nodes of idx, and the
        corner flag (the edges turn by more than CORNER_DEG)."""
        sel = np.zeros(self.mesh.n_nodes, bool)
        sel[idx] = True
        E = self.mesh.boundary_edges
        E = E[sel[E[:, 0]] & sel[E[:, 1]]]
        X = self.X
        acc = {int(i): [] for i in idx}
        for a, b in E:
            t = X[b] - X[a]
            t /= np.linalg.norm(t)
            acc[int(a)].append(t)
            acc[int(b)].append(t)
        out = {}
        for i, ts in acc.items():
            if not ts:
                raise ValueError(f"node {i} is not on a boundary edge joining the given nodes")
            corner = len(ts) == 2 and ts[0] @ ts[1] < np.cos(np.radians(CORNER_DEG))
            t = ts[0] if corner else np.sum(ts, axis=0)
            N = self.mesh.normals[i]
            t = t - (t @ N) * N                  # chords leave the tangent plane
            out[i] = (t / np.linalg.norm(t), corner)
        return out

    def _edge_constraints(self):
        """Masks of hinges and diaphragms, from the final frames."""
        n = self.mesh.n_nodes
        for kind, idx, ax in self._edges:
            mask = np.zeros((n, 3, 3), bool)
            tang = self._edge_tangents(idx)
            comps = [c for c in range(3) if c != ax] if kind == "diaphragm" else [0, 1, 2]
            for i in idx:
                t, corner = tang[int(i)]
                mask[i, 0, comps] = True
                if corner and kind == "hinge":
                    mask[i, 1:, :] = True
                    continue
                align = np.abs(self.frames[i].T @ t)
                s = int(np.argmax(align)) + 1
                if align[s - 1] < 0.99:
                    raise ValueError(f"{kind} at node {i}: no nodal frame vector along the edge "
                                     "(a symmetry plane there imposes another frame)")
                mask[i, s, comps] = True
            m = mask.copy()

            def values(t, U, m=m):
                U[m] = self._Uref[m]
            self._fixed |= mask
            self._bc_setup.append((mask, values))

    def symmetry(self, axis, value=0.0, nodes=None):
        """Symmetry plane X[axis] = value: the shell continues as its mirror image.

        Nodes on the plane (default: all within tolerance) get a frame with one
        vector along the plane normal e (T = N x e, and -e); constraints:
        r . e = value, the derivative along the in-plane frame vector has no
        e-component, the derivative along e is parallel to e.  A node may lie
        on two perpendicular planes (a corner).
        """
        ax = self._axis(axis)
        n = self.mesh.n_nodes
        idx = self.mesh.nodes_on_plane(ax, value) if nodes is None else _nodes(nodes, n)
        if not len(idx):
            raise ValueError(f"symmetry plane {'xyz'[ax]} = {value}: no nodes on it")
        N = self.mesh.normals[idx]
        bad = idx[np.abs(N[:, ax]) > 1e-6]
        if len(bad):
            raise ValueError(f"symmetry plane {'xyz'[ax]} = {value}: the normals at nodes "
                             f"{bad[:8].tolist()} do not lie in the plane")
        for i in idx:
            axes = self._frame_plane.setdefault(int(i), [])
            if ax not in axes:
                axes.append(ax)
            if len(axes) > 2:
                raise ValueError(f"node {i} lies on more than two symmetry planes")
        self._symmetry.append((idx, ax, float(value)))
        self._prepared = False
        return self

    def _symmetry_constraints(self):
        """Masks and values of the symmetry planes, from the final frames."""
        n = self.mesh.n_nodes
        for idx, ax, value in self._symmetry:
            mask = np.zeros((n, 3, 3), bool)
            mask[idx, 0, ax] = True
            for s in (1, 2):
                along = np.abs(self.frames[idx, ax, s - 1]) > 0.5     # frame vector = +-e
                for c in range(3):
                    mask[idx[along], s, c] = c != ax
                    mask[idx[~along], s, c] = c == ax
            m = mask.copy()

            def values(t, U, m=m, idx=idx, ax=ax, value=value):
                U[idx, 0, ax] = value
                sl = m[:, 1:, :]
                U[:, 1:, :][sl] = 0.0
            self._fixed |= mask
            self._bc_setup.append((mask, values))

    # ------------------------------------------------------------------ loads
    def point_force(self, nodes, force):
        """Forces on node positions (dead, ramped with t)."""
        idx = _nodes(nodes, self.mesh.n_nodes)
        F = _finite(force, (len(idx), 3), "point_force: force")
        np.add.at(self._f_nodes, idx, F)
        return self

    def edge_load(self, nodes, traction):
        """Traction per unit reference length on the boundary edges whose both
        ends are in ``nodes`` (constant (3,) or callable X -> (k, 3))."""
        sel = np.zeros(self.mesh.n_nodes, bool)
        sel[_nodes(nodes, self.mesh.n_nodes)] = True
        E = self.mesh.boundary_edges
        E = E[sel[E[:, 0]] & sel[E[:, 1]]]
        if not len(E):
            raise ValueError("edge_load: no boundary edge has both ends in the given nodes")
        X = self.X
        mid = 0.5 * (X[E[:, 0]] + X[E[:, 1]])
        p = _finite(traction(mid) if callable(traction) else traction, mid.shape, "edge_load: traction")
        length = np.linalg.norm(X[E[:, 1]] - X[E[:, 0]], axis=1)
        for k in range(2):
            np.add.at(self._f_nodes, E[:, k], 0.5 * length[:, None] * p)
        return self

    def face_tractions(self, q_plus=None, q_minus=None):
        """Dead tractions per unit reference area on the faces Z = +h/2 (q+) and
        Z = -h/2 (q-): constant (3,), nodal (n, 3) or callable(X, N)."""
        n = self.mesh.n_nodes
        for val, attr in ((q_plus, "_q_plus"), (q_minus, "_q_minus")):
            if val is None:
                continue
            if callable(val):
                val = val(self.X, self.mesh.normals)
            q = _field(val, n, (3,), attr[1:])
            _finite(q, q.shape, attr[1:])
            setattr(self, attr, q)
        return self

    def pressure(self, p, face="middle"):
        """Follower pressure p on a face (docs/pressure.md): the potential -p V,
        V the volume enclosed by the face ``"inner"`` (Z = -h/2) or ``"outer"``
        (Z = +h/2) and the origin, to the order of the model; ``"middle"``: the
        volume of the middle surface (first order in h).  p > 0 pushes along
        the normal (inflates a closed surface with outward normals).  Closed
        surfaces or surfaces with fixed edges."""
        self._pressure = float(_finite(p, (), "pressure"))
        pressure_face(face, self.h)        # checks the name
        self._pressure_face = face
        return self

    # ------------------------------------------------------------------ setup
    def _setup(self):
        if self._prepared:
            return
        n = self.mesh.n_nodes
        N = self.mesh.normals
        self.frames = self.mesh.frames.copy()
        for i, axes in self._frame_plane.items():
            # one frame vector along the (last) plane normal, the other in the plane(s)
            e = np.eye(3)[axes[0]]
            t1 = np.cross(N[i], e) if len(axes) == 1 else np.eye(3)[axes[1]]
            t1 = t1 - (t1 @ N[i]) * N[i]
            t1 /= np.linalg.norm(t1)
            self.frames[i, :, 0] = t1
            self.frames[i, :, 1] = np.cross(N[i], t1)
        for kind, idx, ax in self._edges:
            # frames along the edge (symmetry-plane frames take priority)
            for i, (t, corner) in self._edge_tangents(idx).items():
                if i in self._frame_plane:
                    continue
                t1 = t - (t @ N[i]) * N[i]
                t1 /= np.linalg.norm(t1)
                self.frames[i, :, 0] = t1
                self.frames[i, :, 1] = np.cross(N[i], t1)
        self.frames = np.ascontiguousarray(self.frames)
        self._fixed = self._fixed_user.copy()
        self._bc_setup = list(self._bc)
        self.U = np.zeros((n, 3, 3))
        self.U[:, 0] = self.X
        self.U[:, 1] = self.frames[:, :, 0]
        self.U[:, 2] = self.frames[:, :, 1]
        self._Uref = self.U.copy()
        self._symmetry_constraints()
        self._edge_constraints()
        if self.membrane == "regge":
            self._warn_pinned_boundary_edges()
        free = ~self._fixed.reshape(-1)
        self.free = np.where(free)[0]
        self._build_pattern()
        ne, nq = self.mesh.n_triangles, len(self.wts)
        self.Y1 = np.zeros((ne, nq, 3))
        self.Y2 = np.zeros((ne, nq, 3))
        self._Le = np.zeros(ne)
        self._G = np.zeros((self.mesh.n_nodes, 3, 3))
        self._status = np.zeros(ne, np.int64)
        self._last_evaluation = None     # (t, U, E) of the last evaluation (final_energy)
        self._f_faces = self._face_load_vector()
        self._prepared = True

    def _warn_pinned_boundary_edges(self):
        """membrane="regge": a boundary edge whose two nodes have their
        positions held is a Hermite curve free to bow between them under
        in-plane tension (pin's docstring) if at either node the derivative
        along the edge, sum_k (T_k . e) a_k (e the edge direction, T_k the
        nodal frame), can turn away from e: a free component of a_k, with
        T_k . e nonzero, along an axis that is not e.  A hinge
        (simply_support) fixes it; so do symmetry planes across and along
        the edge (the derivative along the edge keeps its direction)."""
        fixed = self._fixed
        E = self.mesh.boundary_edges
        E = E[fixed[E[:, 0], 0].all(axis=1) & fixed[E[:, 1], 0].all(axis=1)]
        e = self.X[E[:, 1]] - self.X[E[:, 0]]
        e /= np.linalg.norm(e, axis=1)[:, None]
        across = np.abs(e) < 0.99                       # (edge, axis): axis not along the edge
        bowing = np.zeros(len(E), bool)
        for end in (0, 1):
            nodes = E[:, end]
            along = np.abs(np.einsum("ejk,ej->ek", self.frames[nodes], e)) > 1e-8   # T_k . e != 0
            turns = along[:, :, None] & ~fixed[nodes, 1:, :] & across[:, None, :]
            bowing |= turns.any(axis=(1, 2))
        bowing = E[bowing]
        if len(bowing):
            a, b = (int(i) for i in bowing[0])
            warnings.warn(f"{len(bowing)} boundary edges have both nodes pinned (the first: nodes {a}-{b}) "
                          "and the derivative along them free to turn: with membrane='regge' such an "
                          "edge can bow between its nodes under in-plane tension; simply_support(nodes) "
                          "holds the edge (a hinge), clamp(nodes) the edge and its rotation",
                          stacklevel=4)

    def _build_pattern(self):
        """Free-DOF numbering, the Hessian's CSR pattern with its map of entry
        positions, and the element colouring (kernels/assembly.py)."""
        tri = self.mesh.triangles
        fidx = -np.ones(9 * self.mesh.n_nodes, np.int64)
        fidx[self.free] = np.arange(len(self.free))
        self.free_index = fidx
        sg = self.strain_gradient
        pattern_tri = tri if sg is None else np.vstack([tri, sg.virtual_triangles()])
        self._indptr, self._indices, hmap = hessian_pattern(pattern_tri, fidx.reshape(-1, 9))
        self._hmap = hmap[:3] + (hmap[3][: len(tri)],)
        if sg is not None:
            sg.set_pattern(hmap[3][len(tri):])
        self._nnz = len(self._indices)
        colour = color_elements(tri, self.mesh.n_nodes)
        self._order = np.argsort(colour, kind="stable")
        self._colour_start = np.searchsorted(colour[self._order], np.arange(colour.max() + 2))

    def _face_load_vector(self):
        """Nodal forces of -h qbar . r for unit t: sum_q w_q h qbar_q lambda_i."""
        from .kernels.point import _reference_geometry
        f = np.zeros((self.mesh.n_nodes, 3))
        if not (np.any(self._q_plus) or np.any(self._q_minus)):
            return f
        from .discretize.dkt import apply_map, element_chart, point_map
        tri, X, T = self.mesh.triangles, self.X, self.frames
        Q, gl, et, el = np.zeros((3, 2, 2)), np.zeros((3, 2)), np.zeros((3, 2)), np.zeros(3)
        b, C, ref, blocks = np.zeros((5, 9)), np.zeros((2, 9)), np.zeros(15), np.zeros((9, 3))
        w = (np.zeros((3, 3)), np.zeros((2, 3)), np.zeros((2, 2, 3)), np.zeros((2, 3)),
             np.zeros((3, 3)), np.zeros((2, 3)))
        h = self.h
        for e, nodes in enumerate(tri):
            area = element_chart(X[nodes], np.ascontiguousarray(T[nodes]), Q, gl, et, el)
            for i in range(3):
                blocks[3 * i] = X[nodes[i]]
                blocks[3 * i + 1] = T[nodes[i], :, 0]
                blocks[3 * i + 2] = T[nodes[i], :, 1]
            for lam, wq in zip(self.bary, self.wts):
                point_map(lam, Q, gl, et, el, b, C)
                apply_map(b, blocks, ref)
                H, K, _ = _reference_geometry(ref, *w)
                jac = np.linalg.norm(np.cross(ref[0:3], ref[3:6]))
                mup, mum = 1 - H * h + 0.25 * K * h * h, 1 + H * h + 0.25 * K * h * h
                hq = mup * (lam @ self._q_plus[nodes]) + mum * (lam @ self._q_minus[nodes])
                f[nodes] += (wq * area * jac) * np.outer(lam, hq)
        return f

    def _check_solvable(self):
        """Refuse a shell without any fixed DOF (free rigid motions) whose dead
        loads have a net force: it has no equilibrium (solve)."""
        if self._fixed.any() or self._pressure:
            return
        f = self._f_nodes + self._f_faces
        net = f.sum(axis=0)
        if np.linalg.norm(net) > 1e-10 * max(np.abs(f).sum(), 1e-300):
            raise ValueError(f"the shell has no supports (free rigid motions) but its loads have a net "
                             f"force {np.array2string(net, precision=4)}: no equilibrium; clamp or pin "
                             f"nodes, or balance the loads")

    def _failure_hint(self):
        """What the mesh may have to do with a failed solve ('' if nothing)."""
        poor = self.mesh.poor_triangles()
        return f"the mesh has {poor}, a likely cause: remesh them" if poor else ""

    # ------------------------------------------------------------------ problem protocol
    def set_parameter(self, t):
        self._t = t
        self._Gt0, self._Gt1 = self.growth_at(t)
        self._check_growth(self._Gt0, self._Gt1, warn=False)
        self._qp_t = np.ascontiguousarray(t * self._q_plus)
        self._qm_t = np.ascontiguousarray(t * self._q_minus)
        self._f_t = t * (self._f_nodes + self._f_faces)
        self._p_t = t * self._pressure
        for mask, values in self._bc_setup:
            values(t, self.U)

    def parameter_derivative(self, x, t):
        """dg/dt at the free DOFs x, exactly, where only the nodal forces
        (point forces, edge loads) depend on t: the energy's term -t f.r
        gives dg/dt = -f on the positions.  None where growth, face
        tractions, pressure or prescribed motions make the element energies
        depend on t (the solver then differentiates numerically)."""
        grows = self._growth_fn is not None or np.any(self._G1) or np.any(self._G0 != np.eye(3))
        if (grows or self._moving_bc or self._pressure or np.any(self._q_plus)
                or np.any(self._q_minus)):
            return None
        G = np.zeros((self.mesh.n_nodes, 3, 3))
        G[:, 0] = -self._f_nodes
        return G.reshape(-1)[self.free]

    def load_scale(self):
        return float(np.linalg.norm(self._f_t)) + abs(self._p_t) * np.sqrt(self.mesh.areas.sum())

    def energy_magnitude(self):
        """Sum of the magnitudes of the energy terms (its round-off scale)."""
        return self._E_magnitude

    def size_scale(self):
        return float(np.ptp(self.X, axis=0).max())

    def free_state(self):
        self._setup()                  # (a shell not solved yet: its reference state)
        return self.U.reshape(-1)[self.free].copy()

    def set_free_state(self, x):
        self.U.reshape(-1)[self.free] = x

    def save_point(self):
        return (self.U.copy(), self.Y1.copy(), self.Y2.copy())

    def restore_point(self, saved):
        self.U[:], self.Y1[:], self.Y2[:] = saved

    def final_energy(self):
        """The energy of the current state, with the per-element arrays
        (energies, strain-gradient shares: validity.py) at it: those of the
        last evaluation where it was of this state (the solver's last is,
        as a rule: an evaluation less, 3 s at 100k triangles)."""
        last = self._last_evaluation
        if last is not None and last[0] == self._t and np.array_equal(last[1], self.U):
            return last[2]
        return self.evaluate(self.free_state(), 0)[0]

    def evaluate(self, x, mode):
        """Total energy (and gradient/Hessian on the free DOFs) at free DOFs x."""
        U = self.U.copy()
        U.reshape(-1)[self.free] = x
        self._last_evaluation = None
        data = np.empty(self._nnz if mode >= 2 else 0)     # filled by assemble_dkt
        # trial states (line search) start from, but do not overwrite, the warm starts
        Y1 = self.Y1 if mode > 0 else self.Y1.copy()
        has_load = bool(np.any(self._qp_t) or np.any(self._qm_t))
        face = pressure_face(self._pressure_face, self.h)
        assemble_dkt(mode, self._level, self.law.kind, self.law.psi, self.law.params, self.h,
                     self.membrane == "regge", self.mesh.triangles, self.X, self.frames, U,
                     self.bary, self.wts, self._Gt0, self._Gt1, self._qp_t, self._qm_t, has_load,
                     0.0 if face is None else self._p_t, 0.0 if face is None else face,
                     Y1, self.Y2, self._order, self._colour_start, self._hmap,
                     self._Le, self._G, data, self._status)
        if self._status.any():
            # name an inverted element if there is one (the likeliest cause), else the first
            bad = np.flatnonzero(self._status)
            inverted = bad[self._status[bad] == ERR_INVERTED]
            e = int(inverted[0] if len(inverted) else bad[0])
            more = f"; {len(bad) - 1} more elements fail" if len(bad) > 1 else ""
            raise EvaluationError(f"element {e} (nodes {self.mesh.triangles[e].tolist()}): "
                                  f"{ELEMENT_STATUS_TEXT[int(self._status[e])]}{more}")
        if self.strain_gradient is not None:
            self.strain_gradient.add(mode, self, U, self._Le, self._G, data)
        r = U[:, 0]
        E = self._Le.sum() - np.sum(self._f_t * r)
        self._E_magnitude = np.abs(self._Le).sum() + np.abs(self._f_t * r).sum()
        if self._p_t:
            V, gV, HV = _volume_terms(self.mesh.triangles, r, mode)
            E -= self._p_t * V
        self._last_evaluation = (self._t, U, E)       # the per-element arrays hold this state's
        if mode == 0:
            return E, None, None
        G = self._G
        G[:, 0] -= self._f_t
        if self._p_t:
            G[:, 0] -= self._p_t * gV
        g = G.reshape(-1)[self.free]
        if mode == 1:
            return E, g, None
        if self._p_t:
            add_position_blocks(self.mesh.triangles, HV, -self._p_t, self._hmap, data)
        nf = len(self.free)
        K = sp.csr_matrix((data, self._indices, self._indptr), shape=(nf, nf))
        return E, g, K

    def block_layout(self):
        """Nodal blocks: (9, free DOFs in the full numbering, 9 n, callable ->
        the six rigid-body modes of the current state (9 n, 6): translations,
        and rotations acting on positions and both tangent derivatives;
        callable -> the near null space for AMG (9 n, k), at most
        NEAR_NULL_VECTORS of the candidates of _near_null_candidates in their
        order of importance, those dependent on earlier ones left out (on a
        plate the bending modes and strains that involve its normal
        coordinate are zero or rigid rotations); where memory is short, AMG
        keeps the first twelve (AMGSolver, AMG_LEAN_NEAR_NULL)."""
        n = self.mesh.n_nodes

        def rigid_modes():
            return _near_null_candidates(self.U, np.arange(6)).reshape(9 * n, 6)

        def near_null():
            count = 36 if self.strain_gradient is not None else 12
            sample = np.unique(np.linspace(0, n - 1, min(n, NEAR_NULL_SAMPLE)).astype(np.int64))
            C = _near_null_candidates(self.U, np.arange(count), sample)
            keep = _independent_columns(C.reshape(-1, count))[:NEAR_NULL_VECTORS]
            return _near_null_candidates(self.U, keep).reshape(9 * n, len(keep))
        return BlockLayout(9, self.free, 9 * n, rigid_modes, near_null, self.prolongators)

    def _node_positions(self, nodes):
        return self.U[nodes, 0]

    # ------------------------------------------------------------------ solve
    def _describe(self):
        return (f"shellritz: {self.mesh.n_triangles} triangles, {len(self.free)} free DOFs, "
                f"level {self.level}, {len(self.wts)}-point rule")

    def _result(self, history, wall_s, converged, t):
        return Result(self, history, wall_s, converged=converged, t=t)

    def _start_from(self, result):
        """Free DOFs from ``result`` (transfer.py; prescribed DOFs keep their
        values); returns the result's t and the gradient norm of the
        reference state at that t, the force scale the relative tolerance
        refers to (as for a solve from the reference state in one step; the
        transferred state's own gradient is already small, and relative to
        it Newton would be held to round-off)."""
        if not isinstance(result, Result):
            raise TypeError(f"start must be a shellritz Result (of Shell.solve), not {type(result).__name__}")
        if result.t is None:
            raise ValueError("start: the result has no equilibrium state (its solve failed at the start)")
        U, self.prolongators = carry_over(result, self)
        t = float(result.t)
        self.set_parameter(t)
        saved = self.save_point()
        try:
            scale = float(np.linalg.norm(self.evaluate(self.free_state(), 1)[1]))
        except EvaluationError:            # the reference state is not admissible at t
            scale = 0.0
        self.restore_point(saved)
        self.U.reshape(-1)[self.free] = U.reshape(-1)[self.free]
        return t, scale


# AMG near null space (Shell.block_layout): at most NEAR_NULL_VECTORS
# candidates (the coarse operators grow with the square of their number:
# memory at 1M triangles, linalg.AMG_LEAN_NEAR_NULL); candidates that depend
# on earlier ones are found on NEAR_NULL_SAMPLE nodes spread over the mesh
# (the dependencies are polynomial identities in the node positions, exact
# on any nodes in general position) and left out: their part orthogonal to
# the kept ones is below NEAR_NULL_DEPENDENT times the largest candidate
NEAR_NULL_VECTORS = 18
NEAR_NULL_SAMPLE = 4096
NEAR_NULL_DEPENDENT = 1e-8
_PAIRS = ((0, 0), (1, 1), (2, 2), (0, 1), (1, 2), (0, 2))


def _near_null_candidates(U, columns, nodes=None):
    """Candidate near-null vectors of the triangle engine's Hessian at the
    nodal state U (n, 3, 3) (position, tangent derivatives a_1, a_2), the
    ``columns`` of this list, on ``nodes`` (default all): (m, 3, 3, k).

    0-5: the rigid modes, translations e_k and rotations w x (r, a_1, a_2);
    6-11: bending modes, normal displacements c_i c_j n quadratic in the
    centred, scaled coordinates c (the softest modes of a thin shell after
    the rigid ones: with them smoothed aggregation needs 15 instead of 32
    CG iterations on the 12k-triangle leaf, 54 instead of 124 at 50k);
    where the strain-gradient term is on (elements shorter than h; R = C
    |grad grad eps|^2 makes the operator of sixth order at the mesh scale,
    and the coarse spaces must carry the fields it does not see):
    12-17: homogeneous strains, displacements S c with S symmetric (default
    leaf, CG to 1e-8 on the Hessian at the solution, three levels: 40 -> 37
    iterations at 50k triangles, 59 -> 38 at 100k, README "Scaling");
    18-35: quadratic displacements c_i c_j e_k (linear strain: no strain
    gradient), which fill the places of the dependent bending modes and
    strains on a plate (12k-triangle leaf at its flat reference state,
    h/l = 3.6 / 7.3: 44 / 136 -> 29 / 72 iterations).  The tangent
    derivatives of each field along a_1, a_2 make up the other DOFs."""
    V = U if nodes is None else U[nodes]
    a1, a2 = V[:, 1], V[:, 2]
    if max(columns, default=0) >= 6:            # the fields beyond the rigid modes
        centre = U[:, 0].mean(axis=0)
        size = max(np.abs(U[:, 0] - centre).max(), 1e-300)
        c = (V[:, 0] - centre) / size
        nrm = np.cross(a1, a2)
        nrm /= np.linalg.norm(nrm, axis=1)[:, None]
    out = np.zeros((len(V), 3, 3, len(columns)))
    eye = np.eye(3)
    for col, k in enumerate(columns):
        B = out[..., col]
        if k < 3:                                  # translation
            B[:, 0, k] = 1.0
        elif k < 6:                                # rotation w x (r, a_1, a_2)
            B[:] = np.cross(eye[k - 3], V)
        elif k < 12 or k >= 18:                    # c_i c_j n or c_i c_j e_m
            i, j = _PAIRS[(k - 6) if k < 12 else (k - 18) // 3]
            grad = np.zeros_like(c)                # d(c_i c_j)/dr
            grad[:, i] += c[:, j] / size
            grad[:, j] += c[:, i] / size
            d = nrm if k < 12 else eye[(k - 18) % 3]
            B[:, 0] = (c[:, i] * c[:, j])[:, None] * d
            B[:, 1] = (grad * a1).sum(axis=1)[:, None] * d
            B[:, 2] = (grad * a2).sum(axis=1)[:, None] * d
        else:                                      # S c, S[i, j] = S[j, i] = 1
            i, j = _PAIRS[k - 12]
            S = np.zeros((3, 3))
            S[i, j] = S[j, i] = 1.0
            B[:, 0] = c @ S
            B[:, 1] = a1 @ S / size
            B[:, 2] = a2 @ S / size
    return out


def _independent_columns(M):
    """Indices of the columns of M whose part orthogonal to the earlier
    ones kept (modified Gram-Schmidt, twice) is above NEAR_NULL_DEPENDENT
    times the largest column: the candidates are fields of one scale (the
    coordinates c are of order one), so a candidate that vanishes to
    round-off (c_z^2 n on a plate) is left out, not normalized up; so is
    one that is not finite (a degenerate tangent plane)."""
    norms = np.linalg.norm(M, axis=0)
    finite = np.isfinite(norms)
    scale = NEAR_NULL_DEPENDENT * (norms[finite].max() if finite.any() else 0.0)
    kept, Q = [], []
    for j in np.flatnonzero(finite):
        v = M[:, j].astype(np.float64, copy=True)
        for _ in range(2):
            for q in Q:
                v -= (q @ v) * q
        rest = np.linalg.norm(v)
        if rest > scale:
            Q.append(v / rest)
            kept.append(j)
    return np.array(kept, dtype=np.int64)


def _volume_terms(tri, r, mode):
    """V = (1/6) sum r0 . (r1 x r2), its gradient (n, 3) and per-triangle
    Hessian blocks HV (E, 3, 3, 3, 3)."""
    P = r[tri]
    V = np.einsum("ij,ij->i", P[:, 0], np.cross(P[:, 1], P[:, 2])).sum() / 6.0
    if mode == 0:
        return V, None, None
    g = np.zeros_like(r)
    for k in range(3):
        np.add.at(g, tri[:, k], np.cross(P[:, (k + 1) % 3], P[:, (k + 2) % 3]) / 6.0)
    HV = np.zeros((len(tri), 3, 3, 3, 3))
    for k in range(3):
        i, j, l = k, (k + 1) % 3, (k + 2) % 3
        # d2V/dr_i dr_j = [r_l]_x / 6 with (i, j, l) cyclic ... sign from d(r_j x r_l)/dr_j
        S = _skew(P[:, l]) / 6.0
        HV[:, i, j] = -S
        HV[:, j, i] = S
    return V, g, HV


def _skew(a):
    S = np.zeros(a.shape[:-1] + (3, 3))
    S[..., 0, 1], S[..., 0, 2] = -a[..., 2], a[..., 1]
    S[..., 1, 0], S[..., 1, 2] = a[..., 2], -a[..., 0]
    S[..., 2, 0], S[..., 2, 1] = -a[..., 1], a[..., 0]
    return S


@dataclass
class Result:
    """Equilibrium state and fields; see :meth:`save`."""

    shell: Shell
    history: object
    wall_s: float
    converged: bool
    t: float

    def __post_init__(self):
        s = self.shell
        self.r = s.U[:, 0].copy()
        self.derivatives = s.U[:, 1:].copy()
        self.y1 = s.Y1.copy()
        self.y2 = s.Y2.copy()
        self.energy = float(s.final_energy()) if self.t is not None else np.nan
        # per-element measures of the model's range (validity.py); warns for a converged state
        self.validity = dkt_validity(s) if self.t is not None else None
        if self.converged:
            self.validity.warn()

    @property
    def displacement(self):
        return self.r - self.shell.X

    def save(self, path):
        """Write the deformed mesh with fields (VTU by default; any meshio format)."""
        from .post import write_result
        write_result(self, path)
