"""Plane-strain 2D solid reference for necking (scikit-fem): the block of
docs/necking.md as a true 2D body.

Geometry and supports: the half block X in [0, l], Z in [0, h/2] (mirror
symmetry u_z = 0 on Z = 0: the symmetric necking modes), shear-free grips
u_x = 0 on X = 0 and u_x = (lam - 1) l on X = l, top face traction free;
plane strain (F_YY = 1).  Q2 quadrilaterals (scikit-fem ElementQuad2 on a
structured MeshQuad, nx along X, nz across the half thickness, 3x3 Gauss),
any shellritz law (evaluated at the quadrature points by the project's
material layer, kernels/material.py).  Unknown: the displacement minus the
lifting (lam - 1) X e_x, so the fixed DOFs are zero and the homogeneous state
is (z1 - 1) Z e_z exactly (Q2 contains it).

* onset: the stretch where the tangent stiffness at the homogeneous state
  (constant moduli) stops being positive definite (LDL^T inertia, the
  shellritz solver's test), bisected; checked against the exact incremental
  solution of the block (``exact_onset``, the separable modes of Hill &
  Hutchinson 1975: u_x = U(Z) sin(pi X / l), u_z = V(Z) cos(pi X / l)).
* post-bifurcation: the path of the block with a thickness imperfection
  (growth G = diag(1, 1, 1 - delta cos(pi X / l)), thinnest at X = 0, the
  same field as the shell engine's ``set_stretch_growth``) by pseudo-arclength
  continuation (``follow``; displacement control stops at the fold where the
  necking snaps back), Newton with line search of bench/fe3d.py for the
  first points.

Run: python bench/necking_2d.py [--quick]   -> bench/results/necking_2d_path.json
(the onset study is bench/necking.py)
"""

import json
import sys
import time
from pathlib import Path

import numpy as np
import scipy.sparse as sp
from numba import njit
from scipy.optimize import brentq
from skfem import CellBasis, ElementQuad2, MeshQuad

HERE = Path(__file__).resolve().parent
RESULTS = HERE / "results"
sys.path.insert(0, str(HERE))

import fe3d  # noqa: E402  (Newton with line search, linear solver)
from machine import machine_info  # noqa: E402
from shellritz.kernels.material import M_AA, S_W, V_P, mat_prepare, new_state  # noqa: E402
from shellritz.necking import considere_stretch, default_law, plane_strain_tension  # noqa: E402
from shellritz.linalg import negative_eigenvalues  # noqa: E402

IN_PLANE = np.array([0, 2])          # X, Z among the 3D axes (Y: out of plane)


@njit(cache=True)
def _law_at_points(kind, psi, params, A, W, P, AA):
    """W, P (9), AA (9x9) of the law at each A[q] (3x3); returns the index of
    the first inadmissible point or -1."""
    mv, mm, mp = new_state()
    for q in range(A.shape[0]):
        if mat_prepare(kind, psi, params, A[q], mv, mm, mp) != 0:
            return q
        W[q] = mp[S_W]
        P[q] = mv[V_P]
        AA[q] = mm[M_AA]
    return -1


