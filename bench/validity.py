"""The shell energy's range of validity (issue 14, docs/validity.md).

1. symbol: second variation of the energy about a homogeneously deformed flat
   slab, a wave a e^{i k X1} of the middle surface, against k h: the exact 3D
   slab (the profile through the thickness minimized, mean held), the model
   (point kernel), the model with the strain-gradient term;
2. candidates: the k^4 coefficient (the r_ab block of the point Hessian,
   in-plane direction) for states with curvature, a growth gradient, stress;
3. inertia: negative Hessian eigenvalues of a clamped compressed strip (plane
   strain, C1 Hermite) and plate (DKT) against l / h, with and without the
   term, and the critical element size predicted from the symbol;
4. scenes: the two scenes of the issue (axisymmetric engine, consistent level,
   10 steps): without the term, the failing meshes and the critical element
   size along the continuation path; with it, energy and profile under
   refinement (n = 32 ... 512, h = 0.05, 0.1, 0.2) and the triangle engine
   without and with the term (cone, h = 0.2, l = h ... h/4);
5. the triangle engine with the term on both scenes, h = 0.05, 0.1, 0.2,
   l = h, h/2, h/4 (h = 0.2: on to h/16): convergence, stability, Newton
   iterations, time, energy and meridian against the axisymmetric engine at
   n = 512, the strain-gradient share at the poles (the cone points).

Writes bench/results/validity.json and validity.png (1-4) and
validity_dkt.json (5; the finest meshes, 41 952 triangles, take about 8
minutes each on one thread, the whole of 5 about 40 minutes).
Run: python bench/validity.py [--quick]   (--quick: n <= 128, DKT n <= 32; 5: the two coarsest)
     python bench/validity.py --dkt [--only 'fold h=0.05' ...]   (5 only; --only: these cases,
                                           merged into the existing validity_dkt.json)
     python bench/validity.py --tables     (markdown tables of the last results)
"""

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent / "tests"))
sys.path.insert(0, str(HERE))                                 # bench/machine.py

from machine import machine_info  # noqa: E402
from shellritz import NeoHookean, Shell, shapes  # noqa: E402
from shellritz.discretize.axisym import AxisymmetricShell  # noqa: E402
from shellritz.discretize.planestrain import PlaneStrainShell  # noqa: E402
from shellritz.model import evaluate_point  # noqa: E402
from shellritz.scenes import RevolutionScene  # noqa: E402
from shellritz.linalg import negative_eigenvalues  # noqa: E402
from shellritz.solve import SolveError  # noqa: E402
from test_validity import (LAW, cone_scene, fold_scene, inplane, shell_symbol,  # noqa: E402
                           slab_symbol_3d, strain_gradient_symbol)

RESULTS = HERE / "results"
DKT_RESULTS = RESULTS / "validity_dkt.json"
HERMITE_C = 60.0      # max of int u''^2 / int u'^2 times l^2 over C1 cubic Hermite fields


# ---------------------------------------------------------------------------
# 1-2: symbols
# ---------------------------------------------------------------------------

STATES = {"stress free": (1.0, 1.0), "2 % uniaxial compression": (0.98, 1.0),
          "5 % biaxial compression": (0.95, 0.95), "5 % uniaxial tension": (1.05, 1.0)}


def symbols(h=0.1):
    khs = np.geomspace(0.05, 300, 70)
    out = {"h": h, "kh": khs.tolist(), "states": {}}
    for name, (l1, l2) in STATES.items():
        rows = {"3d": [], "model": [], "model+R": [], "3d_normal": [], "model_normal": []}
        for kh in khs:
            k = kh / h
            S3 = slab_symbol_3d(LAW, l1, l2, h, k)
            S = shell_symbol(LAW, l1, l2, h, k)
            R = strain_gradient_symbol(LAW, l1, l2, h, k)
            scale = h * k * k
            rows["3d"].append(inplane(S3) / scale)
            rows["model"].append(inplane(S) / scale)
            rows["model+R"].append(inplane(S + R) / scale)
            rows["3d_normal"].append(float(np.real(S3[2, 2])) / scale)
            rows["model_normal"].append(float(np.real(S[2, 2])) / scale)
        m = np.array(rows["model"])
        neg = khs[m < 0]
        rows["kh_negative_from"] = float(neg.min()) if len(neg) else None
        out["states"][name] = rows
        print(f"symbol, {name}: model in-plane negative from k h = {rows['kh_negative_from']}", flush=True)
    return out


