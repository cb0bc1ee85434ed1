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

``KIND_SVK``: Saint Venant-Kirchhoff, ``W = lambda/2 (tr E)^2 + mu E:E`` with
``E = (A^T A - I)/2``, in closed form (the same W as the invariant form
psi(I1, I2), at a fraction of the cost: no I2 algebra).  With the isotropic
elasticity C4[X, Y] = lambda tr X tr Y + 2 mu X:Y, S = C4[E] and
dE[a] = sym(A^T a), d2E[a, b] = sym(a^T b):

    D2W[a, b]       = S:(a^T b) + C4[sym(A^T a), sym(A^T b)]
    D3W[a, b, c]    = sum over the 3 splits {a, b | c}: C4[sym(a^T b), sym(A^T c)]
    D4W[a, b, c, d] = sum over the 3 splits {a, b | c, d}: C4[sym(a^T b), sym(c^T d)]

As bilinear forms in (a, b) every term is a block delta_ik S'[J, L] (a_iJ b_kL)
or a pair C4[sym(a^T x), sym(b^T y)] = lam x_iJ y_kL + mu (delta_JL (x y^T)_ik
+ x_iL y_kJ), see _svk_combination.

State layout
------------
One evaluation lives in three arrays ``(mv, mm, mp)`` (few arguments keep
Numba calls cheap): ``mv`` rows are 9-vectors (V_*), ``mm`` the 9x9 matrices
(the invariant Hessians Q_a and AA), ``mp`` scalars (S_*).  The active
invariants are (I1, J) (``nk = 2``, when psi does not depend on I2) or
(I1, I2, J) (``nk = 3``); see ``_inv``.  The derivative routines are compiled
once for each ``nk`` (a constant there, so Numba/LLVM unroll the invariant
loops: 1.5-2x faster than a run-time ``nk``).
"""

import numpy as np
from llvmlite import ir
from numba import njit, types
from numba.extending import intrinsic

from . import KERNEL
from .small import fma


KIND_INVARIANT = 0
KIND_LINEAR = 1
KIND_SVK = 2

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


@intrinsic
def _call_psi(typingctx, address, I1, I2, J, par, out):
    """Call the law callback at the integer address (a cfunc of PSI_SIGNATURE,
    materials.Law.psi).  The kernels take the law as an address rather than
    a first-class function: unboxing a function argument costs ~35 us on every
    call of a kernel from Python, more than a small assembly chunk."""
    sig = types.void(types.intp, types.float64, types.float64, types.float64,
                     types.CPointer(types.float64), types.CPointer(types.float64))

    def codegen(context, builder, signature, args):
        d = ir.DoubleType()
        fnty = ir.FunctionType(ir.VoidType(), [d, d, d, d.as_pointer(), d.as_pointer()])
        fn = builder.inttoptr(args[0], fnty.as_pointer())
        builder.call(fn, args[1:])
        return context.get_dummy_value()
    return sig, codegen



# rows of mv
V_A, V_C, V_P, V_G1 = 0, 1, 2, 3          # A, C = A^T A, P = dW/dA, D I1 = 2A
V_G = 4                                    # 3 rows: D I_a (active order)
V_QC, V_QD, V_RCD, V_U, V_RD = 7, 10, 13, 16, 19   # 3 rows each (work)
V_ZS, V_QS = 22, 34                        # 4 pairs x 3 rows (work)
V_PC, V_PD = 46, 47                        # one pair (mat_d4)
V_S = 48                                   # KIND_SVK: S = lam tr E I + 2 mu E
N_VROW = 49
M_AA = 3                                   # mm[0:3] = Q_a, mm[3] = AA
# entries of mp
S_W, S_I1, S_I2, S_J, S_NK, S_KIND = 0, 1, 2, 3, 4, 5
S_PSI = 8
S_P1 = S_PSI + N_PSI                       # p1[a], p2[a,b], p3, p4: psi derivatives
S_P2 = S_P1 + 3                            # on the active invariants
S_P3 = S_P2 + 9
S_P4 = S_P3 + 27
S_GC = S_P4 + 81                           # work: gam_c, gam_d, sigma, alpha (3 each)
S_GD = S_GC + 3
S_SIG = S_GD + 3
S_AL = S_SIG + 3
S_WT = S_AL + 3                            # one pair weight (mat_d4)
S_LAM, S_MU = S_WT + 1, S_WT + 2           # KIND_SVK: Lame constants
N_SCAL = S_WT + 3


@njit(cache=True)
def new_state():
    """Arrays holding one material evaluation (see mat_prepare)."""
    return np.zeros((N_VROW, 9)), np.zeros((4, 9, 9)), np.zeros(N_SCAL)


# ---------------------------------------------------------------------------
# multilinear forms of the invariants
# ---------------------------------------------------------------------------

@njit(**KERNEL, inline="always")
def _add_eps(c, coef, out):
    """out += coef * D3J[., ., c] (the mixed determinant, constant in A)."""
    for n in range(_EPS_SIGN.shape[0]):
        out[_EPS_IDX[n, 0], _EPS_IDX[n, 1]] += coef * _EPS_SIGN[n] * c[_EPS_IDX[n, 2]]


@njit(**KERNEL, inline="always")
def _add_eps_vec(c, d, coef, out):
    """out += coef * D3J[., c, d] as a 9-vector."""
    for n in range(_EPS_SIGN.shape[0]):
        out[_EPS_IDX[n, 0]] += coef * _EPS_SIGN[n] * c[_EPS_IDX[n, 2]] * d[_EPS_IDX[n, 1]]


@njit(**KERNEL, inline="always")
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


@njit(**KERNEL, inline="always")
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


@njit(**KERNEL, inline="always")
def _add_R(inv, A9, g1, c, out):
    """out += D3 I[., ., c] for invariant id inv (linear in c; zero for I1)."""
    if inv == 2:
        _add_eps(c, 1.0, out)
    elif inv == 1:
        # D3 I2[., ., c] = 2 (g1.c) Id + 2 c g1^T + 2 g1 c^T - D3(tr C^2)[., ., c]/2
        gc = 0.0
        for p in range(9):
            gc += g1[p] * c[p]
        for p in range(9):
            out[p, p] += 2.0 * gc
            for q in range(9):
                out[p, q] += 2.0 * (c[p] * g1[q] + g1[p] * c[q])
        _add_s4(c, A9, -0.5, out)


@njit(**KERNEL, inline="always")
def _R_vec(inv, A9, g1, c, d, out):
    """out = D3 I[., c, d] (9-vector) for invariant id inv."""
    for p in range(9):
        out[p] = 0.0
    if inv == 2:
        _add_eps_vec(c, d, 1.0, out)
    elif inv == 1:
        gc = 0.0
        gd = 0.0
        cd = 0.0
        for p in range(9):
            gc += g1[p] * c[p]
            gd += g1[p] * d[p]
            cd += c[p] * d[p]
        for p in range(9):
            out[p] += 2.0 * (gc * d[p] + cd * g1[p] + gd * c[p])
        _add_s4_vec(c, A9, d, -0.5, out)


@njit(**KERNEL, inline="always")
def _add_S(inv, c, d, coef, out):
    """out += coef * D4 I[., ., c, d] (only I2 has a non-zero one)."""
    if inv != 1 or coef == 0.0:
        return
    cd = 0.0
    for p in range(9):
        cd += c[p] * d[p]
    for p in range(9):
        out[p, p] += 4.0 * coef * cd
        for q in range(9):
            out[p, q] += 4.0 * coef * (c[p] * d[q] + d[p] * c[q])
    _add_s4(c, d, -0.5 * coef, out)


@njit(**KERNEL, inline="always")
def _inv(nk, a):
    """Invariant id (0: I1, 1: I2, 2: J) of the a-th active invariant."""
    return a if nk == 3 else 2 * a


@njit(**KERNEL, inline="always")
def _forms(nk, mv, mm, c, qc, gc):
    """q_a = Q_a c and gam_a = g_a . c for the active invariants (Q_I1 = 2 Id)."""
    for a in range(nk):
        s = 0.0
        for p in range(9):
            s = fma(mv[V_G + a, p], c[p], s)
        gc[a] = s
    for p in range(9):
        qc[0, p] = 2.0 * c[p]
    for a in range(1, nk):
        Q = mm[a]
        for p in range(9):
            t = 0.0
            for q in range(9):
                t = fma(Q[p, q], c[q], t)
            qc[a, p] = t


# ---------------------------------------------------------------------------
# public entry points
# ---------------------------------------------------------------------------

@njit(**KERNEL)
def mat_prepare(kind, psi, params, A, mv, mm, mp):
    """Evaluate W, P and AA at A (3x3) into the state (mv, mm, mp).

    Returns 0, or 1 when det A <= 0 (inverted element), or 2 when the law
    returned a non-finite value.
    """
    A9 = mv[V_A]
    for i in range(3):
        for j in range(3):
            A9[3 * i + j] = A[i, j]
    gJ = mv[V_G + 2]             # provisional row for the cofactor
    gJ[0] = A[1, 1] * A[2, 2] - A[1, 2] * A[2, 1]
    gJ[1] = A[1, 2] * A[2, 0] - A[1, 0] * A[2, 2]
    gJ[2] = A[1, 0] * A[2, 1] - A[1, 1] * A[2, 0]
    gJ[3] = A[0, 2] * A[2, 1] - A[0, 1] * A[2, 2]
    gJ[4] = A[0, 0] * A[2, 2] - A[0, 2] * A[2, 0]
    gJ[5] = A[0, 1] * A[2, 0] - A[0, 0] * A[2, 1]
    gJ[6] = A[0, 1] * A[1, 2] - A[0, 2] * A[1, 1]
    gJ[7] = A[0, 2] * A[1, 0] - A[0, 0] * A[1, 2]
    gJ[8] = A[0, 0] * A[1, 1] - A[0, 1] * A[1, 0]
    J = A[0, 0] * gJ[0] + A[0, 1] * gJ[1] + A[0, 2] * gJ[2]
    mp[S_J] = J
    mp[S_KIND] = kind
    if not J > 0.0:
        return 1
    P = mv[V_P]
    AA = mm[M_AA]
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
        mp[S_W] = W
        mp[S_NK] = 0
        for p in range(9):
            for q in range(9):
                AA[p, q] = 0.0
        for i in range(3):
            for j in range(3):
                AA[4 * i, 4 * j] += lam
                AA[3 * i + j, 3 * i + j] += mu
                AA[3 * i + j, 3 * j + i] += mu
        return 0
    if kind == KIND_SVK:
        lam = params[0]
        mu = params[1]
        mp[S_LAM] = lam
        mp[S_MU] = mu
        mp[S_NK] = 0
        S = mv[V_S]
        trE = 0.0
        EE = 0.0
        for J in range(3):
            for L in range(3):
                e = 0.5 * (A[0, J] * A[0, L] + A[1, J] * A[1, L] + A[2, J] * A[2, L]
                           - (1.0 if J == L else 0.0))
                S[3 * J + L] = 2.0 * mu * e
                EE += e * e
                if J == L:
                    trE += e
        for J in range(3):
            S[4 * J] += lam * trE
        mp[S_W] = 0.5 * lam * trE * trE + mu * EE
        for i in range(3):
            for J in range(3):
                P[3 * i + J] = A[i, 0] * S[J] + A[i, 1] * S[3 + J] + A[i, 2] * S[6 + J]
        _svk_combination(mv, mp, 1.0, A9[0:0], mv[0:0], mv[0:0], mp[0:0], AA)
        return 0
    Cm = mv[V_C]
    I1 = 0.0
    for i in range(3):
        for j in range(3):
            s = 0.0
            for k in range(3):
                s += A[k, i] * A[k, j]
            Cm[3 * i + j] = s
        I1 += Cm[4 * i]
    trC2 = 0.0
    for p in range(9):
        trC2 += Cm[p] * Cm[p]
    I2 = 0.5 * (I1 * I1 - trC2)
    mp[S_I1] = I1
    mp[S_I2] = I2
    ps = mp[S_PSI:S_PSI + N_PSI]
    _call_psi(psi, I1, I2, J, _ptr(params), _ptr(mp[S_PSI:]))
    use2 = False
    for n in range(N_PSI):
        if not np.isfinite(ps[n]):
            return 2
        if n > 0 and ps[n] != 0.0 and _HAS_I2[n]:
            use2 = True
    nk = 3 if use2 else 2
    mp[S_NK] = nk
    mp[S_W] = ps[0]
    for a in range(nk):
        mp[S_P1 + a] = ps[1 + _inv(nk, a)]
        for b in range(nk):
            mp[S_P2 + 3 * a + b] = ps[_I2[_inv(nk, a), _inv(nk, b)]]
            for c in range(nk):
                mp[S_P3 + 9 * a + 3 * b + c] = ps[_I3[_inv(nk, a), _inv(nk, b), _inv(nk, c)]]
                for d in range(nk):
                    mp[S_P4 + 27 * a + 9 * b + 3 * c + d] = ps[_I4[_inv(nk, a), _inv(nk, b), _inv(nk, c), _inv(nk, d)]]
    # first and second derivatives of the invariants (active order)
    g1 = mv[V_G1]
    jJ = nk - 1
    for p in range(9):
        g1[p] = 2.0 * A9[p]
        mv[V_G, p] = g1[p]
        mv[V_G + jJ, p] = gJ[p]
    QJ = mm[jJ]
    for p in range(9):
        for q in range(9):
            QJ[p, q] = 0.0
    _add_eps(A9, 1.0, QJ)
    if use2:
        # I2 = (I1^2 - tr C^2)/2: D I2 = I1 D I1 - 2 A C ; D2 I2 = g1 g1^T + 2 I1 Id - D2(tr C^2)/2
        Q2 = mm[1]
        for i in range(3):
            for L in range(3):
                acl = 0.0
                for K in range(3):
                    acl += A[i, K] * Cm[3 * K + L]
                mv[V_G + 1, 3 * i + L] = I1 * g1[3 * i + L] - 2.0 * acl
        for p in range(9):
            for q in range(9):
                Q2[p, q] = g1[p] * g1[q]
            Q2[p, p] += 2.0 * I1
        _add_s4(A9, A9, -0.25, Q2)
    for p in range(9):
        s = 0.0
        for a in range(nk):
            s += mp[S_P1 + a] * mv[V_G + a, p]
        P[p] = s
    mat_combination(mv, mm, mp, 1.0, A9[0:0], mv[0:0], mv[0:0], mp[0:0], AA)
    return 0


@njit(**KERNEL)
def mat_combination(mv, mm, mp, cAA, c3, C, Dd, wts, out):
    """out = cAA AA + D3W[., ., c3] (if c3 is not empty) + sum_p wts[p] D4W[., ., C[p], Dd[p]].

    One pass of Faa di Bruno over the active invariants: with the invariant
    forms g_a = D I_a, Q_a = D2 I_a, R_a(c) = D3 I_a[., ., c],
    r_a = D3 I_a[., c, d], S_a = D4 I_a[., ., c, d], gam = g.c, q = Q c,
    sig_a = c.Q_a d and the psi derivatives p1..p4 (symmetric),

      AA      = sum p1_a Q_a + sum p2_ab g_a g_b^T
      D3(c)   = sum p1_a R_a(c) + sum p2_ab [gam_b Q_a + q_a g_b^T + g_b q_a^T]
                + sum p3_abm gam_m g_a g_b^T
      D4(c,d) = sum p4_abmn gc_m gd_n g_a g_b^T
                + sum p3_abm [gc_b gd_m Q_a + gd_m (qc_a g_b^T + g_b qc_a^T)
                              + gc_m (qd_a g_b^T + g_b qd_a^T) + sig_a g_b g_m^T]
                + sum p2_ab [sig_b Q_a + qc_a qd_b^T + qd_a qc_b^T
                             + gd_b R_a(c) + gc_b R_a(d) + r_a g_b^T + g_b r_a^T]
                + sum p1_a S_a(c, d)

    all of the form  sum_a alpha_a Q_a + sum_a (u_a g_a^T + g_a u_a^T)
    + sum_pairs,b (z_b qd_b^T + qd_b z_b^T) + sum_a R_a(Rdir_a) + S terms,
    which are accumulated and written once.
    """
    if mp[S_KIND] == KIND_LINEAR:   # constant tangent: D3 = D4 = 0
        for p in range(9):
            for q in range(9):
                out[p, q] = cAA * mm[M_AA, p, q]
        return
    if mp[S_KIND] == KIND_SVK:
        _svk_combination(mv, mp, cAA, c3, C, Dd, wts, out)
        return
    # nk as a literal: one specialization of _combination per number of invariants
    if mp[S_NK] == 3:
        _combination(3, mv, mm, mp, cAA, c3, C, Dd, wts, out)
    else:
        _combination(2, mv, mm, mp, cAA, c3, C, Dd, wts, out)


@njit(**KERNEL)
def _combination(nk, mv, mm, mp, cAA, c3, C, Dd, wts, out):
    """mat_combination for nk active invariants (a compile-time constant)."""
    with_c3 = c3.shape[0] > 0
    g = mv[V_G:V_G + 3]
    qc, qd, rcd = mv[V_QC:V_QC + 3], mv[V_QD:V_QD + 3], mv[V_RCD:V_RCD + 3]
    u, Rdir = mv[V_U:V_U + 3], mv[V_RD:V_RD + 3]
    gc, gd = mp[S_GC:S_GC + 3], mp[S_GD:S_GD + 3]
    sig, alpha = mp[S_SIG:S_SIG + 3], mp[S_AL:S_AL + 3]
    A9, g1 = mv[V_A], mv[V_G1]
    npair = wts.shape[0]
    for a in range(nk):
        alpha[a] = cAA * mp[S_P1 + a]
        for p in range(9):
            s = 0.0
            for b in range(nk):
                s += mp[S_P2 + 3 * a + b] * g[b, p]
            u[a, p] = 0.5 * cAA * s
            Rdir[a, p] = 0.0
    if with_c3:
        _forms(nk, mv, mm, c3, qc, gc)
        for a in range(nk):
            for b in range(nk):
                p2 = mp[S_P2 + 3 * a + b]
                alpha[a] += p2 * gc[b]
                gab = 0.0
                for m in range(nk):
                    gab += mp[S_P3 + 9 * a + 3 * b + m] * gc[m]
                for p in range(9):
                    u[b, p] += p2 * qc[a, p] + 0.5 * gab * g[a, p]
            p1 = mp[S_P1 + a]
            for p in range(9):
                Rdir[a, p] += p1 * c3[p]
    for pr in range(npair):
        w = wts[pr]
        c = C[pr]
        d = Dd[pr]
        _forms(nk, mv, mm, c, qc, gc)
        _forms(nk, mv, mm, d, qd, gd)
        for a in range(nk):
            s = 0.0
            for p in range(9):
                s += c[p] * qd[a, p]
            sig[a] = s
            _R_vec(_inv(nk, a), A9, g1, c, d, rcd[a])
        for a in range(nk):
            al = 0.0
            bc = 0.0
            bd = 0.0
            for b in range(nk):
                p2 = mp[S_P2 + 3 * a + b]
                al += p2 * sig[b]
                bc += p2 * gd[b]
                bd += p2 * gc[b]
                for m in range(nk):
                    al += mp[S_P3 + 9 * a + 3 * b + m] * gc[b] * gd[m]
            alpha[a] += w * al
            for p in range(9):
                Rdir[a, p] += w * (bc * c[p] + bd * d[p])
            for b in range(nk):
                gab = 0.0          # coefficient of g_a g_b^T: sum p4 gc gd + sum p3 sig
                p3d = 0.0
                p3c = 0.0
                for m in range(nk):
                    p3 = mp[S_P3 + 9 * a + 3 * b + m]
                    gab += p3 * sig[m]
                    p3d += p3 * gd[m]
                    p3c += p3 * gc[m]
                    for n in range(nk):
                        gab += mp[S_P4 + 27 * a + 9 * b + 3 * m + n] * gc[m] * gd[n]
                p2 = mp[S_P2 + 3 * a + b]
                for p in range(9):
                    u[b, p] += w * (0.5 * gab * g[a, p] + p3d * qc[a, p] + p3c * qd[a, p]
                                    + p2 * rcd[a, p])
        # z_b = w sum_a p2_ab qc_a, paired with qd_b
        for b in range(nk):
            zrow = mv[V_ZS + 3 * pr + b]
            qrow = mv[V_QS + 3 * pr + b]
            for p in range(9):
                s = 0.0
                for a in range(nk):
                    s += mp[S_P2 + 3 * a + b] * qc[a, p]
                zrow[p] = w * s
                qrow[p] = qd[b, p]
    for p in range(9):
        for q in range(p, 9):
            s = 0.0
            for a in range(nk):
                s = fma(u[a, p], g[a, q], fma(g[a, p], u[a, q], s))
            for a in range(1, nk):
                s = fma(alpha[a], mm[a, p, q], s)
            for pr in range(npair):
                for b in range(nk):
                    r = 3 * pr + b
                    s = fma(mv[V_ZS + r, p], mv[V_QS + r, q], fma(mv[V_QS + r, p], mv[V_ZS + r, q], s))
            out[p, q] = s
            out[q, p] = s
        out[p, p] += 2.0 * alpha[0]          # Q_I1 = 2 Id
    for a in range(1, nk):
        _add_R(_inv(nk, a), A9, g1, Rdir[a], out)
    for pr in range(npair):
        for a in range(1, nk):
            _add_S(_inv(nk, a), C[pr], Dd[pr], wts[pr] * mp[S_P1 + a], out)


@njit(**KERNEL)
def _svk_combination(mv, mp, cAA, c3, C, Dd, wts, out):
    """mat_combination for KIND_SVK (module docstring).  The pairs (x, y, coef)
    are (A, A, cAA) for AA, (c3, A, 1) and (A, c3, 1) for D3(c3), (c, d, w) and
    (d, c, w) for each D4 term; with Z = sum coef x (x) y (9x9, symmetric) and
    Z1 its part without (A, A):

      out[(i,J), (k,L)] = delta_ik Sb[J, L] + lam Z[iJ, kL] + mu Z[iL, kJ]
                          + mu delta_JL sum_M Z[iM, kM],
      Sb = cAA S + (lam/2) tr(Z1) I + mu sum_i Z1[i., i.]   (the delta_ik terms)."""
    lam, mu = mp[S_LAM], mp[S_MU]
    A9, S = mv[V_A], mv[V_S]
    Z = mv[V_ZS:V_ZS + 9]        # 9 work rows
    Sb = mv[V_QS]
    for p in range(9):
        for q in range(9):
            Z[p, q] = 0.0
    if c3.shape[0] > 0:
        for p in range(9):
            for q in range(9):
                Z[p, q] += fma(c3[p], A9[q], A9[p] * c3[q])
    for pr in range(wts.shape[0]):
        w = wts[pr]
        c = C[pr]
        d = Dd[pr]
        for p in range(9):
            for q in range(9):
                Z[p, q] = fma(w, fma(c[p], d[q], d[p] * c[q]), Z[p, q])
    tr = Z[0, 0] + Z[1, 1] + Z[2, 2] + Z[3, 3] + Z[4, 4] + Z[5, 5] + Z[6, 6] + Z[7, 7] + Z[8, 8]
    for J in range(3):
        for L in range(3):
            Sb[3 * J + L] = (cAA * S[3 * J + L]
                             + mu * (Z[J, L] + Z[3 + J, 3 + L] + Z[6 + J, 6 + L]))
        Sb[4 * J] += 0.5 * lam * tr
    for p in range(9):
        for q in range(9):
            Z[p, q] = fma(cAA * A9[p], A9[q], Z[p, q])
    for i in range(3):
        for k in range(3):
            n = mu * (Z[3 * i, 3 * k] + Z[3 * i + 1, 3 * k + 1] + Z[3 * i + 2, 3 * k + 2])
            for J in range(3):
                for L in range(3):
                    v = fma(lam, Z[3 * i + J, 3 * k + L], mu * Z[3 * i + L, 3 * k + J])
                    if J == L:
                        v += n
                    if i == k:
                        v += Sb[3 * J + L]
                    out[3 * i + J, 3 * k + L] = v


@njit(**KERNEL)
def mat_d3(mv, mm, mp, c, out):
    """out = D3W[., ., c] (9x9). Requires mat_prepare on the same A."""
    mat_combination(mv, mm, mp, 0.0, c, mv[0:0], mv[0:0], mp[0:0], out)


@njit(**KERNEL)
def mat_d4(mv, mm, mp, c, d, coef, out):
    """out = coef * D4W[., ., c, d] (9x9). Requires mat_prepare."""
    for p in range(9):
        mv[V_PC, p] = c[p]
        mv[V_PD, p] = d[p]
    mp[S_WT] = coef
    mat_combination(mv, mm, mp, 0.0, c[0:0], mv[V_PC:V_PC + 1], mv[V_PD:V_PD + 1],
                    mp[S_WT:S_WT + 1], out)


@njit(**KERNEL)
def mat_d3_vec(mv, mm, mp, c, d, out):
    """out = D3W[., c, d] (9-vector):
    sum_a g_a (sum p3_abm gc_b gd_m + sum p2_ab sig_b)
    + sum p2_ab (qc_a gd_b + qd_a gc_b) + sum p1_a r_a."""
    for p in range(9):
        out[p] = 0.0
    if mp[S_KIND] == KIND_LINEAR:
        return
    if mp[S_KIND] == KIND_SVK:
        _svk_d3_vec(mv, mp, c, d, out)
        return
    if mp[S_NK] == 3:          # nk as a literal: one specialization per number of invariants
        _d3_vec(3, mv, mm, mp, c, d, out)
    else:
        _d3_vec(2, mv, mm, mp, c, d, out)


@njit(**KERNEL, inline="always")
def _c4_sym(x, y, lam, mu, out):
    """out = C4[sym(x^T y)] = lam (x:y) I + mu (x^T y + y^T x) (3x3 flattened)."""
    xy = 0.0
    for p in range(9):
        xy = fma(x[p], y[p], xy)
    for J in range(3):
        for L in range(3):
            t = 0.0
            for i in range(3):
                t = fma(x[3 * i + J], y[3 * i + L], fma(y[3 * i + J], x[3 * i + L], t))
            out[3 * J + L] = mu * t
        out[4 * J] += lam * xy


@njit(**KERNEL)
def _svk_d3_vec(mv, mp, c, d, out):
    """mat_d3_vec for KIND_SVK: out = c S_d + d S_c + A S_cd with
    S_x = lam (A:x) I + mu (A^T x + x^T A), S_cd = lam (c:d) I + mu (c^T d + d^T c)."""
    lam, mu = mp[S_LAM], mp[S_MU]
    A9 = mv[V_A]
    Sx = mv[V_QC:V_QC + 3]       # rows: S_c, S_d, S_cd (3x3 flattened)
    _c4_sym(A9, c, lam, mu, Sx[0])
    _c4_sym(A9, d, lam, mu, Sx[1])
    _c4_sym(c, d, lam, mu, Sx[2])
    for i in range(3):
        for J in range(3):
            s = 0.0
            for L in range(3):
                s += (c[3 * i + L] * Sx[1, 3 * L + J] + d[3 * i + L] * Sx[0, 3 * L + J]
                      + A9[3 * i + L] * Sx[2, 3 * L + J])
            out[3 * i + J] = s


@njit(**KERNEL)
def _d3_vec(nk, mv, mm, mp, c, d, out):
    """mat_d3_vec for nk active invariants (a compile-time constant)."""
    g = mv[V_G:V_G + 3]
    qc, qd, rcd = mv[V_QC:V_QC + 3], mv[V_QD:V_QD + 3], mv[V_RCD:V_RCD + 3]
    gc, gd, sig = mp[S_GC:S_GC + 3], mp[S_GD:S_GD + 3], mp[S_SIG:S_SIG + 3]
    _forms(nk, mv, mm, c, qc, gc)
    _forms(nk, mv, mm, d, qd, gd)
    for a in range(nk):
        s = 0.0
        for p in range(9):
            s += c[p] * qd[a, p]
        sig[a] = s
        _R_vec(_inv(nk, a), mv[V_A], mv[V_G1], c, d, rcd[a])
    for a in range(nk):
        coef = 0.0
        for b in range(nk):
            coef += mp[S_P2 + 3 * a + b] * sig[b]
            for m in range(nk):
                coef += mp[S_P3 + 9 * a + 3 * b + m] * gc[b] * gd[m]
        p1 = mp[S_P1 + a]
        for p in range(9):
            s = coef * g[a, p] + p1 * rcd[a, p]
            for b in range(nk):
                s += mp[S_P2 + 3 * a + b] * (qc[a, p] * gd[b] + qd[a, p] * gc[b])
            out[p] += s
