"""Numba assembly of the DKT shell energy, gradient and Hessian.

The elements are coloured once per mesh so that two elements of one colour
share no node; colour by colour, the elements of a colour run in parallel
(chunks on threads, kernels/parallel.py, one scratch per chunk) and add
their gradient and Hessian straight into the global arrays without races:
no per-element matrices are stored.  The Hessian is the lower triangle of
the free DOFs in a CSR pattern built once per mesh and constraint set; the
data position of an entry comes from the compact map ``hmap`` of
hessian_pattern (add_block: a few integers per node and nine per
element, where a table of the 378 entries of every element took 1.5 GB at
1M triangles).  Global DOFs of node n: U[n, s, c],
s = 0 position, 1 and 2 the derivatives along T_n1, T_n2; local DOF
9 i + 3 s + c for the element's node i.
"""

import numpy as np
from numba import njit

from ..discretize.dkt import THIN_HEIGHT, apply_map, element_chart, gather_element, point_map
from ..discretize.regge import (BLEND, MAX_POINTS, N_DATA, N_JET, N_REGGE, N_SLOTS,
                                add_data_hessian, data_forms, data_gradients, data_values,
                                match_reference, metric_coefficients, tangent_curvature,
                                tangent_map, tangent_vectors)
from . import KERNEL
from .parallel import run_chunks
from .point import ERR_INVERTED, OK, STATUS_TEXT, _reference_geometry, new_scratch, point_kernel
from .small import fma

ERR_METRIC = 100        # element-level status (the point kernel's are below)
ELEMENT_STATUS_TEXT = dict(STATUS_TEXT)
ELEMENT_STATUS_TEXT[ERR_METRIC] = ("assumed membrane metric not positive definite "
                                   "(discretize/regge.py)")


@njit(cache=True)
def _element_work():
    return (np.zeros((3, 3)), np.zeros((3, 3, 2)), np.zeros((3, 2, 2)), np.zeros((3, 2)),
            np.zeros((3, 2)), np.zeros(3), np.zeros((5, 9)), np.zeros((2, 9)),
            np.zeros((9, 3)), np.zeros((9, 3)), np.zeros(15), np.zeros(15),
            np.zeros((3, 3)), np.zeros((3, 3)), np.zeros((2, 3, 3)), np.zeros(3), np.zeros(3),
            np.zeros((2, 3)), np.zeros(15), np.zeros((15, 15)), np.zeros((15, 27)),
            np.zeros((3, 3)), np.zeros((2, 3)), np.zeros((2, 2, 3)), np.zeros((2, 3)),
            np.zeros((3, 3)), np.zeros((2, 3)))


@njit(cache=True)
def _regge_work():
    """Work arrays of the assumed membrane metric (discretize/regge.py)."""
    return (np.zeros((N_DATA, 9, 9)), np.zeros((N_DATA, 27)),              # 0 data forms, 1 their gradients
            np.zeros((MAX_POINTS, 3, N_DATA)), np.zeros((N_REGGE, 2 * N_REGGE)),  # 2 alpha, 3 work
            np.zeros((3, 2)), np.zeros((9, 9)),                             # 4, 5 work
            np.zeros(N_DATA), np.zeros(N_DATA),                             # 6, 7 data of U, U_ref
            np.zeros(N_SLOTS), np.zeros((N_SLOTS, N_JET)),                  # 8, 9 jets
            np.zeros((N_SLOTS, N_JET, N_JET)),                              # 10 jets
            np.zeros(N_JET), np.zeros(6), np.zeros((6, N_JET)),             # 11 x, 12 rhat, 13 J
            np.zeros((N_JET, N_JET)), np.zeros((3, N_JET)), np.zeros(15),   # 14 H9, 15 phi, 16 vhat
            np.zeros((15, N_JET)), np.zeros((15, 3)), np.zeros((3, 3)),     # 17 HJ, 18 H_zA, 19 H_AA
            np.zeros((3, 27)), np.zeros((3, 27)), np.zeros(3),              # 20 dChat, 21 work, 22 sA
            np.zeros(6), np.zeros((27, 3)),                                 # 23 g6, 24 work
            np.zeros((2, 9)), np.zeros(3), np.zeros(N_DATA))                # 25, 26 work, 27 gamma


