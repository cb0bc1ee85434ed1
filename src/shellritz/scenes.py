"""Scenes that can be solved by more than one discretization (DESIGN.md:
model no more than a scene needs).

A scene describes the physics once — reference geometry, thickness, law,
growth, loads, supports — and ``solve(method=..., level=..., n=...)`` builds
the engine:

* :class:`RevolutionScene` — a shell of revolution: ``"axisym"`` (meridian,
  C1 Hermite elements) or ``"dkt"`` (a quarter of the surface of revolution
  with symmetry planes, triangles);
* :class:`StripScene` — a strip in cylindrical bending: ``"planestrain"``
  (section curve) or ``"dkt"`` (a strip of triangles with symmetry planes at
  its long edges, i.e. plane strain).

Growth is given by stretches along the reference directions (the paper's
eq:gg): gamma1 along the second direction (the azimuth / the generator),
gamma2 along the curve, gamma_n along the normal, each gamma(s, Z) =
gamma(s) + Z gamma_z(s); numbers or functions of s.  Face tractions are
functions of s returning (q_a, q_b) in the section plane (radial and axial
components for a surface of revolution).
"""

import time
from dataclasses import dataclass, field

import numpy as np

from . import shapes
from .materials import NeoHookean
from .discretize.axisym import AxisymmetricShell
from .discretize.planestrain import PlaneStrainShell
from .shell import Shell


def _fn(g):
    return g if callable(g) else (lambda s, g=g: np.full(np.shape(s), float(g)))


def _check_ends(ends, allowed):
    ends = tuple(ends)
    bad = [e for e in ends if e not in allowed]
    if len(ends) != 2 or bad:
        raise ValueError(f"ends must be two of {allowed}, got {ends!r}")
    return ends


@dataclass
class SceneResult:
    """Solved curve as samples: s, a(s) (radius / x), b(s) (height / z)."""

    method: str
    level: str
    n: int
    dofs: int
    wall_s: float
    s: np.ndarray
    a: np.ndarray
    b: np.ndarray
    iterations: int
    raw: object = field(repr=False, default=None)


class _Scene:
    def __init__(self, curve, s_range, thickness, material, gamma1=1.0, gamma2=1.0, gamma_n=1.0,
                 gamma1_z=0.0, gamma2_z=0.0, q_plus=None, q_minus=None, pressure=0.0):
        self.curve = curve
        self.s_range = tuple(float(x) for x in s_range)
        self.h = thickness
        self.law = material
        self.gamma = [_fn(g) for g in (gamma1, gamma2, gamma_n, gamma1_z, gamma2_z)]
        self.q_plus, self.q_minus = q_plus, q_minus
        self.p = pressure

    def _line_engine(self, cls, level, n):
        """The 1D engine on n elements with growth, tractions and pressure."""
        eng = cls(np.linspace(*self.s_range, n + 1), self.curve, self.h, self.law, level)
        eng.set_stretch_growth(*self.gamma)
        in_plane = lambda q: None if q is None else (lambda s: np.c_[q(s)[0], 0 * s, q(s)[1]])
        eng.face_tractions(in_plane(self.q_plus), in_plane(self.q_minus))
        if self.p:
            eng.pressure(self.p)
        return eng

    @staticmethod
    def _line_solution(eng, steps, verbose):
        r = eng.solve(steps=steps, verbose=verbose)
        return r, len(eng.free), eng.s[: eng.n_nodes], r.a, r.b, len(r.history.iterations)

    def _sample(self, s):
        r, z, dr, dz = (np.asarray(v, dtype=np.float64) for v in self.curve(s))
        return r, z, dr, dz

    methods = ()

    def solve(self, method, level="consistent", n=32, steps=4, verbose=False, **kw):
        """Solve with a discretization from ``self.methods`` at a model level,
        n elements along the curve (the triangle version of a shell of
        revolution also takes ``nphi``, intervals on the widest quarter ring,
        default: square elements there)."""
        if method not in self.methods:
            raise ValueError(f"{type(self).__name__} can be solved by {' or '.join(self.methods)}, "
                             f"not {method!r}")
        t = time.perf_counter()
        res, dofs, s, a, b, its = getattr(self, "_solve_" + method)(level, n, steps, verbose, **kw)
        return SceneResult(method, level, n, dofs, time.perf_counter() - t, s, a, b, its, res)


