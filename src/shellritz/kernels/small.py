"""Allocation-free 2x2 / 3x3 linear algebra for the Numba kernels.

Everything here works on caller-provided arrays so that the point kernel can
run without heap allocation inside element loops.
"""

import llvmlite.binding as llvm
import numba
import numpy as np
from llvmlite import ir
from numba import njit, types
from numba.extending import intrinsic

from . import KERNEL


def _target_has_fma():
    """Whether Numba compiles for a CPU with fused multiply-add (every x86-64
    since 2013, every aarch64): the features Numba is told to target
    (NUMBA_CPU_NAME / NUMBA_CPU_FEATURES, e.g. "generic" for portable
    caches) or else the host's."""
    if llvm.get_process_triple().startswith("aarch64"):
        return True
    if numba.config.CPU_NAME not in (None, "host"):
        features = numba.config.CPU_FEATURES or ""
    else:
        try:
            features = llvm.get_host_cpu_features().flatten()
        except RuntimeError:            # llvmlite cannot read them on this host
            return False
    return "+fma" in features.split(",")


# where not, fma is a product and a sum (a call of libm's fma would be slow)
FUSED = _target_has_fma()


@intrinsic
def fma(typingctx, a, b, c):
    """a * b + c in one rounding (llvm.fma).  The kernels call it explicitly
    where a product is summed: with Numba's ``fastmath={"contract"}`` LLVM
    fuses where it sees fit, and a run that compiled the kernels and a run
    that loaded them from Numba's cache rounded differently (kernels/__init__.py);
    an explicit fma rounds the same way in every compilation."""
    if not all(isinstance(x, types.Number) for x in (a, b, c)):
        return None
    sig = types.float64(a, b, c)

    def codegen(context, builder, signature, args):
        x, y, z = (context.cast(builder, v, t, types.float64) for v, t in zip(args, signature.args))
        if not FUSED:
            return builder.fadd(builder.fmul(x, y), z)
        d = ir.DoubleType()
        fn = builder.module.declare_intrinsic("llvm.fma", [d], ir.FunctionType(d, [d, d, d]))
        return builder.call(fn, [x, y, z])
    return sig, codegen


@njit(**KERNEL, inline="always")
def det3(a):
    return (a[0, 0] * (a[1, 1] * a[2, 2] - a[1, 2] * a[2, 1])
            - a[0, 1] * (a[1, 0] * a[2, 2] - a[1, 2] * a[2, 0])
            + a[0, 2] * (a[1, 0] * a[2, 1] - a[1, 1] * a[2, 0]))


@njit(**KERNEL)
def cof3(a, out):
    """Cofactor matrix, out[i, j] = d det(a) / d a[i, j]."""
    out[0, 0] = a[1, 1] * a[2, 2] - a[1, 2] * a[2, 1]
    out[0, 1] = a[1, 2] * a[2, 0] - a[1, 0] * a[2, 2]
    out[0, 2] = a[1, 0] * a[2, 1] - a[1, 1] * a[2, 0]
    out[1, 0] = a[0, 2] * a[2, 1] - a[0, 1] * a[2, 2]
    out[1, 1] = a[0, 0] * a[2, 2] - a[0, 2] * a[2, 0]
    out[1, 2] = a[0, 1] * a[2, 0] - a[0, 0] * a[2, 1]
    out[2, 0] = a[0, 1] * a[1, 2] - a[0, 2] * a[1, 1]
    out[2, 1] = a[0, 2] * a[1, 0] - a[0, 0] * a[1, 2]
    out[2, 2] = a[0, 0] * a[1, 1] - a[0, 1] * a[1, 0]


@njit(**KERNEL)
def inv3(a, out):
    """Inverse of a 3x3 matrix; returns the determinant (out untouched if 0)."""
    d = det3(a)
    if d == 0.0:
        return d
    out[0, 0] = (a[1, 1] * a[2, 2] - a[1, 2] * a[2, 1]) / d
    out[1, 0] = (a[1, 2] * a[2, 0] - a[1, 0] * a[2, 2]) / d
    out[2, 0] = (a[1, 0] * a[2, 1] - a[1, 1] * a[2, 0]) / d
    out[0, 1] = (a[0, 2] * a[2, 1] - a[0, 1] * a[2, 2]) / d
    out[1, 1] = (a[0, 0] * a[2, 2] - a[0, 2] * a[2, 0]) / d
    out[2, 1] = (a[0, 1] * a[2, 0] - a[0, 0] * a[2, 1]) / d
    out[0, 2] = (a[0, 1] * a[1, 2] - a[0, 2] * a[1, 1]) / d
    out[1, 2] = (a[0, 2] * a[1, 0] - a[0, 0] * a[1, 2]) / d
    out[2, 2] = (a[0, 0] * a[1, 1] - a[0, 1] * a[1, 0]) / d
    return d


