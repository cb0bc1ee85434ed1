"""Material layer of the point kernel: W(A) and its derivatives up to order 4.

Conventions
-----------
``A`` is the elastic deformation (3x3, spatial index first).  Second-order
tensors are flattened row-major, ``p = 3*i + J``, so the tangent
``AA[p, q] = d2W / dA_p dA_q`` is a 9x9 matrix.  The kernel needs, besides
``W``, ``P = dW/dA`` and ``AA``, only contractions of the third and fourth
derivatives with given directions (see kernels/point.py and MODEL.md
section 4):

    D3(c)[p, q]    = D^3 W[e_p, e_q, c]
    D4(c, d)[p, q] = D^4 W[e_p, e_q, c, d]

Two kinds of law exist.

``KIND_INVARIANT``: ``W = psi(I1, I2, J)`` with ``I1 = tr C``,
``I2 = (I1^2 - tr C^2)/2``, ``J = det A``, ``C = A^T A``.  The law supplies the
partial derivatives of ``psi`` up to order 4 through a C callback (see
materials.py); the derivatives of ``W`` follow from Faa di Bruno's formula
with the exact multilinear forms of the three invariants (``I1`` quadratic,
``J`` cubic, ``I2`` quartic in ``A``).

``KIND_LINEAR``: the linear isotropic law of the paper (eq:Ww),
``W = lambda/2 (tr H)^2 + mu |sym H|^2`` with ``H = A - I``: constant tangent,
zero third and fourth derivatives.
"""

import numpy as np
from numba import njit, types
from numba.extending import intrinsic

from .small import cof3

KIND_INVARIANT = 0
KIND_LINEAR = 1

# Signature of a law callback: psi(I1, I2, J, params*, out*) writes the 35
# distinct partial derivatives of psi of order 0..4 in the compact order of
# COMPACT_INDEX (order 0, then 1, 2, 3, 4; index tuples sorted ascending,
# lexicographic within an order).
PSI_SIGNATURE = types.void(types.float64, types.float64, types.float64,
                           types.CPointer(types.float64),
                           types.CPointer(types.float64))


def _compact_tables():
    tuples = [()]
    for order in range(1, 5):
        acc = [()]
        for _ in range(order):
            acc = [t + (k,) for t in acc for k in range(3) if not t or k >= t[-1]]
        tuples += acc
    pos = {t: n for n, t in enumerate(tuples)}
    i2 = np.zeros((3, 3), np.int64)
    i3 = np.zeros((3, 3, 3), np.int64)
    i4 = np.zeros((3, 3, 3, 3), np.int64)
    for k in range(3):
        for l in range(3):
            i2[k, l] = pos[tuple(sorted((k, l)))]
            for m in range(3):
                i3[k, l, m] = pos[tuple(sorted((k, l, m)))]
                for n in range(3):
                    i4[k, l, m, n] = pos[tuple(sorted((k, l, m, n)))]
    return tuples, i2, i3, i4


COMPACT_INDEX, _I2, _I3, _I4 = _compact_tables()
N_PSI = len(COMPACT_INDEX)  # 35


def _eps_table():
    """Non-zero entries of E(c)[(i,L),(j,M)] = sum eps_ijk eps_LMN c[k,N]."""
    eps = np.zeros((3, 3, 3))
    eps[0, 1, 2] = eps[1, 2, 0] = eps[2, 0, 1] = 1.0
    eps[0, 2, 1] = eps[2, 1, 0] = eps[1, 0, 2] = -1.0
    rows = []
    for i in range(3):
        for j in range(3):
            if i == j:
                continue
            k = 3 - i - j
            for L in range(3):
                for M in range(3):
                    if L == M:
                        continue
                    N = 3 - L - M
                    rows.append((3 * i + L, 3 * j + M, 3 * k + N,
                                 eps[i, j, k] * eps[L, M, N]))
    tab = np.array(rows)
    return tab[:, :3].astype(np.int64), tab[:, 3].copy()


_EPS_IDX, _EPS_SIGN = _eps_table()

# compact psi entries that involve I2 (a law not using I2 skips its algebra)
_HAS_I2 = np.array([1 in t for t in COMPACT_INDEX])


@intrinsic
def _ptr(typingctx, arr):
    """Raw data pointer of a contiguous float64 array (for the law callback)."""
    def codegen(context, builder, signature, args):
        ary = context.make_array(signature.args[0])(context, builder, args[0])
        return ary.data
    return types.CPointer(arr.dtype)(arr), codegen