def k4_coefficient(ref, v, h, **kw):
    """In-plane k^4 and k^2 coefficients of the point Hessian along r_1:
    t.H[r_11, r_11].t and t.H[r_1, r_1].t, t = r_1 / |r_1|."""
    H = evaluate_point(LAW, v, ref, h, "consistent", **kw).hess
    t = v[0:3] / np.linalg.norm(v[0:3])
    return float(t @ H[6:9, 6:9] @ t), float(t @ H[0:3, 0:3] @ t)


def candidates(h=0.1):
    """k^4 coefficient / (h^3 E'/12) for one change at a time from the stress-free plate."""
    E_plane = 4 * LAW.C * (LAW.D + LAW.C) / (LAW.D + 2 * LAW.C)
    scale = h ** 3 * E_plane / 12
    flat = np.r_[1.0, 0, 0, 0, 1, 0, np.zeros(9)]
    rows = []

    def row(name, ref, v, **kw):
        c4, c2 = k4_coefficient(ref, v, h, **kw)
        rows.append({"state": name, "k4_over_h3E/12": c4 / scale,
                     "critical_kh": float(h * np.sqrt(c2 / -c4)) if c4 < 0 else None})

    row("stress free", flat, flat)
    for kh_ in (0.1, 0.3, 0.6):      # cylinder of radius 1/kappa bent uniformly (stress-free reference)
        R = h / kh_
        ref = np.r_[1.0, 0, 0, 0, 1, 0, 0, 0, 1 / R, 0, 0, 0, 0, 0, 0]
        row(f"curved reference, kappa h = {kh_} (stress free)", ref, ref)
        v = ref.copy()
        v[8] *= 1.5
        row(f"curvature changed by 50 %, kappa h = {kh_}", ref, v)
    for g1h in (0.1, 0.3):
        row(f"growth gradient h |G1| = {g1h} (flat)", flat, flat, G1=np.diag([g1h / h, g1h / h, 0.0]))
    for lam in (0.99, 0.98, 0.95, 1.02):
        v = flat.copy()
        v[0] = lam
        row(f"in-plane stretch {lam} along the wave", flat, v)
    v = flat.copy()
    v[0] = 0.98
    v[8] = 0.3 / h
    row("stretch 0.98 and curvature kappa h = 0.3", flat, v)
    for r in rows:
        print(f"k^4 coefficient, {r['state']}: {r['k4_over_h3E/12']:+.4f}"
              + (f" (negative: k h_c = {r['critical_kh']:.1f})" if r["critical_kh"] else ""), flush=True)
    return rows


# ---------------------------------------------------------------------------
# 3: inertia of clamped compressed strips and plates
# ---------------------------------------------------------------------------

def negative_pivots(engine):
    engine._setup()
    engine.set_parameter(1.0)
    _, _, K = engine.evaluate(engine.free_state(), 2)
    return negative_eigenvalues(K)


