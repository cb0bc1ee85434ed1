"""Where a solved state is outside the shell model's range (MODEL.md section 8,
docs/validity.md): per-element measures, and a warning naming the elements.

* ``curvature_h``: h times the largest principal curvature of the current
  middle surface (the expansion is in kappa h; the offset surface Z = -h/2
  folds at kappa h = 2, which the point kernel refuses);
* ``growth_gradient_h``: h |G0^-1 G1| (largest singular value): the growth
  varies through the thickness by that fraction;
* ``strain_gradient_share``: the element's h^5 strain-gradient term R over
  its elastic energy, about (k h)^4 / 720 for an in-plane wave of wavenumber
  k: the state has in-plane features shorter than a few thicknesses, where
  the model's expansion (and its h^5 term) no longer describes the 3D solid.

``LIMITS`` are the values above which an element is reported.  At kappa h =
0.43 and h |G1| = 0.1 (the invagination at h = 0.1) the consistent model is
within 5e-3 of the 3D solid (bench/accuracy_vs_cost.py).
"""

import warnings
from dataclasses import dataclass, field

import numpy as np
from numba import njit

from .discretize.dkt import apply_map, element_chart, gather_element, point_map

LIMITS = {"curvature_h": 0.5, "growth_gradient_h": 0.5, "strain_gradient_share": 0.01}

_TEXT = {"curvature_h": "kappa h (curvature times thickness)",
         "growth_gradient_h": "h |G0^-1 G1| (growth gradient through the thickness)",
         "strain_gradient_share": "strain-gradient share of the energy (in-plane features "
                                  "shorter than a few thicknesses)"}


class ValidityWarning(UserWarning):
    """A solved state is outside the shell model's range (see Validity)."""


@dataclass
class Validity:
    """Per-element measures of the model's range; ``flagged[name]``: the
    elements above ``LIMITS[name]``."""

    curvature_h: np.ndarray
    growth_gradient_h: np.ndarray
    strain_gradient_share: np.ndarray
    flagged: dict = field(init=False)

    def __post_init__(self):
        self.flagged = {name: np.where(getattr(self, name) > limit)[0] for name, limit in LIMITS.items()}

    @property
    def ok(self):
        return not any(len(v) for v in self.flagged.values())

    def report(self, element_word="element"):
        """One line per exceeded measure: the limit, the worst value and the
        (first 8) elements, or '' when all are inside."""
        lines = []
        for name, idx in self.flagged.items():
            if not len(idx):
                continue
            values = getattr(self, name)
            worst = idx[np.argsort(-values[idx])][:8]
            lines.append(f"{_TEXT[name]} above {LIMITS[name]:g} in {len(idx)} {element_word}s, largest "
                         f"{values[worst[0]]:.3g}; {element_word}s " + ", ".join(
                             f"{int(e)} ({values[e]:.2g})" for e in worst)
                         + (" ..." if len(idx) > 8 else ""))
        return "\n".join(lines)

    def warn(self, element_word="element"):
        text = self.report(element_word)
        if text:
            warnings.warn("the solved state is outside the shell model's range (README, 'Validity "
                          "limits'):\n" + text, ValidityWarning, stacklevel=3)


def max_curvature(v):
    """Largest |principal curvature| of the surface with local derivatives
    v (..., 15) = (r_1, r_2, r_11, r_12, r_22), per unit current length."""
    r1, r2 = v[..., 0:3], v[..., 3:6]
    a11, a12, a22 = (r1 * r1).sum(-1), (r1 * r2).sum(-1), (r2 * r2).sum(-1)
    n = np.cross(r1, r2)
    n /= np.linalg.norm(n, axis=-1)[..., None]
    b11, b12, b22 = ((n * v[..., k:k + 3]).sum(-1) for k in (6, 9, 12))
    deta = a11 * a22 - a12 * a12
    H = 0.5 * (a22 * b11 - 2 * a12 * b12 + a11 * b22) / deta
    K = (b11 * b22 - b12 * b12) / deta
    return np.abs(H) + np.sqrt(np.maximum(H * H - K, 0.0))