class Block:
    """The half block, Q2 quads; global DOF of component i (0: x, 1: z) at node a: 2 a + i."""

    def __init__(self, law, h, length, nx, nz, imperfection=0.0):
        self.law, self.h, self.length = law, h, length
        mesh = MeshQuad.init_tensor(np.linspace(0, length, nx + 1), np.linspace(0, h / 2, nz + 1))
        basis = CellBasis(mesh, ElementQuad2(), intorder=4)
        nb = len(basis.basis)
        self.dN = np.ascontiguousarray(np.array([basis.basis[a][0].grad for a in range(nb)])
                                       .transpose(2, 3, 0, 1))           # (e, q, a, K)
        self.X = basis.doflocs                                            # (2, N)
        self.nodes = basis.element_dofs.T                                 # (e, a)
        self.gdof = (2 * self.nodes[:, :, None] + np.arange(2)).reshape(len(self.nodes), -1)
        self.ndof = 2 * self.X.shape[1]
        Xq = basis.mapping.F(basis.X)                                     # (2, e, q)
        # growth diag(1, 1, gamma(X)): per reference volume det G W(F G^-1)
        self.gamma = 1.0 - imperfection * np.cos(np.pi * Xq[0] / length)
        self.c = np.asarray(basis.dx) * self.gamma                        # weights x det G
        x, z = self.X
        tol = 1e-9 * length
        fixed = np.concatenate([2 * np.nonzero(np.abs(x) < tol)[0],
                                2 * np.nonzero(np.abs(x - length) < tol)[0],
                                2 * np.nonzero(np.abs(z) < tol)[0] + 1])
        self.free_mask = np.ones(self.ndof, bool)
        self.free_mask[fixed] = False
        self.end_x = 2 * np.nonzero(np.abs(x - length) < tol)[0]         # x DOFs of the grip X = l
        self.top = np.nonzero(np.abs(z - h / 2) < tol)[0]
        self.top = self.top[np.argsort(x[self.top])]
        rows = np.repeat(self.gdof, self.gdof.shape[1], axis=1).ravel()
        cols = np.tile(self.gdof, (1, self.gdof.shape[1])).ravel()
        self._rc = (rows, cols)
        self.set_stretch(1.0)

    def set_stretch(self, lam):
        self.lam = float(lam)
        lift = np.zeros((self.X.shape[1], 2))
        lift[:, 0] = (lam - 1.0) * self.X[0]
        self.lift = lift.reshape(-1)

    def homogeneous(self, z1):
        """Unknown (displacement minus lifting) of the homogeneous state."""
        U = np.zeros((self.X.shape[1], 2))
        U[:, 1] = (z1 - 1.0) * self.X[1]
        return U.reshape(-1)

    def _material(self, U):
        """W (e, q), first Piola P2 (e, q, 2, 2), tangent AA2 (e, q, 2, 2, 2, 2)
        with respect to the in-plane F, growth included; None if inadmissible."""
        Ue = (U + self.lift).reshape(-1, 2)[self.nodes]                  # (e, a, i)
        F2 = np.eye(2) + np.einsum("eai,eqaK->eqiK", Ue, self.dN)
        ne, nq = F2.shape[:2]
        A = np.zeros((ne, nq, 3, 3))
        A[..., 1, 1] = 1.0
        A[:, :, IN_PLANE[:, None], IN_PLANE[None, :]] = F2
        A[..., :, 2] /= self.gamma[..., None]                            # A = F G^-1
        npt = ne * nq
        W, P, AA = np.zeros(npt), np.zeros((npt, 9)), np.zeros((npt, 9, 9))
        bad = _law_at_points(self.law.kind, self.law.psi, self.law.params,
                             np.ascontiguousarray(A.reshape(npt, 3, 3)), W, P, AA)
        if bad >= 0:
            return None
        ginv = np.ones((ne, nq, 3))
        ginv[..., 2] = 1.0 / self.gamma
        P = P.reshape(ne, nq, 3, 3) * ginv[:, :, None, :]
        AA = (AA.reshape(ne, nq, 3, 3, 3, 3) * ginv[:, :, None, :, None, None]
              * ginv[:, :, None, None, None, :])
        ip = IN_PLANE
        return (W.reshape(ne, nq), P[:, :, ip[:, None], ip[None, :]],
                AA[:, :, ip[:, None, None, None], ip[None, :, None, None],
                   ip[None, None, :, None], ip[None, None, None, :]])

    # -- the interface of fe3d._newton --------------------------------------
    def energy_residual(self, U, want_residual=True):
        mat = self._material(U)
        if mat is None:
            return np.inf, None
        W, P2, _ = mat
        E = float(np.sum(W * self.c))
        self.Escale = float(np.sum(np.abs(W) * self.c))
        if not want_residual:
            return E, None
        r = np.einsum("eq,eqiK,eqaK->eai", self.c, P2, self.dN)
        R = np.bincount(self.gdof.ravel(), weights=r.ravel(), minlength=self.ndof)
        return E, R

    def tangent(self, U):
        mat = self._material(U)
        if mat is None:
            raise FloatingPointError("inadmissible state in the tangent")
        K = np.einsum("eq,eqaJ,eqiJkL,eqbL->eaibk", self.c, self.dN, mat[2], self.dN,
                      optimize=True)
        ne = K.shape[0]
        K = K.reshape(ne, self.gdof.shape[1], self.gdof.shape[1])
        return sp.csr_matrix((K.ravel(), self._rc), shape=(self.ndof, self.ndof))

    def system(self, K):
        """K with the fixed rows and columns replaced by the identity."""
        D = sp.diags(self.free_mask.astype(float))
        return (D @ K @ D + sp.diags((~self.free_mask).astype(float))).tocsr()

    # -- outputs ------------------------------------------------------------
    def end_force(self, U):
        """Axial force per unit width on the grip X = l, whole thickness."""
        _, R = self.energy_residual(U)
        return 2.0 * float(R[self.end_x].sum())

    def profile(self, U):
        """(x, thickness) of the top face: current X-position and 2 z."""
        u = (U + self.lift).reshape(-1, 2)
        return self.X[0, self.top] + u[self.top, 0], 2 * (self.X[1, self.top] + u[self.top, 1])