def inertia(quick):
    h, L = 0.1, 0.2
    out = {"h": h, "length": L, "strip": [], "plate": []}
    for gamma in (1.02, 1.05, 1.25):
        # predicted critical element size of the Hermite strip: l_c = h sqrt(60) / (k h)_c
        l1 = 1 / gamma
        S = lambda kh: inplane(shell_symbol(LAW, l1, 1.0, h, kh / h)) / (kh / h) ** 2
        a0, a1 = S(1e-3), (S(10.0) - S(1e-3)) / 100
        kh_c = float(np.sqrt(a0 / -a1))
        for n in (4, 8, 16, 32, 64, 128, 256):
            row = {"gamma": gamma, "n": n, "l_over_h": L / n / h, "predicted_l_c_over_h": np.sqrt(HERMITE_C) / kh_c}
            for cured in (False, True):
                ps = PlaneStrainShell.strip(n, L, h, LAW)
                if not cured:
                    ps.strain_gradient = None
                ps.set_growth(G0=np.diag([gamma, 1, 1]))
                ps.clamp(0).clamp(-1)
                row["negative_with_term" if cured else "negative"] = negative_pivots(ps)
            out["strip"].append(row)
            print(f"strip, growth {gamma}, l/h = {row['l_over_h']:.4f} (predicted l_c/h {row['predicted_l_c_over_h']:.3f}): "
                  f"negative eigenvalues {row['negative']} -> {row['negative_with_term']}", flush=True)
        for n in (4, 8, 16) if quick else (4, 8, 16, 32):
            row = {"gamma": gamma, "n": n, "l_over_h": L / n / h}
            for cured in (False, True):
                mesh = shapes.rectangle(n, n, lx=L, ly=L)
                sh = Shell(mesh, h, LAW)
                if not cured:
                    sh.strain_gradient = None
                sh.set_growth(G0=np.diag([gamma, gamma, 1.0]))
                sh.clamp(mesh.boundary_nodes())
                row["negative_with_term" if cured else "negative"] = negative_pivots(sh)
            out["plate"].append(row)
            print(f"plate, growth {gamma}, l/h = {row['l_over_h']:.4f}: negative eigenvalues "
                  f"{row['negative']} -> {row['negative_with_term']}", flush=True)
    return out


# ---------------------------------------------------------------------------
# 4: the scenes of the issue
# ---------------------------------------------------------------------------

SCENES = {"cone": cone_scene, "fold": fold_scene}


def critical_element_size(engine):
    """max over the Gauss points of l_c = sqrt(60 |C| / A) where C < 0 and A
    are the in-plane k^4 and k^2 coefficients (meridional direction) of the
    point Hessian at the current state (engine without the term)."""
    U = engine.U
    best = 0.0
    for q in range(len(engine.sq)):
        v = engine.B[q] @ U[engine.elem_dofs[engine.qelem[q]]] + engine.c[q]
        H = evaluate_point(engine.law, v, engine.REF[q], engine.h, engine.level, G0=engine._G0q[q],
                           G1=engine._G1q[q], dG0=engine._dG0[q], qbar=engine._QB[q], m=engine._M[q],
                           dm=engine._DM[q]).hess
        t = v[3:6] / np.linalg.norm(v[3:6])
        C, A = t @ H[12:15, 12:15] @ t, t @ H[3:6, 3:6] @ t
        if C < 0:
            best = max(best, float(np.sqrt(HERMITE_C * -C / A)))
    return best


def line_engine(scene, n, cured, level="consistent"):
    eng = scene._line_engine(AxisymmetricShell, level, n)
    eng.fix_coordinate(0, "b")
    if not cured:
        eng.strain_gradient = None
    return eng


def uncured_runs(name, h, sizes):
    """Each mesh without the term: converged or the last converged t, and the
    critical element size l_c(t) at the converged steps."""
    rows = []
    for n in sizes:
        eng = line_engine(SCENES[name](h), n, cured=False)
        t0 = time.perf_counter()
        try:
            eng.solve(steps=10, verbose=False)
            last, ok = 1.0, True
        except SolveError as exc:           # the engine holds the last converged state
            last, ok = exc.last_t, False
        wall = time.perf_counter() - t0
        lc = critical_element_size(eng) / h
        rows.append({"n": n, "l_over_h": np.pi / n / h, "converged": ok, "last_t": last, "wall_s": wall,
                     "l_c_over_h_at_last_t": lc})
        print(f"{name} h={h} n={n} (l/h = {np.pi / n / h:.3f}) without the term: "
              f"{'converged' if ok else f'fails beyond t = {last:.4f}'}; l_c/h there {lc:.3f}", flush=True)
    return rows