def new_state():
    """Arrays holding one material evaluation (see mat_prepare)."""
    return (np.zeros(8),            # 0 scal: W, I1, I2, J, use_I2, kind
            np.zeros((3, 3)),       # 1 A
            np.zeros((3, 3)),       # 2 C = A^T A
            np.zeros((3, 3)),       # 3 A A^T
            np.zeros((3, 9)),       # 4 gI: first derivatives of invariants
            np.zeros((3, 9, 9)),    # 5 QI: second derivatives of invariants
            np.zeros(N_PSI),        # 6 psi, compact
            np.zeros(9),            # 7 P
            np.zeros((9, 9)),       # 8 AA
            np.zeros((6, 3, 9)),    # 9 vector work (q_c, q_d, r_cd, w, z, -)
            np.zeros((3, 3)),       # 10 cofactor work
            np.zeros((4, 3)))       # 11 scalar work (gamma_c, gamma_d, sigma)


# ---------------------------------------------------------------------------
# multilinear forms of the invariants
# ---------------------------------------------------------------------------

@njit(cache=True)
def _add_eps(c, coef, out):
    """out += coef * D3J[., ., c] (the mixed determinant, constant in A)."""
    for n in range(_EPS_SIGN.shape[0]):
        out[_EPS_IDX[n, 0], _EPS_IDX[n, 1]] += coef * _EPS_SIGN[n] * c[_EPS_IDX[n, 2]]


@njit(cache=True)
def _add_eps_vec(c, d, coef, out):
    """out += coef * D3J[., c, d] as a 9-vector."""
    for n in range(_EPS_SIGN.shape[0]):
        out[_EPS_IDX[n, 0]] += coef * _EPS_SIGN[n] * c[_EPS_IDX[n, 2]] * d[_EPS_IDX[n, 1]]


@njit(cache=True)
def _add_s4(c, d, coef, out):
    """out += coef * D4(tr C^2)[., ., c, d]  (c, d flattened 3x3).

    S[(i,L),(j,M)] = 4 d_LM (c d^T + d c^T)_ij + 4 (c_iM d_jL + d_iM c_jL)
                     + 4 d_ij (c^T d + d^T c)_LM
    With d = A this is D3(tr C^2)[., ., c]; with c = d = A it is twice the
    Hessian of tr C^2.
    """
    f = 4.0 * coef
    for i in range(3):
        for j in range(3):
            cdij = 0.0
            for K in range(3):
                cdij += c[3 * i + K] * d[3 * j + K] + d[3 * i + K] * c[3 * j + K]
            for L in range(3):
                out[3 * i + L, 3 * j + L] += f * cdij
                for M in range(3):
                    out[3 * i + L, 3 * j + M] += f * (c[3 * i + M] * d[3 * j + L]
                                                      + d[3 * i + M] * c[3 * j + L])
    for L in range(3):
        for M in range(3):
            ctd = 0.0
            for k in range(3):
                ctd += c[3 * k + L] * d[3 * k + M] + d[3 * k + L] * c[3 * k + M]
            for i in range(3):
                out[3 * i + L, 3 * i + M] += f * ctd


@njit(cache=True)
def _add_s4_vec(c, d, e, coef, out):
    """out += coef * S4(c, d) e (9-vector), S4 as in _add_s4."""
    f = 4.0 * coef
    for i in range(3):
        for L in range(3):
            acc = 0.0
            for j in range(3):
                cdij = 0.0
                for K in range(3):
                    cdij += c[3 * i + K] * d[3 * j + K] + d[3 * i + K] * c[3 * j + K]
                acc += cdij * e[3 * j + L]
                for M in range(3):
                    acc += (c[3 * i + M] * d[3 * j + L] + d[3 * i + M] * c[3 * j + L]) * e[3 * j + M]
            for M in range(3):
                ctd = 0.0
                for k in range(3):
                    ctd += c[3 * k + L] * d[3 * k + M] + d[3 * k + L] * c[3 * k + M]
                acc += ctd * e[3 * i + M]
            out[3 * i + L] += f * acc