@njit(**KERNEL, inline="always")
def cross(a, b, out):
    out[0] = a[1] * b[2] - a[2] * b[1]
    out[1] = a[2] * b[0] - a[0] * b[2]
    out[2] = a[0] * b[1] - a[1] * b[0]


@njit(**KERNEL)
def chol3(b, out):
    """Cholesky factor (lower) of a symmetric 3x3 matrix.

    Returns False when b is not positive definite (loss of ellipticity of the
    acoustic tensor), in which case out is meaningless.
    """
    scale = abs(b[0, 0]) + abs(b[1, 1]) + abs(b[2, 2])
    tiny = 1e-14 * scale
    d0 = b[0, 0]
    if not d0 > tiny:
        return False
    l00 = np.sqrt(d0)
    l10 = b[1, 0] / l00
    l20 = b[2, 0] / l00
    d1 = b[1, 1] - l10 * l10
    if not d1 > tiny:
        return False
    l11 = np.sqrt(d1)
    l21 = (b[2, 1] - l20 * l10) / l11
    d2 = b[2, 2] - l20 * l20 - l21 * l21
    if not d2 > tiny:
        return False
    out[0, 0] = l00
    out[1, 0] = l10
    out[2, 0] = l20
    out[1, 1] = l11
    out[2, 1] = l21
    out[2, 2] = np.sqrt(d2)
    out[0, 1] = 0.0
    out[0, 2] = 0.0
    out[1, 2] = 0.0
    return True


@njit(**KERNEL)
def chol3_inverse(lo, out):
    """out = (L L^T)^{-1} from the Cholesky factor L (symmetric result).

    The kernels solve with the same 3x3 matrix for many right-hand sides;
    a matrix-vector product with the inverse avoids chains of divisions."""
    i00 = 1.0 / lo[0, 0]
    i11 = 1.0 / lo[1, 1]
    i22 = 1.0 / lo[2, 2]
    m10 = -lo[1, 0] * i00 * i11
    m21 = -lo[2, 1] * i11 * i22
    m20 = -(lo[2, 0] * i00 + lo[2, 1] * m10) * i22
    # (L L^T)^{-1} = L^{-T} L^{-1}, L^{-1} = [[i00, 0, 0], [m10, i11, 0], [m20, m21, i22]]
    out[0, 0] = i00 * i00 + m10 * m10 + m20 * m20
    out[1, 1] = i11 * i11 + m21 * m21
    out[2, 2] = i22 * i22
    out[0, 1] = out[1, 0] = m10 * i11 + m20 * m21
    out[0, 2] = out[2, 0] = m20 * i22
    out[1, 2] = out[2, 1] = m21 * i22


@njit(**KERNEL, inline="always")
def mm3(a, b, out):
    """out = a b for 3x3 matrices (out must not alias a or b)."""
    for i in range(3):
        for j in range(3):
            out[i, j] = a[i, 0] * b[0, j] + a[i, 1] * b[1, j] + a[i, 2] * b[2, j]


@njit(**KERNEL, inline="always")
def mv3(a, x, out):
    """out = a x for a 3x3 matrix (x may alias out)."""
    x0, x1, x2 = x[0], x[1], x[2]
    out[0] = a[0, 0] * x0 + a[0, 1] * x1 + a[0, 2] * x2
    out[1] = a[1, 0] * x0 + a[1, 1] * x1 + a[1, 2] * x2
    out[2] = a[2, 0] * x0 + a[2, 1] * x1 + a[2, 2] * x2


@njit(**KERNEL)
def chol3_solve(lo, rhs, out):
    """Solve (L L^T) x = rhs for one right-hand side (rhs may alias out)."""
    z0 = rhs[0] / lo[0, 0]
    z1 = (rhs[1] - lo[1, 0] * z0) / lo[1, 1]
    z2 = (rhs[2] - lo[2, 0] * z0 - lo[2, 1] * z1) / lo[2, 2]
    x2 = z2 / lo[2, 2]
    x1 = (z1 - lo[2, 1] * x2) / lo[1, 1]
    x0 = (z0 - lo[1, 0] * x1 - lo[2, 0] * x2) / lo[0, 0]
    out[0] = x0
    out[1] = x1
    out[2] = x2