def critical_path(name, h, n):
    """l_c(t)/h along the continuation path of a converging mesh (without the term)."""
    eng = line_engine(SCENES[name](h), n, cured=False)
    states = []
    from shellritz import solve as solve_mod
    orig = solve_mod.equilibrium          # sampled after every converged step

    def equilibrium(problem, t, *args):
        ok = orig(problem, t, *args)
        if ok:
            states.append((t, critical_element_size(eng)))
        return ok
    solve_mod.equilibrium = equilibrium
    try:
        eng.solve(steps=10, verbose=False)
    finally:
        solve_mod.equilibrium = orig
    return [{"t": t, "l_c_over_h": l / h} for t, l in states]


def profile_on(result, s):
    a, b = result.raw.at(s)
    return np.c_[a, b]


def cured_runs(name, h, sizes, s_common):
    rows, profiles = [], {}
    for n in sizes:
        t0 = time.perf_counter()
        r = SCENES[name](h).solve("axisym", level="consistent", n=n, steps=10)
        row = {"n": n, "l_over_h": np.pi / n / h, "energy": r.raw.energy, "iterations": r.iterations,
               "stable": bool(r.raw.history.stable), "wall_s": time.perf_counter() - t0,
               "strain_gradient_share": r.raw.engine.strain_gradient.per_element.sum() / r.raw.energy}
        profiles[n] = profile_on(r, s_common)
        rows.append(row)
    finest = max(sizes)
    for row in rows:
        row["energy_error"] = abs(row["energy"] - rows[-1]["energy"]) / abs(rows[-1]["energy"])
        row["profile_error"] = float(np.abs(profiles[row["n"]] - profiles[finest]).max())
    for a, b in zip(rows[:-2], rows[1:-1]):
        b["energy_rate"] = float(np.log2(a["energy_error"] / b["energy_error"]))
        b["profile_rate"] = float(np.log2(a["profile_error"] / b["profile_error"]))
    for row in rows:
        print(f"{name} h={h} n={row['n']}: E = {row['energy']:.10e} (error {row['energy_error']:.2e}), "
              f"profile error {row['profile_error']:.2e}, {row['iterations']} iterations, "
              f"R/E = {row['strain_gradient_share']:.1e}", flush=True)
    return rows


def dkt_runs(sizes):
    rows = []
    for cured in (False, True):
        for n in sizes:
            scene = cone_scene(0.2)
            t0 = time.perf_counter()
            try:
                if cured:
                    r = scene.solve("dkt", level="consistent", n=n, steps=10)
                else:
                    import shellritz.scenes as S

                    class Uncured(Shell):
                        def __init__(self, *a, **k):
                            super().__init__(*a, **k)
                            self.strain_gradient = None
                    S.Shell, orig = Uncured, S.Shell
                    try:
                        r = scene.solve("dkt", level="consistent", n=n, steps=10)
                    finally:
                        S.Shell = orig
                row = {"cured": cured, "n": n, "converged": True, "energy_quarter": r.raw.energy,
                       "iterations": r.iterations, "dofs": r.dofs}
            except SolveError as exc:
                row = {"cured": cured, "n": n, "converged": False, "last_t": exc.last_t}
            row["wall_s"] = time.perf_counter() - t0
            row["l_over_h"] = np.pi / n / 0.2
            rows.append(row)
            print("dkt cone h=0.2", row, flush=True)
    return rows


# ---------------------------------------------------------------------------
# 5: the triangle engine on both scenes, elements from h down to h/4
# ---------------------------------------------------------------------------