@njit(cache=True)
def _add_R(k, ms, c, coef, out):
    """out += coef * D3 I_k[., ., c]."""
    if coef == 0.0:
        return
    A = ms[1].reshape(9)
    g = ms[4]
    if k == 2:
        _add_eps(c, coef, out)
    elif k == 1:
        # D3 I2[., ., c] = 2 (g1.c) Id + 2 c g1^T + 2 g1 c^T - D3(tr C^2)[., ., c]/2
        gc = 0.0
        for p in range(9):
            gc += g[0, p] * c[p]
        for p in range(9):
            out[p, p] += 2.0 * coef * gc
            for q in range(9):
                out[p, q] += 2.0 * coef * (c[p] * g[0, q] + g[0, p] * c[q])
        _add_s4(c, A, -0.5 * coef, out)


@njit(cache=True)
def _add_R_vec(k, ms, c, d, coef, out):
    """out += coef * D3 I_k[., c, d] (9-vector)."""
    if coef == 0.0:
        return
    A = ms[1].reshape(9)
    g = ms[4]
    if k == 2:
        _add_eps_vec(c, d, coef, out)
    elif k == 1:
        gc = 0.0
        gd = 0.0
        cd = 0.0
        for p in range(9):
            gc += g[0, p] * c[p]
            gd += g[0, p] * d[p]
            cd += c[p] * d[p]
        for p in range(9):
            out[p] += 2.0 * coef * (gc * d[p] + cd * g[0, p] + gd * c[p])
        _add_s4_vec(c, A, d, -0.5 * coef, out)


@njit(cache=True)
def _add_S(k, c, d, coef, out):
    """out += coef * D4 I_k[., ., c, d] (only I2 has a non-zero one)."""
    if k != 1 or coef == 0.0:
        return
    cd = 0.0
    for p in range(9):
        cd += c[p] * d[p]
    for p in range(9):
        out[p, p] += 4.0 * coef * cd
        for q in range(9):
            out[p, q] += 4.0 * coef * (c[p] * d[q] + d[p] * c[q])
    _add_s4(c, d, -0.5 * coef, out)


# ---------------------------------------------------------------------------
# psi derivatives in full (symmetric) index form
# ---------------------------------------------------------------------------

@njit(cache=True, inline="always")
def _p1(ms, k):
    return ms[6][1 + k]


@njit(cache=True, inline="always")
def _p2(ms, k, l):
    return ms[6][_I2[k, l]]


@njit(cache=True, inline="always")
def _p3(ms, k, l, m):
    return ms[6][_I3[k, l, m]]


@njit(cache=True, inline="always")
def _p4(ms, k, l, m, n):
    return ms[6][_I4[k, l, m, n]]


@njit(cache=True, inline="always")
def _nk(ms):
    """Invariants actually used: 3 if the law depends on I2, else I1 and J only."""
    return 3 if ms[0][4] != 0.0 else 2


@njit(cache=True, inline="always")
def _inv(ms, a):
    """Map a loop index 0..nk-1 to the invariant index (skipping I2 if unused)."""
    if ms[0][4] != 0.0:
        return a
    return 0 if a == 0 else 2


# ---------------------------------------------------------------------------
# public entry points
# ---------------------------------------------------------------------------