# --------------------------------------------------------------------- onset

def block_inertia(block, lam):
    """Negative eigenvalues of the stiffness on the free DOFs at the
    homogeneous state of stretch lam (and |residual| there: round-off)."""
    block.set_stretch(lam)
    U = block.homogeneous(plane_strain_tension(block.law, lam).z1)
    fm = block.free_mask
    K = block.tangent(U)[fm][:, fm].tocsc()
    negative = negative_eigenvalues(sp.tril(K).tocsr())
    _, R = block.energy_residual(U)
    return negative, float(np.abs(R[fm]).max())


def fe_onset(law, h_over_l, nz, tol=1e-9):
    """Onset stretch of the 2D solid by bisection of its stiffness inertia;
    nz elements across the half thickness, square elements."""
    nx = int(round(2 * nz / h_over_l))
    block = Block(law, h_over_l, 1.0, nx, nz)
    lo = considere_stretch(law) - 0.01
    hi = lo + 0.05
    if block_inertia(block, lo)[0] != 0 or block_inertia(block, hi)[0] == 0:
        raise RuntimeError("fe_onset: bracket does not contain the onset")
    rmax = 0.0
    while hi - lo > tol:
        mid = 0.5 * (lo + hi)
        neg, r = block_inertia(block, mid)
        rmax = max(rmax, r)
        lo, hi = (mid, hi) if neg == 0 else (lo, mid)
    return 0.5 * (lo + hi), {"nx": nx, "nz": nz, "dofs": int(block.free_mask.sum()),
                             "max_residual": rmax}


def _moduli(law, lam):
    st = plane_strain_tension(law, lam)
    AA = law.evaluate(np.diag([lam, 1.0, st.z1]))[2]
    # x = 1, z = 3: a11 = A_1111, a13 = A_1133, a33 = A_3333, g1 = A_1313, g3 = A_3131, gm = A_1331
    return AA[0, 0], AA[0, 8], AA[8, 8], AA[2, 2], AA[6, 6], AA[2, 6]


def exact_bifurcation_function(law, lam, h_over_l, mode=1):
    """Exact incremental problem of the block (constant moduli, shear-free
    ends): modes u_x = U(Z) sin kX, u_z = V(Z) cos kX, k = mode pi / l,
    symmetric in Z; U, V ~ exp(q k Z) with
        g1 a33 q^4 + ((a13 + gm)^2 - g1 g3 - a11 a33) q^2 + a11 g3 = 0,
    U = sum A_j cosh(q_j k Z), V = sum b_j A_j sinh(q_j k Z),
    b_j = (g1 q_j^2 - a11) / ((a13 + gm) q_j), traction free at Z = h/2.
    Returns Re[det / (q1 - q2)]: real and continuous through the change from
    complex to real roots (where det itself vanishes identically)."""
    a11, a13, a33, g1, g3, gm = _moduli(law, lam)
    q2 = np.roots([g1 * a33, (a13 + gm) ** 2 - g1 * g3 - a11 * a33, a11 * g3]).astype(complex)
    q = np.sqrt(q2)
    b = (g1 * q ** 2 - a11) / ((a13 + gm) * q)
    kH = mode * np.pi * h_over_l / 2
    r1 = (g1 * q - gm * b) * np.sinh(q * kH)        # shear traction S_13
    r2 = (a13 + a33 * b * q) * np.cosh(q * kH)      # normal traction S_33
    return ((r1[0] * r2[1] - r1[1] * r2[0]) / (q[0] - q[1])).real