@njit(**KERNEL)
def _point_data(e, iq, bary, wts, area, Q, gl, et, el, b, C, bref, bcur, ref, v, tri, h, G0n,
                G1n, qp, qm, has_load, G0, G1, dG0, qb, m, dm, gE, gLam, gdg, gna, gkap, gup):
    """Quadrature point iq of element e: its map b, reference and current
    vectors ref, v, the growth G0, G1 and dG0/dtheta, the load resultants qb,
    m, dm (MODEL.md eq:qm); returns the weight (rule weight x area x jacobian)."""
    n0, n1, n2 = tri[e, 0], tri[e, 1], tri[e, 2]
    lam = bary[iq]
    point_map(lam, Q, gl, et, el, b, C)
    apply_map(b, bref, ref)
    apply_map(b, bcur, v)
    jx = ref[1] * ref[5] - ref[2] * ref[4]
    jy = ref[2] * ref[3] - ref[0] * ref[5]
    jz = ref[0] * ref[4] - ref[1] * ref[3]
    for r in range(3):
        for c in range(3):
            G0[r, c] = lam[0] * G0n[n0, r, c] + lam[1] * G0n[n1, r, c] + lam[2] * G0n[n2, r, c]
            G1[r, c] = lam[0] * G1n[n0, r, c] + lam[1] * G1n[n1, r, c] + lam[2] * G1n[n2, r, c]
            for a in range(2):
                dG0[a, r, c] = (gl[0, a] * G0n[n0, r, c] + gl[1, a] * G0n[n1, r, c]
                                + gl[2, a] * G0n[n2, r, c])
    for c in range(3):
        qb[c] = 0.0
        m[c] = 0.0
        dm[0, c] = 0.0
        dm[1, c] = 0.0
    if has_load:
        H, K, ok = _reference_geometry(ref, gE, gLam, gdg, gna, gkap, gup)
        mup = 1.0 - H * h + 0.25 * K * h * h      # mu(+h/2)
        mum = 1.0 + H * h + 0.25 * K * h * h      # mu(-h/2)
        for c in range(3):
            qpc = lam[0] * qp[n0, c] + lam[1] * qp[n1, c] + lam[2] * qp[n2, c]
            qmc = lam[0] * qm[n0, c] + lam[1] * qm[n1, c] + lam[2] * qm[n2, c]
            qb[c] = (mup * qpc + mum * qmc) / h
            m[c] = 0.5 * (mup * qpc - mum * qmc)
            for a in range(2):
                dqp = gl[0, a] * qp[n0, c] + gl[1, a] * qp[n1, c] + gl[2, a] * qp[n2, c]
                dqm = gl[0, a] * qm[n0, c] + gl[1, a] * qm[n1, c] + gl[2, a] * qm[n2, c]
                dm[a, c] = 0.5 * (mup * dqp - mum * dqm)
    return wts[iq] * area * np.sqrt(jx * jx + jy * jy + jz * jz)


@njit(**KERNEL)
def _add_point(mode, w, b, grad, hess, T15, ge, ke):
    """ge += w (b (x) I3)^T grad, upper triangle of ke += w (b (x) I3)^T hess (b (x) I3)."""
    if mode >= 1:
        for k in range(9):
            for c in range(3):
                s = 0.0
                for a in range(5):
                    s = fma(b[a, k], grad[3 * a + c], s)
                ge[k, c] = fma(w, s, ge[k, c])
    if mode >= 2:
        # T15 = H (b (x) I3): T15[(a,c), (k,c')] = sum_a' H[(a,c),(a',c')] b[a',k]
        for r in range(15):
            for k in range(9):
                for c2 in range(3):
                    s = 0.0
                    for a2 in range(5):
                        s = fma(hess[r, 3 * a2 + c2], b[a2, k], s)
                    T15[r, 3 * k + c2] = s
        for k in range(9):
            for c in range(3):
                row = 3 * k + c
                for col in range(row, 27):
                    s = 0.0
                    for a in range(5):
                        s = fma(b[a, k], T15[3 * a + c, col], s)
                    ke[row, col] = fma(w, s, ke[row, col])


