"""Model levels and the point-level API (MODEL.md section 4).

Levels of the energy density (per unit reference area, see kernels/point.py):

``membrane``
    ``h Wbar(F0) - h m.y1`` -- stretching only.
``bending``
    membrane + ``(h^3/24) min_y2 phi''(0)``, ``phi(Z) = Wbar(F0 + Z F1, Z)``:
    the condensed bending energy ``rho:AA:rho - y2.B y2`` plus the terms of a
    through-thickness growth gradient ``G1`` (which drives natural curvature),
    without the curvature and load couplings.
``consistent``
    all of MODEL.md section 4 (the paper's eq:twod plus the ``_Z`` terms).
"""

from dataclasses import dataclass

import numpy as np

from .kernels.point import (LEVEL_BENDING, LEVEL_CONSISTENT, LEVEL_MEMBRANE,
                            MODE_ENERGY, MODE_GRADIENT, MODE_HESSIAN, OK,
                            STATUS_TEXT, new_scratch, point_kernel)

LEVELS = {"membrane": LEVEL_MEMBRANE, "bending": LEVEL_BENDING,
          "consistent": LEVEL_CONSISTENT}
MODES = {"energy": MODE_ENERGY, "gradient": MODE_GRADIENT, "hessian": MODE_HESSIAN}


class ShellError(RuntimeError):
    """A physical or numerical failure at a known place (element, point)."""


def level_id(level):
    try:
        return LEVELS[level]
    except KeyError:
        raise ValueError(f"unknown model level {level!r}; choose one of {sorted(LEVELS)}") from None


FACES = {"inner": -0.5, "outer": 0.5}       # Z / h of the faces


def pressure_face(face, h):
    """Z of the face a follower pressure acts on (``pressure(p, face=...)``):
    ``"inner"`` Z = -h/2 (the side the normal points away from), ``"outer"``
    Z = +h/2; ``"middle"``: None (the potential -p V of the middle surface,
    first order in h; docs/pressure.md)."""
    if face == "middle":
        return None
    try:
        return FACES[face] * h
    except KeyError:
        raise ValueError(f"pressure face {face!r}: choose 'inner', 'outer' or 'middle'") from None


def checked_int(name, value, low):
    """``value`` as an int >= low (bools and non-integral numbers refused)."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)):
        raise TypeError(f"{name} must be an integer, got {value!r}")
    if value < low:
        raise ValueError(f"{name} must be at least {low}, got {value!r}")
    return int(value)


def checked_float(name, value, low, high=None, zero_ok=False, high_ok=False):
    """``value`` as a finite float in (low, high) (``zero_ok``: low
    included; ``high_ok``: high included; high None: no upper bound)."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise TypeError(f"{name} must be a number, got {value!r}")
    value = float(value)
    above = value >= low if zero_ok else value > low
    below = high is None or (value <= high if high_ok else value < high)
    if not (np.isfinite(value) and above and below):
        interval = (("[" if zero_ok else "(") + f"{low:g}, "
                    + ("inf)" if high is None else f"{high:g}" + ("]" if high_ok else ")")))
        raise ValueError(f"{name} must be in {interval}, got {value!r}")
    return value


def check_thickness(h):
    return checked_float("thickness", h, 0)


@dataclass
class PointResult:
    L: float
    grad: np.ndarray     # dL/dv, v = (r_1, r_2, r_11, r_12, r_22)
    hess: np.ndarray     # d2L/dv2
    y1: np.ndarray       # director (eq:mm)
    y2: np.ndarray       # second director (eq:g)


def _arr(x, shape, default=0.0):
    if x is None:
        return np.full(shape, default, dtype=np.float64)
    a = np.ascontiguousarray(x, dtype=np.float64)
    if a.shape != shape:
        raise ValueError(f"expected shape {shape}, got {a.shape}")
    if not np.all(np.isfinite(a)):
        raise ValueError(f"non-finite input {a}")
    return a


def evaluate_point(law, v, ref, h, level="consistent", G0=None, G1=None, dG0=None,
                   qbar=None, m=None, dm=None, y1=None, mode="hessian", scratch=None,
                   face_pressure=(0.0, 0.0)):
    """Energy density of MODEL.md section 4 at one point, with derivatives.

    ``v``/``ref``: 15 numbers ``(r_1, r_2, r_11, r_12, r_22)`` of the current and
    reference middle surface in any local coordinates (not necessarily
    orthonormal).  Growth ``G(Z) = G0 + Z G1`` (3x3, default identity / zero),
    ``dG0`` (2x3x3) its surface derivatives; ``qbar``, ``m``, ``dm`` the load
    resultants of eq:qm; ``face_pressure = (p, Z)``: a follower pressure p on
    the face Z (docs/pressure.md; the volume of the middle surface is the
    discretization's).  Raises :class:`ShellError` on failure.
    """
    lev = level_id(level)
    h = check_thickness(h)
    v = _arr(v, (15,))
    ref = _arr(ref, (15,))
    G0 = np.eye(3) if G0 is None else _arr(G0, (3, 3))
    G1 = _arr(G1, (3, 3))
    dG0 = _arr(dG0, (2, 3, 3))
    qbar, m = _arr(qbar, (3,)), _arr(m, (3,))
    dm = _arr(dm, (2, 3))
    y1 = np.zeros(3) if y1 is None else _arr(y1, (3,)).copy()
    y2 = np.zeros(3)
    grad = np.zeros(15)
    hess = np.zeros((15, 15))
    sc = new_scratch() if scratch is None else scratch
    pf, zf = (float(x) for x in face_pressure)
    L, status = point_kernel(MODES[mode], lev, law.kind, law.psi, law.params, h, v, ref,
                             G0, G1, dG0, qbar, m, dm, y1, y2, grad, hess, sc, pf, zf)
    if status != OK:
        raise ShellError(f"point kernel failed: {STATUS_TEXT[status]}")
    return PointResult(L, grad, hess, y1, y2)


def reference_geometry(ref):
    """Mean curvature H, Gaussian curvature K and unit normal n at a point.

    ``ref`` = (R_1, R_2, R_11, R_12, R_22).  Conventions of MODEL.md section 1:
    ``n = R_1 x R_2 / |R_1 x R_2|``, ``kappa = -dn/dR``; the unit sphere with
    outward normal has H = -1, K = 1.
    """
    from .kernels.point import _reference_geometry
    ref = _arr(ref, (15,))
    E, Lam, dgup, na, kap, gup = (np.zeros((3, 3)), np.zeros((2, 3)), np.zeros((2, 2, 3)),
                                  np.zeros((2, 3)), np.zeros((3, 3)), np.zeros((2, 3)))
    H, K, ok = _reference_geometry(ref, E, Lam, dgup, na, kap, gup)
    if not ok:
        raise ShellError("degenerate reference tangents (R_1 x R_2 = 0)")
    return H, K, E[:, 2].copy()


def thickness_jacobian(H, K, Z):
    """mu(Z) = 1 - 2 H Z + K Z^2 (dV = mu dZ dA)."""
    return 1.0 - 2.0 * H * Z + K * Z * Z