def exact_onset(law, h_over_l, mode=1):
    """First zero of exact_bifurcation_function beyond the Considere stretch
    minus 0.01 (scanned, then brentq)."""
    f = lambda lam: exact_bifurcation_function(law, lam, h_over_l, mode)
    lam = considere_stretch(law) - 0.01
    f0 = f(lam)
    while True:
        nxt = lam + 2e-4
        if np.sign(f(nxt)) != np.sign(f0):
            return brentq(f, lam, nxt, xtol=1e-13)
        lam = nxt
        if lam > 3.0:
            raise RuntimeError("exact_onset: no bifurcation below lam = 3")


# ------------------------------------------------------------ post-bifurcation

def _in_plane_ellipticity(block, U, n_dir=72):
    """Smallest eigenvalue over the quadrature points and in-plane unit
    vectors N of the acoustic tensor Q_ik = A_iJkL N_J N_L (growth included),
    relative to the initial shear modulus: < 0 where strong ellipticity is lost."""
    AA = block._material(U)[2]
    th = np.linspace(0, np.pi, n_dir, endpoint=False)
    N = np.stack([np.cos(th), np.sin(th)], axis=1)
    Q = np.einsum("eqiJkL,nJ,nL->eqnik", AA, N, N)
    return float(np.linalg.eigvalsh(Q).min()) / block.law.evaluate(np.eye(3))[2][1, 1]


def _path_row(block, U, its):
    x, t = block.profile(U)
    fm = block.free_mask
    negative = negative_eigenvalues(sp.tril(block.tangent(U)[fm][:, fm]).tocsr())
    return {"lam": block.lam, "force": block.end_force(U), "t_min": float(t.min()),
            "iterations": its, "negative_eigenvalues": negative,
            "ellipticity": _in_plane_ellipticity(block, U), "x": x.tolist(), "thickness": t.tolist()}