@njit(**KERNEL)
def _element(e, mode, level, kind, psi, params, h, tri, X, T, U, bary, wts, G0n, G1n, qp, qm,
             has_load, pf, zf, Y1, Y2, ge, ke, sc, wk):
    """Energy of element e with the DKT membrane metric; ge (9, 3) and the
    upper triangle of ke (27, 27) if mode asks; pf, zf: follower pressure pf
    on the face Z = zf (point_kernel).  Returns (L, status)."""
    (Xe, Te, Q, gl, et, el, b, C, bref, bcur, ref, v, G0, G1, dG0, qb, m, dm, grad, hess,
     T15, gE, gLam, gdg, gna, gkap, gup) = wk
    gather_element(e, tri, X, T, U, Xe, Te, bref, bcur)
    area = element_chart(Xe, Te, Q, gl, et, el)
    Le = 0.0
    zero_element(mode, ge, ke)
    for iq in range(bary.shape[0]):
        w = _point_data(e, iq, bary, wts, area, Q, gl, et, el, b, C, bref, bcur, ref, v, tri, h,
                        G0n, G1n, qp, qm, has_load, G0, G1, dG0, qb, m, dm, gE, gLam, gdg, gna,
                        gkap, gup)
        L, st = point_kernel(mode, level, kind, psi, params, h, v, ref, G0, G1, dG0, qb, m, dm,
                             Y1[e, iq], Y2[e, iq], grad, hess, sc, pf, zf)
        if st != OK:
            return np.nan, st
        Le += w * L
        _add_point(mode, w, b, grad, hess, T15, ge, ke)
    return Le, OK


@njit(**KERNEL)
def _element_regge(e, mode, level, kind, psi, params, h, tri, X, T, U, bary, wts, G0n, G1n, qp,
                   qm, has_load, pf, zf, Y1, Y2, ge, ke, sc, wk, rw):
    """_element with the assumed membrane metric of discretize/regge.py: the
    point kernel receives tangent vectors with that metric, at each point a
    combination of the data (quadratic forms of the element's nodal
    vectors), and the chain rule runs through them."""
    (Xe, Te, Q, gl, et, el, b, C, bref, bcur, ref, v, G0, G1, dG0, qb, m, dm, grad, hess,
     T15, gE, gLam, gdg, gna, gkap, gup) = wk
    (forms, dD, alpha, Mw, P, gram, D, Dref, jv, jg, jh, x9, rhat, Jf, H9, phi, vhat, HJ, HzA,
     HAA, dC, M3, sA, g6, T3, Bc, lamw, gam) = rw
    gather_element(e, tri, X, T, U, Xe, Te, bref, bcur)
    area = element_chart(Xe, Te, Q, gl, et, el)
    Le = 0.0
    zero_element(mode, ge, ke)
    longest = max(el[0], el[1], el[2])
    beta = min(1.0, BLEND * h / longest)
    if 2.0 * area / longest < THIN_HEIGHT * h:
        # thin against the thickness (discretize/dkt.py): the Regge field R,
        # rebuilt from the edge data of nearly parallel edges, is ill-conditioned
        # there; the conforming field's own metric g is not (README, Membrane locking)
        beta = 1.0
    data_forms(Q, gl, et, el, bary, wts, forms, P, Bc, lamw)
    metric_coefficients(bary, et, beta, alpha, Mw)
    nd = N_REGGE + 3 * bary.shape[0]      # the data in use (regge.data_forms)
    data_values(forms, nd, bref, gram, Dref)
    data_values(forms, nd, bcur, gram, D)
    if mode >= 1:
        data_gradients(forms, nd, bcur, dD)
        for j in range(N_DATA):
            gam[j] = 0.0
    for iq in range(bary.shape[0]):
        w = _point_data(e, iq, bary, wts, area, Q, gl, et, el, b, C, bref, bcur, ref, v, tri, h,
                        G0n, G1n, qp, qm, has_load, G0, G1, dG0, qb, m, dm, gE, gLam, gdg, gna,
                        gkap, gup)
        # x = (r_1, r_2, Chat), Chat = K^T A(U) K = alpha[iq] . D (regge.py)
        if not match_reference(alpha[iq], Dref, ref):
            return np.nan, _metric_failure(bref, bcur)
        for i in range(6):
            x9[i] = v[i]
        for c in range(3):
            s = 0.0
            for j in range(nd):
                s += alpha[iq, c, j] * D[j]
            x9[6 + c] = s
        if not tangent_map(x9, jv, jg, jh, mode):
            return np.nan, _metric_failure(bref, bcur)
        tangent_vectors(x9, jv, jg, rhat, Jf, mode)
        for i in range(15):
            vhat[i] = rhat[i] if i < 6 else v[i]
        L, st = point_kernel(mode, level, kind, psi, params, h, vhat, ref, G0, G1, dG0, qb, m,
                             dm, Y1[e, iq], Y2[e, iq], grad, hess, sc, pf, zf)
        if st != OK:
            return np.nan, st
        Le += w * L
        if mode >= 1:
            _regge_point(mode, w, b, alpha[iq], dD, x9, jv, jg, jh, Jf, grad, hess, g6, H9, phi,
                         HJ, HzA, HAA, dC, M3, sA, T3, gam, ke)
        _add_point(mode, w, b, grad, hess, T15, ge, ke)
    if mode >= 1:
        for k in range(9):
            for comp in range(3):
                v2 = 0.0
                for j in range(nd):
                    v2 += gam[j] * dD[j, 3 * k + comp]
                ge[k, comp] += v2
    if mode >= 2:
        add_data_hessian(forms, nd, gam, ke)
    return Le, OK