# n along the meridian for each h: l = pi/n from about h to about h/4 (h = 0.2:
# on to h/16, where the cone point's strain-gradient energy shows, section 6)
DKT_SIZES = {0.2: (16, 32, 64, 128, 256), 0.1: (32, 64, 128), 0.05: (64, 128, 256)}
DKT_AXISYM_N = 512      # the axisymmetric energy of the same scene the triangles are compared with


def dkt_run(name, h, n, nphi=None, axisym=None):
    """One triangle solve of a scene (a quarter sphere with symmetry planes,
    consistent level, 10 steps; nphi None: square elements on the widest
    ring).  Energies are 4 x the quarter's.  A failed solve is recorded with
    its last converged t and the validity measures of that state.  axisym: a
    solved axisymmetric result of the same scene; the meridian phi = 0 of the
    triangles is compared with it (largest distance at the nodes).  The
    strain-gradient energy of the triangles within 2 l of the axis (the
    poles) is recorded apart."""
    import warnings
    from shellritz.validity import ValidityWarning
    scene = SCENES[name](h)
    t0 = time.perf_counter()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", ValidityWarning)
        try:
            r = scene.solve("dkt", level="consistent", n=n, steps=10, nphi=nphi)
            raw, row = r.raw, {"converged": True, "iterations": r.iterations, "dofs": r.dofs}
            if axisym is not None:
                a, b = axisym.raw.at(r.s)
                row["profile_difference"] = float(np.hypot(r.a - a, r.b - b).max())
        except SolveError as exc:
            raw, row = exc.result, {"converged": False, "last_t": exc.last_t,
                                    "iterations": len(exc.history.iterations)}
    wall = time.perf_counter() - t0
    sh = raw.shell
    if nphi is None:      # as RevolutionScene._solve_dkt: square elements on the widest ring
        s = np.linspace(*scene.s_range, n + 1)
        nphi = max(1, int(round(np.abs(scene._sample(s)[0]).max() * np.pi / 2 / (s[1] - s[0]))))
    nphi_used = nphi
    sg = sh.strain_gradient
    V = raw.validity
    X = sh.mesh.vertices
    c = X[sh.mesh.triangles].mean(axis=1)
    near_axis = np.hypot(c[:, 0], c[:, 1]) < 2 * np.pi / n
    row.update({"scene": name, "h": h, "n": n, "nphi": nphi_used, "triangles": int(sh.mesh.n_triangles),
                "l_over_h": np.pi / n / h, "l_phi_over_h": np.pi / 2 / nphi_used / h,
                "stable": bool(raw.history.stable) if raw.history.stable is not None else None,
                "energy": 4 * raw.energy, "t": raw.t, "wall_s": wall,
                "assemblies": raw.history.assemblies, "linear": raw.history.linear,
                "strain_gradient_share": (float(sg.per_element.sum() / raw.energy) if sg is not None else 0.0),
                "active_triangles": int(sg.active.sum()) if sg is not None else 0,
                "pole_strain_gradient_share": (float(sg.per_element[near_axis].sum() / raw.energy)
                                               if sg is not None else 0.0),
                "pole_triangles": int(near_axis.sum()),
                "validity": {k: {"max": float(getattr(V, k).max()), "flagged": len(v),
                                 "worst": [int(e) for e in v[np.argsort(-getattr(V, k)[v])][:8]]}
                             for k, v in V.flagged.items()},
                "warnings": [str(w.message) for w in caught if issubclass(w.category, ValidityWarning)]})
    print(f"dkt {name} h={h} n={n} nphi={nphi_used} ({row['triangles']} triangles, l/h = {row['l_over_h']:.3f}): "
          + (f"E = {row['energy']:.8e}, {row['iterations']} iterations, stable {row['stable']}"
             if row["converged"] else f"FAILS beyond t = {row['last_t']:.4f}")
          + f", {wall:.1f} s; R/E = {row['strain_gradient_share']:.1e} "
          f"({row['pole_strain_gradient_share']:.1e} in the {row['pole_triangles']} triangles at the poles)"
          + (f", meridian {row['profile_difference']:.1e} from the axisymmetric" if "profile_difference" in row
             else ""), flush=True)
    return row