def follow(law, h, length, nx, nz, imperfection, lam_end, ds=0.004, ds_max=0.004, max_steps=300,
           t_stop=0.4, verbose=False):
    """Equilibrium path of the imperfect block from lam = 1 by pseudo-arclength
    continuation in (unknown, lam), so that it passes the folds where the end
    displacement turns back (the necking of this hyperelastic solid snaps
    back).  Arc length measured on the total displacement u = U + (lam - 1) X e_x
    (units of length, per node); secant predictor; corrector: Newton on the
    residual and the arc-length condition, the bordered system solved by
    block elimination with one factorization of the stiffness (fe3d._factor).
    Stops at lam_end, at max_steps, when the thinnest section is below t_stop h,
    or where strong ellipticity is lost (beyond that the 2D solution depends on
    the mesh: shear bands).  Returns (rows, why it stopped)."""
    block = Block(law, h, length, nx, nz, imperfection)
    fm = block.free_mask
    Ld = np.zeros((block.X.shape[1], 2))
    Ld[:, 0] = block.X[0]
    Ld = Ld.reshape(-1)                        # d(lifting)/d(lam)
    scale = np.sqrt(block.X.shape[1])          # arc length per node

    def residual(U, lam):
        block.set_stretch(lam)
        return block.energy_residual(U)[1]

    # two displacement-controlled points start the secant
    lin = fe3d._LinearSolver()
    pts = []
    for lam in (1.0, 1.0 + 0.5 * ds):
        block.set_stretch(lam)
        _, R0 = block.energy_residual(np.zeros(block.ndof))
        ref = max(np.linalg.norm(R0[fm]), 1e-3 * law.evaluate(np.eye(3))[2][1, 1] * h)
        U, its, ok = fe3d._newton(block, pts[-1][0] if pts else np.zeros(block.ndof), 1e-10, ref, lin)
        if not ok:
            return [], f"no equilibrium at lam = {lam}"
        pts.append((U, lam))
    rows = [_path_row(block, pts[-1][0], its)]
    stop = f"max_steps = {max_steps}"
    tol = 1e-10 * ref
    for step in range(max_steps):
        (U0, l0), (U1, l1) = pts[-2], pts[-1]
        norm = np.linalg.norm((U1 - U0) + (l1 - l0) * Ld) / scale
        t_u, t_l = (U1 - U0) / norm, (l1 - l0) / norm      # unit secant
        m = (t_u + t_l * Ld) / scale ** 2                  # arc-length condition: m . du_total = ds
        while True:
            U, lam = U1 + ds * t_u, l1 + ds * t_l
            ok = False
            for its in range(1, 16):
                R = residual(U, lam)
                if R is None:
                    break
                g = m @ ((U - U1) + (lam - l1) * Ld) - ds
                if np.linalg.norm(R[fm]) <= tol and abs(g) <= 1e-12 * ds:
                    ok = True
                    break
                K = block.tangent(U)
                solve = fe3d._factor(K[fm][:, fm])
                a = solve(-R[fm])
                b = solve(-(K @ Ld)[fm])
                dlam = -(g + m[fm] @ a) / (m[fm] @ b + m @ Ld)
                U = U.copy()
                U[fm] += a + dlam * b
                lam += dlam
            if ok:
                break
            ds *= 0.5
            if ds < 1e-6:
                return rows, f"arc-length corrector fails beyond lam = {l1:.6f} (step below 1e-6)"
        pts = [pts[-1], (U, lam)]
        row = _path_row(block, U, its)
        rows.append(row)
        if verbose:
            print(f"  lam {lam:.6f}  force {row['force']:.7f}  t_min/h {row['t_min'] / h:.4f}  "
                  f"neg {row['negative_eigenvalues']}  ellipticity {row['ellipticity']:.2e}  "
                  f"({its} its, ds {ds:.3g})", flush=True)
        if row["ellipticity"] <= 0:
            stop = f"strong ellipticity lost at lam = {lam:.6f}"
            break
        if lam >= lam_end:
            stop = f"reached lam = {lam:.6f}"
            break
        if row["t_min"] <= t_stop * h:
            stop = f"thinnest section below {t_stop} h"
            break
        ds = min(ds_max, 1.5 * ds) if its <= 5 else ds
    return rows, stop


def main():
    quick = "--quick" in sys.argv
    law = default_law()
    RESULTS.mkdir(exist_ok=True)
    h, nz = 0.2, (2 if quick else 4)
    t0 = time.perf_counter()
    # arc steps of 0.002: the path is sampled densely enough to be splined
    # (examples/necking.py compares the shell engine's path with it)
    rows, stop = follow(law, h, 1.0, int(round(2 * nz / h)), nz, 1e-3, 1.6, ds=0.002, ds_max=0.002,
                        max_steps=30 if quick else 600, verbose=True)
    out = {"machine": machine_info(), "law": repr(law), "h": h, "length": 1.0, "nz": nz,
           "imperfection": 1e-3, "ds": 0.002, "rows": rows, "stop": stop, "wall_s": time.perf_counter() - t0}
    print("path:", stop)
    name = "necking_2d_path_quick" if quick else "necking_2d_path"
    (RESULTS / f"{name}.json").write_text(json.dumps(out, indent=1))
    chart(out, RESULTS / f"{name}.png")


def chart(out, path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    rows, h = out["rows"], out["h"]
    lam = [r["lam"] for r in rows]
    fig, (ax, bx) = plt.subplots(1, 2, figsize=(9, 3.6))
    ax.plot(lam, [r["force"] / h for r in rows], ".-")
    ax.set_xlabel("end stretch")
    ax.set_ylabel("N / (h mu)")
    bx.plot(lam, [r["t_min"] / h for r in rows], ".-")
    bx.set_xlabel("end stretch")
    bx.set_ylabel("thinnest section / h")
    fig.suptitle(f"2D solid, h/l = {h}, imperfection {out['imperfection']:g}: {out['stop']}",
                 fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=120)


if __name__ == "__main__":
    main()