@njit(**KERNEL)
def _metric_failure(bref, bcur):
    """The status of an element whose assumed metric is not positive
    definite: ERR_INVERTED if its facet (the triangle of its nodes'
    positions) has turned over against the reference facet, else ERR_METRIC."""
    s = 0.0
    for m in range(3):
        m1, m2 = (m + 1) % 3, (m + 2) % 3
        nc = ((bcur[3, m1] - bcur[0, m1]) * (bcur[6, m2] - bcur[0, m2])
              - (bcur[3, m2] - bcur[0, m2]) * (bcur[6, m1] - bcur[0, m1]))
        nr = ((bref[3, m1] - bref[0, m1]) * (bref[6, m2] - bref[0, m2])
              - (bref[3, m2] - bref[0, m2]) * (bref[6, m1] - bref[0, m1]))
        s += nc * nr
    return ERR_INVERTED if s <= 0.0 else ERR_METRIC


@njit(**KERNEL)
def _regge_point(mode, w, b, alpha, dD, x, jv, jg, jh, Jf, grad, hess, g6, H9, phi, HJ, HzA, HAA,
                 dC, M3, sA, T3, gam, ke):
    """Chain rule through rhat(r_1, r_2, Chat) at a point: grad, hess (kernel
    derivatives in vhat) become those in (r_1, r_2, r_ab) with Chat fixed (for
    _add_point); the terms through Chat = alpha . D (data D, their gradients
    dD): gam += w sA . alpha (sA = dL/dChat; the element adds gam . dD to
    ge and gam . d2D to ke), and to the upper triangle of ke
        T3 dChat + dChat^T T3^T + w dChat^T HAA dChat,
    dChat (3, 27) = alpha dD, T3 = w (b (x) I3)^T HzA."""
    for i in range(6):
        g6[i] = grad[i]
    # gradient: d/dx = Jf^T g6
    for p in range(N_JET):
        s = 0.0
        for i in range(6):
            s += Jf[i, p] * g6[i]
        if p < 6:
            grad[p] = s
        else:
            sA[p - 6] = s
    for j in range(N_DATA):
        gam[j] += w * (sA[0] * alpha[0, j] + sA[1] * alpha[1, j] + sA[2] * alpha[2, j])
    if mode < 2:
        return
    for c in range(3):
        for q in range(27):
            dC[c, q] = 0.0
        for j in range(N_DATA):
            a = alpha[c, j]
            if a != 0.0:
                for q in range(27):
                    dC[c, q] += a * dD[j, q]
    # HJ = hess[:, 0:6] Jf (15 x 9); H9 = Jf^T HJ[0:6] + d2(g6 . rhat)/dx2
    for r in range(15):
        for p in range(N_JET):
            s = 0.0
            for i in range(6):
                s += hess[r, i] * Jf[i, p]
            HJ[r, p] = s
    tangent_curvature(x, g6, jv, jg, jh, H9, phi)
    for p in range(N_JET):
        for q in range(N_JET):
            s = 0.0
            for i in range(6):
                s += Jf[i, p] * HJ[i, q]
            H9[p, q] += s
    for r in range(15):
        for c in range(3):
            HzA[r, c] = H9[r, 6 + c] if r < 6 else HJ[r, 6 + c]
    for c in range(3):
        for c2 in range(3):
            HAA[c, c2] = H9[6 + c, 6 + c2]
    for p in range(6):
        for q in range(6):
            hess[p, q] = H9[p, q]
        for r in range(6, 15):
            hess[p, r] = HJ[r, p]
            hess[r, p] = HJ[r, p]
    # T3 = w (b (x) I3)^T HzA (27 x 3), M3 = w HAA dChat (3 x 27)
    for k in range(9):
        for comp in range(3):
            for c in range(3):
                s = 0.0
                for a in range(5):
                    s += b[a, k] * HzA[3 * a + comp, c]
                T3[3 * k + comp, c] = w * s
    for c in range(3):
        for q in range(27):
            M3[c, q] = w * (HAA[c, 0] * dC[0, q] + HAA[c, 1] * dC[1, q] + HAA[c, 2] * dC[2, q])
    for p in range(27):
        for q in range(p, 27):
            s = 0.0
            for c in range(3):
                s += T3[p, c] * dC[c, q] + dC[c, p] * (T3[q, c] + M3[c, q])
            ke[p, q] += s