@njit(cache=True)
def mat_prepare(kind, psi_fn, params, A, ms):
    """Evaluate W, P and AA at A into the state ms.

    Returns 0, or 1 when det A <= 0 (inverted element), or 2 when the law
    returned a non-finite value.
    """
    scal, As, Cm, AAt, g, Q, ps, P, AA = ms[0], ms[1], ms[2], ms[3], ms[4], ms[5], ms[6], ms[7], ms[8]
    cof = ms[10]
    for i in range(3):
        for j in range(3):
            As[i, j] = A[i, j]
    cof3(A, cof)
    J = A[0, 0] * cof[0, 0] + A[0, 1] * cof[0, 1] + A[0, 2] * cof[0, 2]
    scal[3] = J
    scal[5] = kind
    if not J > 0.0:
        return 1
    Af = As.reshape(9)
    if kind == KIND_LINEAR:
        lam = params[0]
        mu = params[1]
        tr = A[0, 0] + A[1, 1] + A[2, 2] - 3.0
        W = 0.5 * lam * tr * tr
        for i in range(3):
            for j in range(3):
                hij = A[i, j] - (1.0 if i == j else 0.0)
                hji = A[j, i] - (1.0 if i == j else 0.0)
                s = 0.5 * (hij + hji)
                W += mu * s * s
                P[3 * i + j] = lam * tr * (1.0 if i == j else 0.0) + mu * (hij + hji)
        scal[0] = W
        for p in range(9):
            for q in range(9):
                AA[p, q] = 0.0
        for i in range(3):
            for j in range(3):
                AA[4 * i, 4 * j] += lam
                AA[3 * i + j, 3 * i + j] += mu
                AA[3 * i + j, 3 * j + i] += mu
        return 0
    # C = A^T A, A A^T, invariants
    I1 = 0.0
    for i in range(3):
        for j in range(3):
            s = 0.0
            t = 0.0
            for k in range(3):
                s += A[k, i] * A[k, j]
                t += A[i, k] * A[j, k]
            Cm[i, j] = s
            AAt[i, j] = t
        I1 += Cm[i, i]
    trC2 = 0.0
    for i in range(3):
        for j in range(3):
            trC2 += Cm[i, j] * Cm[i, j]
    I2 = 0.5 * (I1 * I1 - trC2)
    scal[1] = I1
    scal[2] = I2
    psi_fn(I1, I2, J, _ptr(params), _ptr(ps))
    use2 = 0.0
    for n in range(N_PSI):
        if not np.isfinite(ps[n]):
            return 2
    for n in range(1, N_PSI):
        # any derivative that involves I2 (index 1)?
        if ps[n] != 0.0 and _HAS_I2[n]:
            use2 = 1.0
    scal[4] = use2
    scal[0] = ps[0]
    # first and second derivatives of the invariants
    for p in range(9):
        g[0, p] = 2.0 * Af[p]
        g[2, p] = cof[p // 3, p % 3]
        for q in range(9):
            Q[0, p, q] = 0.0
            Q[1, p, q] = 0.0
            Q[2, p, q] = 0.0
        Q[0, p, p] = 2.0
    _add_eps(Af, 1.0, Q[2])
    if use2 != 0.0:
        # I2 = (I1^2 - tr C^2)/2: D I2 = I1 D I1 - (1/2) 4 A C
        for i in range(3):
            for L in range(3):
                acl = 0.0
                for K in range(3):
                    acl += A[i, K] * Cm[K, L]
                g[1, 3 * i + L] = I1 * g[0, 3 * i + L] - 2.0 * acl
        for p in range(9):
            Q[1, p, p] += 2.0 * I1
            for q in range(9):
                Q[1, p, q] += g[0, p] * g[0, q]
        _add_s4(Af, Af, -0.25, Q[1])
    # P = sum psi_k g_k ; AA = sum psi_k Q_k + sum psi_kl g_k g_l^T
    nk = _nk(ms)
    for p in range(9):
        s = 0.0
        for a in range(nk):
            k = _inv(ms, a)
            s += _p1(ms, k) * g[k, p]
        P[p] = s
    for p in range(9):
        for q in range(9):
            s = 0.0
            for a in range(nk):
                k = _inv(ms, a)
                s += _p1(ms, k) * Q[k, p, q]
                for b in range(nk):
                    l = _inv(ms, b)
                    s += _p2(ms, k, l) * g[k, p] * g[l, q]
            AA[p, q] = s
    return 0


@njit(cache=True)
def _rank2_sym(u, v, coef, out):
    """out += coef * (u v^T + v u^T)."""
    for p in range(9):
        cu = coef * u[p]
        cv = coef * v[p]
        for q in range(9):
            out[p, q] += cu * v[q] + cv * u[q]


@njit(cache=True)
def mat_d3(ms, c, out):
    """out = D^3 W[., ., c] (9x9). Requires mat_prepare on the same A."""
    for p in range(9):
        for q in range(9):
            out[p, q] = 0.0
    if ms[0][5] == KIND_LINEAR:
        return
    g, Q = ms[4], ms[5]
    qc = ms[9][0]
    w = ms[9][3]
    nk = _nk(ms)
    gam = ms[11][0]
    for a in range(nk):
        k = _inv(ms, a)
        s = 0.0
        for p in range(9):
            s += g[k, p] * c[p]
            t = 0.0
            for q in range(9):
                t += Q[k, p, q] * c[q]
            qc[k, p] = t
        gam[k] = s
    for a in range(nk):
        k = _inv(ms, a)
        # sum_k psi_k R_k(c)
        _add_R(k, ms, c, _p1(ms, k), out)
        # alpha_k Q_k, alpha_k = sum_l psi_kl gamma_l
        alpha = 0.0
        for b in range(nk):
            alpha += _p2(ms, k, _inv(ms, b)) * gam[_inv(ms, b)]
        if alpha != 0.0:
            for p in range(9):
                for q in range(9):
                    out[p, q] += alpha * Q[k, p, q]
    for b in range(nk):
        l = _inv(ms, b)
        # w_l = sum_k psi_kl q_k
        nz = False
        for p in range(9):
            s = 0.0
            for a in range(nk):
                k = _inv(ms, a)
                s += _p2(ms, k, l) * qc[k, p]
            w[l, p] = s
            nz = nz or s != 0.0
        if nz:
            _rank2_sym(w[l], g[l], 1.0, out)
        for a in range(b, nk):
            k = _inv(ms, a)
            gkl = 0.0
            for e in range(nk):
                m = _inv(ms, e)
                gkl += _p3(ms, k, l, m) * gam[m]
            if gkl != 0.0:
                _rank2_sym(g[k], g[l], gkl if k != l else 0.5 * gkl, out)


@njit(cache=True)
def mat_d4(ms, c, d, coef, out):
    """out += coef * D^4 W[., ., c, d] (9x9). Requires mat_prepare."""
    if ms[0][5] == KIND_LINEAR or coef == 0.0:
        return
    g, Q = ms[4], ms[5]
    qc, qd, rcd, w, z = ms[9][0], ms[9][1], ms[9][2], ms[9][3], ms[9][4]
    nk = _nk(ms)
    gc, gd, sig = ms[11][0], ms[11][1], ms[11][2]
    for a in range(nk):
        k = _inv(ms, a)
        sc = 0.0
        sd = 0.0
        ss = 0.0
        for p in range(9):
            sc += g[k, p] * c[p]
            sd += g[k, p] * d[p]
            tc = 0.0
            td = 0.0
            for q in range(9):
                tc += Q[k, p, q] * c[q]
                td += Q[k, p, q] * d[q]
            qc[k, p] = tc
            qd[k, p] = td
            ss += c[p] * td
            rcd[k, p] = 0.0
        gc[k] = sc
        gd[k] = sd
        sig[k] = ss
        _add_R_vec(k, ms, c, d, 1.0, rcd[k])
    for a in range(nk):
        k = _inv(ms, a)
        # psi_k S_k(c, d)
        _add_S(k, c, d, coef * _p1(ms, k), out)
        # beta^c_k R_k(c) + beta^d_k R_k(d)
        bc = 0.0
        bd = 0.0
        alpha = 0.0
        for b in range(nk):
            l = _inv(ms, b)
            bc += _p2(ms, k, l) * gd[l]
            bd += _p2(ms, k, l) * gc[l]
            alpha += _p2(ms, k, l) * sig[l]
            for e in range(nk):
                m = _inv(ms, e)
                alpha += _p3(ms, k, l, m) * gc[l] * gd[m]
        _add_R(k, ms, c, coef * bc, out)
        _add_R(k, ms, d, coef * bd, out)
        if alpha != 0.0:
            for p in range(9):
                for q in range(9):
                    out[p, q] += coef * alpha * Q[k, p, q]
    for b in range(nk):
        l = _inv(ms, b)
        nzw = False
        nzz = False
        for p in range(9):
            sw = 0.0
            sz = 0.0
            for a in range(nk):
                k = _inv(ms, a)
                p3d = 0.0
                p3c = 0.0
                for e in range(nk):
                    m = _inv(ms, e)
                    p3d += _p3(ms, k, l, m) * gd[m]
                    p3c += _p3(ms, k, l, m) * gc[m]
                pkl = _p2(ms, k, l)
                sw += p3d * qc[k, p] + p3c * qd[k, p] + pkl * rcd[k, p]
                sz += pkl * qc[k, p]
            w[l, p] = sw
            z[l, p] = sz
            nzw = nzw or sw != 0.0
            nzz = nzz or sz != 0.0
        if nzw:
            _rank2_sym(w[l], g[l], coef, out)
        if nzz:
            _rank2_sym(z[l], qd[l], coef, out)
        for a in range(b, nk):
            k = _inv(ms, a)
            gam = 0.0
            for e in range(nk):
                m = _inv(ms, e)
                gam += _p3(ms, k, l, m) * sig[m]
                for f in range(nk):
                    n = _inv(ms, f)
                    gam += _p4(ms, k, l, m, n) * gc[m] * gd[n]
            if gam != 0.0:
                _rank2_sym(g[k], g[l], coef * gam if k != l else 0.5 * coef * gam, out)