class RevolutionScene(_Scene):
    """Shell of revolution: curve(s) -> (r, z, r', z') over s_range; the ends
    are poles (r = 0: regular through the axis) unless given in ``ends``
    ('free' | 'clamp' | 'symmetry_z')."""

    methods = ("axisym", "dkt")

    def __init__(self, *args, ends=("pole", "pole"), **kw):
        super().__init__(*args, **kw)
        self.ends = _check_ends(ends, ("pole", "free", "clamp", "symmetry_z"))

    def _solve_axisym(self, level, n, steps, verbose):
        eng = self._line_engine(AxisymmetricShell, level, n)
        for end, kind in zip((0, -1), self.ends):
            if kind == "clamp":
                eng.clamp(end)
            elif kind == "symmetry_z":
                eng.symmetry(end, "b")
        if self.ends[0] in ("pole", "free"):
            eng.fix_coordinate(0, "b")            # no vertical translation
        return self._line_solution(eng, steps, verbose)

    def _solve_dkt(self, level, n, steps, verbose, nphi=None):
        s = np.linspace(*self.s_range, n + 1)
        if nphi is None:   # square elements on the widest ring
            r_max = np.abs(self._sample(s)[0]).max()
            nphi = max(1, int(round(r_max * np.pi / 2 / (s[1] - s[0]))))
        mesh, sn = shapes.revolution(self.curve, s, nphi, phi=(0.0, np.pi / 2))
        X, N = mesh.vertices, mesh.normals
        ephi = np.c_[-X[:, 1], X[:, 0], 0 * X[:, 0]]
        rho = np.hypot(X[:, 0], X[:, 1])
        axis = rho < 1e-12
        ephi[~axis] /= rho[~axis, None]
        ephi[axis] = [0.0, 1.0, 0.0]
        t = np.cross(N, ephi)                      # r_phi x r_s = n  =>  t = n x e_phi ... unit
        t /= np.linalg.norm(t, axis=1)[:, None]
        g = [f(sn) for f in self.gamma]
        outer = lambda u: np.einsum("ni,nj->nij", u, u)
        G0 = g[0][:, None, None] * outer(ephi) + g[1][:, None, None] * outer(t) + g[2][:, None, None] * outer(N)
        G1 = g[3][:, None, None] * outer(ephi) + g[4][:, None, None] * outer(t)
        if axis.any():   # at a pole the two tangential growths must coincide (regularity)
            P = np.eye(3) - outer(N[axis])
            G0[axis] = (0.5 * (g[0][axis] + g[1][axis]))[:, None, None] * P + g[2][axis][:, None, None] * outer(N[axis])
            G1[axis] = (0.5 * (g[3][axis] + g[4][axis]))[:, None, None] * P
        sh = Shell(mesh, self.h, self.law, level=level)
        sh.set_growth(G0=G0, G1=G1)

        def lift(q):
            if q is None:
                return None
            qa, qb = q(sn)
            er = np.zeros_like(X)
            er[~axis] = np.c_[X[~axis, 0], X[~axis, 1], 0 * X[~axis, 0]] / rho[~axis, None]
            return qa[:, None] * er + qb[:, None] * np.array([0, 0, 1.0])
        sh.face_tractions(lift(self.q_plus), lift(self.q_minus))
        if self.p:
            sh.pressure(self.p)
        sh.symmetry("x", 0.0).symmetry("y", 0.0)
        for k, (end, kind) in enumerate(zip((s[0], s[-1]), self.ends)):
            ring = np.where(np.isclose(sn, end))[0]
            if kind == "clamp":
                sh.clamp(ring)
            elif kind == "symmetry_z":
                sh.symmetry("z", X[ring[0], 2])
            elif k == 0:                  # pole or free start: fix the height of one node
                sh.pin(ring[:1], components="z")
        r = sh.solve(steps=steps, verbose=verbose)
        # meridian samples on the phi = 0 line (y = 0)
        on = mesh.nodes_on_plane("y", 0.0)
        on = on[np.argsort(sn[on])]
        return r, len(sh.free), sn[on], np.hypot(r.r[on, 0], r.r[on, 1]), r.r[on, 2], \
            len(r.history.iterations)