def dkt_scenes(res, quick, only=None):
    """Both scenes at h = 0.05, 0.1, 0.2 on the triangle engine (l = h ... h/4),
    with the axisymmetric energy at n = DKT_AXISYM_N for comparison.
    res["dkt_scenes"][key] = {"axisym_energy": ..., "runs": [...]}; written
    after every run."""
    out = res.setdefault("dkt_scenes", {})
    for name in SCENES:
        for h in (0.2, 0.1, 0.05):
            key = f"{name} h={h}"
            if only and key not in only:
                continue
            ax = {m: SCENES[name](h).solve("axisym", level="consistent", n=m, steps=10)
                  for m in (256, DKT_AXISYM_N)}
            entry = out[key] = {"axisym_energy": ax[DKT_AXISYM_N].raw.energy,
                                "axisym_energy_256": ax[256].raw.energy, "axisym_n": DKT_AXISYM_N,
                                "axisym_strain_gradient_share": float(
                                    ax[DKT_AXISYM_N].raw.engine.strain_gradient.per_element.sum()
                                    / ax[DKT_AXISYM_N].raw.energy), "runs": []}
            sizes = DKT_SIZES[h][:2] if quick else DKT_SIZES[h]
            for n in sizes:
                entry["runs"].append(dkt_run(name, h, n, axisym=ax[DKT_AXISYM_N]))
                entry["machine"] = machine_info()     # load average after the run (shared machine)
                yield res
            runs = [r for r in entry["runs"] if r["converged"]]
            for r in runs:
                r["difference_to_axisym"] = (r["energy"] - entry["axisym_energy"]) / abs(entry["axisym_energy"])
            if len(runs) >= 2:
                entry["last_change"] = (runs[-1]["energy"] - runs[-2]["energy"]) / abs(entry["axisym_energy"])
            yield res