@njit(cache=True)
def _node_elements(tri, n_nodes):
    """The elements of node n: adj[start[n]:start[n + 1]] (CSR), and the
    largest number of elements at a node."""
    start = np.zeros(n_nodes + 1, np.int64)
    for e in range(tri.shape[0]):
        for i in range(3):
            start[tri[e, i] + 1] += 1
    for n in range(n_nodes):
        start[n + 1] += start[n]
    fill = start[:-1].copy()
    adj = np.empty(start[n_nodes], np.int64)
    for e in range(tri.shape[0]):
        for i in range(3):
            adj[fill[tri[e, i]]] = e
            fill[tri[e, i]] += 1
    valence = 0
    for n in range(n_nodes):
        valence = max(valence, start[n + 1] - start[n])
    return start, adj, valence


@njit(cache=True)
def color_elements(tri, n_nodes):
    """Greedy colouring: colour[e] is the smallest colour not taken by an
    element sharing a node with e (7 to 9 colours on the meshes tested)."""
    ne = tri.shape[0]
    start, adj, valence = _node_elements(tri, n_nodes)
    colour = -np.ones(ne, np.int64)
    taken = -np.ones(3 * valence + 1, np.int64)    # taken[c] == e: c is used next to e
    for e in range(ne):
        for i in range(3):
            nd = tri[e, i]
            for k in range(start[nd], start[nd + 1]):
                c = colour[adj[k]]
                if c >= 0:
                    taken[c] = e
        c = 0
        while taken[c] == e:
            c += 1
        colour[e] = c
    return colour


def assemble_dkt(mode, level, kind, psi, params, h, regge, tri, X, T, U, bary, wts, G0n, G1n,
                 qp, qm, has_load, pf, zf, Y1, Y2, order, colour_start, hmap, Le, G, data,
                 status):
    """Element energies Le (E); for mode >= 1 the gradient G (n, 3, 3), for
    mode >= 2 the Hessian values data (positions: hmap of hessian_pattern), both overwritten.

    order: the elements sorted by colour, colour c being
    order[colour_start[c]:colour_start[c + 1]] (see color_elements); the
    elements of a colour run in parallel (kernels/parallel.py).
    regge: the assumed membrane metric of discretize/regge.py (else the DKT
    one; each is compiled on its first use).
    pf, zf: the points' part of a follower pressure pf on the face Z = zf
    (point_kernel; the volume of the positions is the caller's).
    status[e] = point-kernel status of the first failing point, or ERR_METRIC (0: ok).
    """
    if mode >= 1:
        G[:] = 0.0
    if mode >= 2:
        data[:] = 0.0
    kernel = assemble_elements_regge if regge else assemble_elements
    for c in range(colour_start.shape[0] - 1):
        run_chunks(kernel, colour_start[c], colour_start[c + 1], mode, level, kind, psi, params,
                   h, tri, X, T, U, bary, wts, G0n, G1n, qp, qm, has_load, pf, zf, Y1, Y2,
                   order, hmap, Le, G, data, status)


