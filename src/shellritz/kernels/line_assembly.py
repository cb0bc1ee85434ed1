"""Numba assembly for the one-dimensional engines (axisymmetric, plane strain).

At every quadrature point q the local variables are an affine function of the
8 DOFs of its element, v = B[q] u_e + c[q] (B: 15 x 8, precomputed); the
point kernel gives L, dL/dv, d2L/dv2 and the point contributes w[q] L,
w[q] B^T dL/dv and w[q] B^T d2L/dv2 B.  Points are independent: parallel chunks.
"""

import numpy as np
from numba import njit

from .parallel import run_chunks
from .point import OK, new_scratch, point_kernel

MIN_CHUNK = 64          # points per parallel chunk, at least


def assemble_line(mode, level, kind, psi, params, h, elem_dofs, qelem, B, c, REF, W, U,
                  G0, G1, dG0, QB, M, DM, pf, zf, Y1, Y2, Lq, Gq, Hq, status):
    """Per-point energy Lq (nq), gradient Gq (nq, 8), Hessian Hq (nq, 8, 8).

    elem_dofs (ne, 8): global DOFs of each element; qelem (nq): element of
    each point; U: global DOF vector; pf, zf: the points' part of a follower
    pressure pf on the face Z = zf (point_kernel).  The points run in
    parallel (kernels/parallel.py).
    """
    run_chunks(assemble_points, 0, qelem.shape[0], mode, level, kind, psi, params, h, elem_dofs,
               qelem, B, c, REF, W, U, G0, G1, dG0, QB, M, DM, pf, zf, Y1, Y2, Lq, Gq, Hq,
               status, min_chunk=MIN_CHUNK)


@njit(cache=True, nogil=True)
def assemble_points(lo, hi, mode, level, kind, psi, params, h, elem_dofs, qelem, B, c, REF, W,
                    U, G0, G1, dG0, QB, M, DM, pf, zf, Y1, Y2, Lq, Gq, Hq, status):
    """The points lo .. hi - 1 of assemble_line."""
    sc = new_scratch()
    v = np.zeros(15)
    grad = np.zeros(15)
    hess = np.zeros((15, 15))
    ue = np.zeros(8)
    T = np.zeros((15, 8))
    for q in range(lo, hi):
        e = qelem[q]
        for k in range(8):
            ue[k] = U[elem_dofs[e, k]]
        for r in range(15):
            s = c[q, r]
            for k in range(8):
                s += B[q, r, k] * ue[k]
            v[r] = s
        L, st = point_kernel(mode, level, kind, psi, params, h, v, REF[q], G0[q], G1[q],
                             dG0[q], QB[q], M[q], DM[q], Y1[q], Y2[q], grad, hess, sc, pf, zf)
        status[q] = st
        if st != OK:
            Lq[q] = np.nan
            continue
        w = W[q]
        Lq[q] = w * L
        if mode >= 1:
            for k in range(8):
                s = 0.0
                for r in range(15):
                    s += B[q, r, k] * grad[r]
                Gq[q, k] = w * s
        if mode >= 2:
            for r in range(15):
                for k in range(8):
                    s = 0.0
                    for r2 in range(15):
                        s += hess[r, r2] * B[q, r2, k]
                    T[r, k] = s
            for k in range(8):
                for l in range(8):
                    s = 0.0
                    for r in range(15):
                        s += B[q, r, k] * T[r, l]
                    Hq[q, k, l] = w * s