class StripScene(_Scene):
    """Strip in cylindrical bending: section curve(s) -> (x, z, x', z') over
    s_range; ``ends``: 'symmetry' (mirror plane x = const with z fixed there,
    removes rigid motions) | 'free' | 'clamp'."""

    methods = ("planestrain", "dkt")

    def __init__(self, *args, ends=("symmetry", "free"), width=0.1, **kw):
        super().__init__(*args, **kw)
        self.ends = _check_ends(ends, ("symmetry", "free", "clamp"))
        self.width = width

    def _solve_planestrain(self, level, n, steps, verbose):
        eng = self._line_engine(PlaneStrainShell, level, n)
        for end, kind in zip((0, -1), self.ends):
            if kind == "clamp":
                eng.clamp(end)
            elif kind == "symmetry":
                eng.symmetry(end, "a").fix_coordinate(end, "b")
        return self._line_solution(eng, steps, verbose)

    def _solve_dkt(self, level, n, steps, verbose):
        s0, s1 = self.s_range
        r, z, dr, dz = self._sample(np.array([s0, s1]))
        if not (np.allclose(z, 0) and np.allclose(dz, 0) and np.allclose(dr, 1)):
            raise NotImplementedError("the triangle version of a strip scene needs a straight reference x = s")
        if self.p:
            raise NotImplementedError("pressure on the triangle version of a strip: use face tractions")
        mesh = shapes.rectangle(n, 1, lx=s1 - s0, ly=self.width, origin=(s0, 0.0))
        X = mesh.vertices
        g = [f(X[:, 0]) for f in self.gamma]
        G0 = np.zeros((mesh.n_nodes, 3, 3))
        G1 = np.zeros((mesh.n_nodes, 3, 3))
        G0[:, 1, 1], G0[:, 0, 0], G0[:, 2, 2] = g[0], g[1], g[2]
        G1[:, 1, 1], G1[:, 0, 0] = g[3], g[4]
        sh = Shell(mesh, self.h, self.law, level=level)
        sh.set_growth(G0=G0, G1=G1)
        lift = lambda q: None if q is None else np.c_[q(X[:, 0])[0], 0 * X[:, 0], q(X[:, 0])[1]]
        sh.face_tractions(lift(self.q_plus), lift(self.q_minus))
        sh.symmetry("y", 0.0).symmetry("y", self.width)
        for x_end, kind in zip((s0, s1), self.ends):
            nodes = mesh.nodes_on_plane("x", x_end)
            if kind == "clamp":
                sh.clamp(nodes)
            elif kind == "symmetry":
                sh.symmetry("x", x_end)
                sh.pin(nodes, components="z")     # no vertical translation
        res = sh.solve(steps=steps, verbose=verbose)
        on = mesh.nodes_on_plane("y", 0.0)
        on = on[np.argsort(X[on, 0])]
        return res, len(sh.free), X[on, 0], res.r[on, 0], res.r[on, 2], len(res.history.iterations)


def leaf(rings=None, thickness=None, membrane=None):
    """The default scene (``shellritz``, the scene file ``meshes/leaf.toml``):
    a growing leaf — a flat disc of radius 1 grown in its plane by
    ``1 + 0.3 rho^2`` buckles into a saddle.  ``rings=None``: the file's mesh
    (16 rings, 1 536 triangles); else the same scene on ``shapes.disc(rings)``
    (about 6 rings^2 triangles; benchmarks).  ``thickness``: instead of the
    file's 0.02 (same units as the disc's radius 1); ``membrane``: the
    membrane metric instead of the file's ("regge"; "dkt" | "regge", Shell).
    Returns the Shell, ready to solve."""
    from importlib.resources import files
    from .meshdata import Surface
    from .scenefile import load_scene
    scene = load_scene(files("shellritz.meshes") / "leaf.toml")
    surf = scene.read() if rings is None else Surface(shapes.disc(int(rings)))
    return scene.build(surf, thickness=thickness, membrane=membrane)[0]


def invagination(thickness=0.1, nu=0.4, compression=0.4, extension=0.2, gradient=-1.0,
                 centre=0.45 * np.pi, width=0.08 * np.pi):
    """A spherical cell sheet (radius 1, the paper's section 6: h = 0.1,
    nu = 0.4, neo-Hookean, growth of the form eq:gg) folding inwards along a
    band: with b(s) = exp(-((s - centre)/width)^2) over the polar angle s from
    the bottom pole, azimuthal growth gamma1 = 1 - compression b, meridional
    gamma2 = 1 + extension b + Z gradient b.  The defaults form an
    equatorial furrow (radius down to 0.665)."""
    bump = lambda s: np.exp(-((s - centre) / width) ** 2)
    sphere = lambda s: (np.sin(s), 1 - np.cos(s), np.cos(s), np.sin(s))
    return RevolutionScene(sphere, (0.0, np.pi), thickness, NeoHookean(1.0, nu=nu),
                           gamma1=lambda s: 1 - compression * bump(s),
                           gamma2=lambda s: 1 + extension * bump(s),
                           gamma2_z=lambda s: gradient * bump(s))