@njit(cache=True, nogil=True)
def assemble_elements(lo, hi, mode, level, kind, psi, params, h, tri, X, T, U, bary, wts, G0n,
                      G1n, qp, qm, has_load, pf, zf, Y1, Y2, order, hmap, Le, G, data, status):
    """The elements order[lo:hi] (no two sharing a node) into Le, G, data,
    status (see assemble_dkt), DKT metric."""
    sc = new_scratch()
    wk = _element_work()
    ge = np.zeros((9, 3))
    ke = np.zeros((27, 27))
    for j in range(lo, hi):
        e = order[j]
        Le[e], status[e] = _element(e, mode, level, kind, psi, params, h, tri, X, T, U, bary,
                                    wts, G0n, G1n, qp, qm, has_load, pf, zf, Y1, Y2, ge, ke, sc,
                                    wk)
        if status[e] == OK:
            scatter_element(e, mode, tri, ge, ke, hmap, G, data)


@njit(cache=True, nogil=True)
def assemble_elements_regge(lo, hi, mode, level, kind, psi, params, h, tri, X, T, U, bary, wts,
                            G0n, G1n, qp, qm, has_load, pf, zf, Y1, Y2, order, hmap, Le, G, data,
                            status):
    """assemble_elements with the assumed membrane metric (a separate kernel:
    scenes without it do not compile it)."""
    sc = new_scratch()
    wk = _element_work()
    rw = _regge_work()
    ge = np.zeros((9, 3))
    ke = np.zeros((27, 27))
    for j in range(lo, hi):
        e = order[j]
        Le[e], status[e] = _element_regge(e, mode, level, kind, psi, params, h, tri, X, T, U,
                                          bary, wts, G0n, G1n, qp, qm, has_load, pf, zf, Y1, Y2,
                                          ge, ke, sc, wk, rw)
        if status[e] == OK:
            scatter_element(e, mode, tri, ge, ke, hmap, G, data)


@njit(**KERNEL)
def zero_element(mode, ge, ke):
    """Clear the element gradient ge (9, 3) and Hessian ke (27, 27) the mode fills."""
    if mode >= 1:
        for k in range(9):
            for c in range(3):
                ge[k, c] = 0.0
    if mode >= 2:
        for p in range(27):
            for q in range(27):
                ke[p, q] = 0.0


@njit(**KERNEL, inline="always")
def add_block(hmap, ni, nj, off, M, nd, transposed, diag, scale, data):
    """data += scale x the block between DOFs a < nd of node ni and b < nd of
    node nj, whose value is M[b, a] if transposed else M[a, b]; off =
    hmap[3][e, i, j] for an element e with those nodes as its local i, j
    (the column offset of the pair in the rows of the later node;
    hessian_pattern); diag (ni == nj): the entries b <= a only; fixed DOFs
    are skipped.  The row's start is looked up once per row."""
    indptr, fidx, rank = hmap[0], hmap[1], hmap[2]
    if ni >= nj:                            # rows: the DOFs a of ni
        for a in range(nd):
            fr = fidx[ni, a]
            if fr < 0:
                continue
            base = indptr[fr] + off
            for b in range(a + 1 if diag else nd):
                if fidx[nj, b] >= 0:
                    data[base + rank[nj, b]] += scale * (M[b, a] if transposed else M[a, b])
    else:                                   # rows: the DOFs b of nj
        for b in range(nd):
            fr = fidx[nj, b]
            if fr < 0:
                continue
            base = indptr[fr] + off
            for a in range(nd):
                if fidx[ni, a] >= 0:
                    data[base + rank[ni, a]] += scale * (M[b, a] if transposed else M[a, b])


@njit(**KERNEL)
def scatter_element(e, mode, tri, ge, ke, hmap, G, data):
    """Add element e's gradient ge (9, 3) to the nodal gradient G and (mode 2)
    the upper triangle of its Hessian ke (27, 27) to the CSR data (positions:
    hmap of hessian_pattern; fixed DOFs skipped)."""
    if mode >= 1:
        for i in range(3):
            nd = tri[e, i]
            for s in range(3):
                for k in range(3):
                    G[nd, s, k] += ge[3 * i + s, k]
    if mode >= 2:
        eoff = hmap[3]
        for i in range(3):
            for j in range(i + 1):
                # entry (DOF a of node i, DOF b of node j), j <= i: ke[9 j + b, 9 i + a]
                add_block(hmap, tri[e, i], tri[e, j], eoff[e, i, j],
                          ke[9 * j:9 * j + 9, 9 * i:9 * i + 9], 9, True, i == j, 1.0, data)