def dkt_table(res):
    """Markdown table of section 5 (results/validity_dkt.json)."""
    out = ["| scene | h | n | nphi | triangles | l / h | converged, stable | energy (4 x quarter) | vs axisym | "
           "change from previous | meridian vs axisym | R / E (at the poles) | Newton iterations | wall (s) |",
           "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for key, entry in res["dkt_scenes"].items():
        name, h = key.split(" h=")
        prev = None
        for r in entry["runs"]:
            ok = r["converged"]
            change = (f"{(r['energy'] - prev) / abs(entry['axisym_energy']):+.2%}" if ok and prev is not None else "")
            out.append(f"| {name} | {h} | {r['n']} | {r['nphi']} | {r['triangles']} | {r['l_over_h']:.2f} | "
                       + (f"yes, {'yes' if r['stable'] else 'no'} | {r['energy']:.5e} | "
                          f"{r['difference_to_axisym']:+.2%} | {change} | {r.get('profile_difference', float('nan')):.1e} | "
                          if ok else f"no: t = {r['last_t']:.3f} | — | — | — | — | ")
                       + f"{r['strain_gradient_share']:.1e} ({r['pole_strain_gradient_share']:.1e}) | "
                       f"{r['iterations']} | {r['wall_s']:.0f} |")
            prev = r["energy"] if ok else prev
        out.append(f"| {name} | {h} | axisym, n = {entry['axisym_n']} | | | | | {entry['axisym_energy']:.5e} | | | | "
                   f"{entry['axisym_strain_gradient_share']:.1e} | | |")
    return "\n".join(out)


def chart(res, path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, axes = plt.subplots(1, 3, figsize=(16, 4.8))
    ax = axes[0]
    sym = res["symbol"]
    kh = np.array(sym["kh"])
    colours = dict(zip(sym["states"], ("k", "C0", "C3", "C2")))
    for name, rows in sym["states"].items():
        c = colours[name]
        ax.semilogx(kh, rows["3d"], color=c, lw=2.5, alpha=0.35)
        ax.semilogx(kh, rows["model"], color=c, ls="--", label=f"{name}")
        ax.semilogx(kh, rows["model+R"], color=c, ls=":")
    ax.axhline(0, color="gray", lw=0.8)
    top = max(max(rows["3d"]) for rows in sym["states"].values())
    ax.set_ylim(-top, 1.6 * top)
    ax.set_xlabel("k h")
    ax.set_ylabel("in-plane wave: second variation / (h k^2)")
    ax.set_title("slab: 3D (thick), model (dashed), model + R (dotted)")
    ax.legend(fontsize=7, loc="lower left")
    ax = axes[1]
    for gamma in sorted({r["gamma"] for r in res["inertia"]["strip"]}):
        rows = [r for r in res["inertia"]["strip"] if r["gamma"] == gamma]
        x = [r["l_over_h"] for r in rows]
        p = ax.loglog(x, [max(r["negative"], 0.5) for r in rows], "o-", label=f"strip, growth {gamma}")
        ax.loglog(x, [max(r["negative_with_term"], 0.5) for r in rows], "x", color=p[0].get_color())
        ax.axvline(rows[0]["predicted_l_c_over_h"], color=p[0].get_color(), ls=":", lw=1)
        rows = [r for r in res["inertia"]["plate"] if r["gamma"] == gamma]
        ax.loglog([r["l_over_h"] for r in rows], [max(r["negative"], 0.5) for r in rows], "s--",
                  color=p[0].get_color(), mfc="none", label=f"DKT plate, growth {gamma}")
    ax.set_xlabel("element size / h")
    ax.set_ylabel("negative Hessian eigenvalues (0 shown as 0.5)")
    ax.set_title("clamped compressed strip / plate; x: with R (all 0); dotted: predicted l_c")
    ax.legend(fontsize=7)
    ax = axes[2]
    for key, rows in res.get("scenes_cured", {}).items():
        rows = rows[:-1]
        ax.loglog([r["n"] for r in rows], [r["energy_error"] for r in rows], "o-", label=f"{key}: energy")
        ax.loglog([r["n"] for r in rows], [r["profile_error"] for r in rows], "x--", label=f"{key}: profile")
    ax.set_xlabel("elements along the meridian n")
    ax.set_ylabel("difference to the finest mesh")
    ax.set_title("scenes of issue 14 with R (axisymmetric, consistent)")
    ax.legend(fontsize=6, ncol=2)
    fig.tight_layout()
    fig.savefig(path, dpi=110)


def tables(res):
    """Markdown tables of the refinement study (docs/validity.md section 6)."""
    out = ["| scene (difference to n = 512) | h | n = 32 | 64 | 128 | 256 | observed rate (log2 of the ratios) |",
           "|---|---|---|---|---|---|---|"]
    for key, rows in res["scenes_cured"].items():
        name, h = key.split(" h=")
        for what in ("energy", "profile"):
            errs = [r[f"{what}_error"] for r in rows[:-1]]
            rates = [r[f"{what}_rate"] for r in rows if f"{what}_rate" in r]
            out.append(f"| {name} ({what}) | {h} | " + " | ".join(f"{e:.1e}" for e in errs)
                       + " | " + ", ".join(f"{q:.1f}" for q in rates) + " |")
    out += ["", "| scene | h | without the term: converges up to n | fails at n (last t) | "
            "with the term: Newton iterations n = 32 ... 512 |", "|---|---|---|---|---|"]
    for key, rows in res["scenes_uncured"].items():
        name, h = key.split(" h=")
        ok = [r["n"] for r in rows if r["converged"]]
        bad = [f"{r['n']} ({r['last_t']:.3f})" for r in rows if not r["converged"]]
        its = [str(r["iterations"]) for r in res["scenes_cured"][key]]
        out.append(f"| {name} | {h} | {max(ok) if ok else '—'} | {', '.join(bad) or '—'} | {', '.join(its)} |")
    if "dkt" in res:
        out += ["", "| triangles, cone h = 0.2 | n | l / h | converged | energy (quarter) | iterations |",
                "|---|---|---|---|---|---|"]
        for r in res["dkt"]:
            out.append(f"| {'with' if r['cured'] else 'without'} the term | {r['n']} | {r['l_over_h']:.2f} | "
                       f"{r['converged'] if r['converged'] else 'no, t = %.3f' % r['last_t']} | "
                       f"{r.get('energy_quarter', float('nan')):.6e} | {r.get('iterations', '—')} |")
    return "\n".join(out)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--tables", action="store_true", help="print the tables of results/validity.json")
    ap.add_argument("--dkt", action="store_true",
                    help="only the triangle engine on both scenes (section 5): results/validity_dkt.json")
    ap.add_argument("--only", nargs="*", metavar="KEY",
                    help="with --dkt: only these cases, e.g. 'fold h=0.05' (merged into the existing file)")
    args = ap.parse_args()
    if args.tables:
        print(tables(json.loads((RESULTS / "validity.json").read_text())))
        if DKT_RESULTS.exists():
            print()
            print(dkt_table(json.loads(DKT_RESULTS.read_text())))
        return
    if args.dkt:
        run_dkt(args.quick, args.only)
        return
    res = {"law": "neo-Hookean C = 1, nu = 0.4", "quick": args.quick}
    res["symbol"] = symbols()
    res["machine"] = machine_info()          # after the kernels ran (threading layer known)
    res["candidates"] = candidates()
    res["inertia"] = inertia(args.quick)
    sizes = [32, 64, 128] if args.quick else [32, 64, 128, 256, 512]
    s_common = np.linspace(0, np.pi, 257)
    res["scenes_uncured"], res["critical_path"], res["scenes_cured"] = {}, {}, {}
    for name in SCENES:
        for h in (0.05, 0.1, 0.2):
            key = f"{name} h={h}"
            res["scenes_uncured"][key] = uncured_runs(name, h, sizes)
            ok = [r["n"] for r in res["scenes_uncured"][key] if r["converged"]]
            if ok:
                res["critical_path"][key] = {"n": max(ok), "path": critical_path(name, h, max(ok))}
            res["scenes_cured"][key] = cured_runs(name, h, sizes, s_common)
            write(res)                       # partial results survive an interrupted run
    res["dkt"] = dkt_runs([16, 32] if args.quick else [16, 32, 64])
    write(res)
    chart(res, RESULTS / "validity.png")
    run_dkt(args.quick, None)


def run_dkt(quick, only):
    """Section 5 into results/validity_dkt.json (merged with the cases already
    there when ``only`` names some)."""
    res = json.loads(DKT_RESULTS.read_text()) if only and DKT_RESULTS.exists() else {}
    res.update({"law": "neo-Hookean C = 1, nu = 0.4", "quick": quick,
                "setup": "RevolutionScene.solve('dkt', level='consistent', n, steps=10): a quarter sphere "
                         "with symmetry planes, nphi square elements on the widest ring; energies 4 x quarter"})
    for res in dkt_scenes(res, quick, only):
        res["machine"] = machine_info()       # as of the last run (each case has its own)
        RESULTS.mkdir(exist_ok=True)
        DKT_RESULTS.write_text(json.dumps(res, indent=1, default=float))
    print(dkt_table(res))


def write(res):
    RESULTS.mkdir(exist_ok=True)
    (RESULTS / "validity.json").write_text(json.dumps(res, indent=1, default=float))


if __name__ == "__main__":
    main()