def growth_gradient(h, G0, G1):
    """h |G0^-1 G1|_2 for stacks of 3x3 tensors."""
    return h * np.linalg.norm(np.linalg.solve(G0, G1), ord=2, axis=(-2, -1))


def _share(R, L):
    """R_e / |L_e - R_e| with a floor of 1e-12 of the mean |L| (elements
    without energy)."""
    elastic = np.abs(L - R)
    return R / np.maximum(elastic, 1e-12 * max(np.abs(L).mean(), 1e-300))


def line_validity(engine):
    """Validity of the current state of a LineShell (after an evaluation)."""
    e = engine
    v = np.einsum("qrd,qd->qr", e.B, e.U[e.elem_dofs[e.qelem]]) + e.c
    ne = e.n_elements
    kh = (e.h * max_curvature(v)).reshape(ne, -1).max(axis=1)        # points are stored by element
    gh = growth_gradient(e.h, e._G0q, e._G1q).reshape(ne, -1).max(axis=1)
    L = np.bincount(e.qelem, e._Lq, minlength=ne)
    sg = e.strain_gradient
    R = sg.per_element if sg is not None else np.zeros(ne)
    return Validity(kh, gh, _share(R, L + R))


@njit(cache=True)
def _dkt_curvature(tri, X, T, U, bary, out):
    """Largest h-free |principal curvature| of the current DKT surface at the
    quadrature points, per element (out)."""
    Xe, Te = np.zeros((3, 3)), np.zeros((3, 3, 2))
    Q, gl, et, el = np.zeros((3, 2, 2)), np.zeros((3, 2)), np.zeros((3, 2)), np.zeros(3)
    b, C, blocks, v = np.zeros((5, 9)), np.zeros((2, 9)), np.zeros((9, 3)), np.zeros(15)
    bref = np.zeros((9, 3))
    for e in range(tri.shape[0]):
        gather_element(e, tri, X, T, U, Xe, Te, bref, blocks)
        element_chart(Xe, Te, Q, gl, et, el)
        worst = 0.0
        for iq in range(bary.shape[0]):
            point_map(bary[iq], Q, gl, et, el, b, C)
            apply_map(b, blocks, v)
            n0 = v[1] * v[5] - v[2] * v[4]
            n1 = v[2] * v[3] - v[0] * v[5]
            n2 = v[0] * v[4] - v[1] * v[3]
            nn = np.sqrt(n0 * n0 + n1 * n1 + n2 * n2)
            a11 = v[0] * v[0] + v[1] * v[1] + v[2] * v[2]
            a12 = v[0] * v[3] + v[1] * v[4] + v[2] * v[5]
            a22 = v[3] * v[3] + v[4] * v[4] + v[5] * v[5]
            b11 = (n0 * v[6] + n1 * v[7] + n2 * v[8]) / nn
            b12 = (n0 * v[9] + n1 * v[10] + n2 * v[11]) / nn
            b22 = (n0 * v[12] + n1 * v[13] + n2 * v[14]) / nn
            deta = a11 * a22 - a12 * a12
            H = 0.5 * (a22 * b11 - 2 * a12 * b12 + a11 * b22) / deta
            K = (b11 * b22 - b12 * b12) / deta
            k = abs(H) + np.sqrt(max(H * H - K, 0.0))
            worst = max(worst, k)
        out[e] = worst


def dkt_validity(shell):
    """Validity of the current state of a Shell (after an evaluation)."""
    s = shell
    tri = s.mesh.triangles
    kappa = np.zeros(len(tri))
    _dkt_curvature(tri, s.X, s.frames, s.U, s.bary, kappa)
    G0, G1 = s.growth_at(s._t)
    gh = growth_gradient(s.h, G0, G1)[tri].max(axis=1)
    sg = s.strain_gradient
    R = sg.per_element if sg is not None else np.zeros(len(tri))
    return Validity(s.h * kappa, gh, _share(R, s._Le))