@njit(**KERNEL)
def add_position_blocks(tri, HV, coef, hmap, data):
    """data += coef HV on the position DOFs; HV[e, i, j] is the (3, 3) block
    between the positions of the element's nodes i and j (symmetric overall)."""
    eoff = hmap[3]
    for e in range(tri.shape[0]):
        for i in range(3):
            for j in range(i + 1):
                add_block(hmap, tri[e, i], tri[e, j], eoff[e, i, j], HV[e, i, j], 3, False, i == j,
                          coef, data)


@njit(cache=True)
def hessian_pattern(tri, free_index):
    """CSR pattern (indptr, indices) of the lower triangle of the Hessian on the
    free DOFs, and the compact map hmap = (indptr, free_index, rank, eoff) of
    add_block: rank[J, l] the free DOFs of node J before its DOF l,
    eoff[e, i, j] the column offset, in the rows of the later of the nodes
    tri[e, i], tri[e, j], of the other node's block.

    free_index (n, 9): free index of DOF k of node n (-1: fixed), increasing in
    (n, k).  Built node by node: row (I, a) holds the free DOFs of the nodes
    J < I that share an element with I, in order, then those of I up to a.
    """
    n = free_index.shape[0]
    ne = tri.shape[0]
    # nbr[nptr[I]:nptr[I + 1]]: nodes J <= I sharing an element with I, sorted
    start, adj, valence = _node_elements(tri, n)
    nptr = np.zeros(n + 1, np.int64)
    nbr = np.empty(3 * start[n], np.int64)
    buf = np.empty(3 * valence, np.int64)
    m = 0
    for I in range(n):
        k = 0
        for s in range(start[I], start[I + 1]):
            for j in range(3):
                J = tri[adj[s], j]
                if J <= I:
                    buf[k] = J
                    k += 1
        for i in range(1, k):               # insertion sort (a few dozen entries)
            v, j = buf[i], i
            while j > 0 and buf[j - 1] > v:
                buf[j] = buf[j - 1]
                j -= 1
            buf[j] = v
        for i in range(k):
            if i == 0 or buf[i] != buf[i - 1]:
                nbr[m] = buf[i]
                m += 1
        nptr[I + 1] = m
    # rank[J, l]: free DOFs of node J before l; offset[s]: columns before slot s
    rank = np.zeros((n, 10), np.int64)
    for J in range(n):
        for l in range(9):
            rank[J, l + 1] = rank[J, l] + (1 if free_index[J, l] >= 0 else 0)
    offset = np.zeros(m + 1, np.int64)
    for I in range(n):
        acc = 0
        for s in range(nptr[I], nptr[I + 1]):
            offset[s] = acc
            acc += rank[nbr[s], 9]
    nf = 0
    for I in range(n):
        nf += rank[I, 9]
    indptr = np.zeros(nf + 1, np.int64)
    for I in range(n):
        own = offset[nptr[I + 1] - 1]           # node I is the last of its list
        for a in range(9):
            r = free_index[I, a]
            if r >= 0:
                indptr[r + 1] = own + rank[I, a] + 1
    for r in range(nf):
        indptr[r + 1] += indptr[r]
    if indptr[nf] >= 2 ** 31 - 1:
        raise ValueError("more Hessian entries than a 32-bit index holds")
    indices = np.empty(indptr[nf], np.int32)
    for I in range(n):
        for a in range(9):
            r = free_index[I, a]
            if r < 0:
                continue
            k = indptr[r]
            for s in range(nptr[I], nptr[I + 1]):
                J = nbr[s]
                top = a + 1 if J == I else 9
                for l in range(top):
                    if free_index[J, l] >= 0:
                        indices[k] = free_index[J, l]
                        k += 1
    eoff = np.empty((ne, 3, 3), np.int32)
    for e in range(ne):
        for i in range(3):
            for j in range(3):
                ni, nj = max(tri[e, i], tri[e, j]), min(tri[e, i], tri[e, j])
                s = nptr[ni]
                while nbr[s] != nj:
                    s += 1
                eoff[e, i, j] = offset[s]
    indptr = indptr.astype(np.int32)                  # int32: scipy's native index type
    return indptr, indices, (indptr, free_index, rank.astype(np.int32), eoff)
