"""Peer comparison: the Sze cantilever under end shear, shellritz against
Kratos Multiphysics, same meshes, same run, same threads.

Sze, Liu & Lo (2004), "Popular benchmark problems for geometric nonlinear
analysis of shells", section 3.1: a strip L = 10, b = 1, h = 0.1,
E = 1.2e6, nu = 0, clamped at x = 0, a total shear P = 4 (direction +z) on
the free edge x = L, dead, in 10 equal load steps.  With nu = 0 the strip is
a beam with EI = E b h^3 / 12 = 100, P L^2 / EI = 4, and the reference is the
elastica (computed here by shooting to 1e-13): at P = 4 the tip moves by
u = -3.2894 along the strip (x, the horizontal shortening) and w = 6.6996 in
the load direction (z, the vertical deflection) -- Sze et al.'s table gives
about -3.29 and 6.70.  Tip displacement = mean over the free-edge nodes.

Both codes get the same vertices and triangles (`shapes.rectangle`, quads
split by alternating diagonals) and the same nodal forces (trapezoid weights
of the edge traction P / b, what `Shell.edge_load` computes):

* shellritz: `Shell(mesh, h, StVenantKirchhoff.from_young(E, 0), level=
  "consistent")`, `clamp(x = 0)`, `edge_load(x = L, (0, 0, P / b))`,
  `solve(steps=10, max_dt=0.1)`: the protocol's 10 equal load steps (a
  step is halved only if it fails; the steps taken are recorded), each
  started from the cubic Hermite extrapolation of the last two equilibria
  and their tangents (the default predictor); convergence |g| <= 1e-9
  max(|g| at the step start, |load at t|), or a Newton correction at
  round-off.  Code `shellritz-adaptive`: `solve(steps=10)`, shellritz's
  default, whose steps double after easy ones (fewer than 10 steps).
* Kratos: `ShellThinElementCorotational3D3N` with `LinearElasticPlaneStress2DLaw`,
  displacements and rotations fixed at x = 0, `PointLoadCondition3D1N` on
  the free-edge nodes, `ResidualBasedNewtonRaphsonStrategy` with
  `ResidualBasedIncrementalUpdateStaticScheme` and the block builder, linear
  solver `sparse_lu` of LinearSolversApplication (Eigen SparseLU; its PyPI
  wheel is built without MKL, so without `pardiso_*`; of the direct solvers
  it has, sparse_lu was the fastest: the 1,280-triangle run took 16.4 s, with
  `skyline_lu_factorization` 24.0 s, with `sparse_qr` 29.7 s, same Newton
  iterations; one run each on the loaded 2-core machine).  Convergence: `DisplacementCriteria`, Newton correction
  <= 1e-9 of the displacement norm.  Kratos' residual cannot be used at
  1e-9 of the load: it stalls at a round-off floor (3e-9 of the load
  increment at 32 triangles, 4e-8 at 1,280) while the corrections fall to
  1e-15; the criterion above stops at that floor, and the final residual of
  each code relative to the load is recorded (`residual_rel`).

Wall time: from the mesh arrays to the converged state at P (model set-up
included), median of --repeats runs, codes alternating (``wall_over_kratos``:
the ratio of the medians; ``wall_over_kratos_paired``: the median of the
ratios within each repeat, whose runs follow each other); the process CPU time
of the same span (all threads; spinning OpenMP threads count) is recorded
too, as the machine may be shared (load average recorded).  Compile time is
excluded and reported separately: shellritz.batch.prepare_kernels compiles
the Numba kernels (or loads them from the disk cache), then both codes solve
a 32-triangle mesh.  2 threads
each: OMP_NUM_THREADS, NUMBA_NUM_THREADS, MKL_NUM_THREADS are set before
anything loads, plus numba.set_num_threads and Kratos'
ParallelUtilities.SetNumThreads; the values in effect are recorded.

Rows carry wall_over_kratos (wall time / Kratos' in the same run).
Writes bench/results/peers.json and peers.png (--quick: one repeat on
meshes of 64 and 256 triangles, peers_quick.*; --membrane regge: shellritz
with the locking-free membrane metric, peers_regge.*).
Run:  pip install -e '.[peers]' && python bench/peers.py [--repeats 3] [--quick] [--membrane regge]
"""

import os

THREADS = 2
for _var in ("OMP_NUM_THREADS", "NUMBA_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS"):
    os.environ[_var] = str(THREADS)      # before numpy, numba, MKL and Kratos load

import argparse  # noqa: E402
import json  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))      # bench/machine.py

import numpy as np  # noqa: E402
from scipy.integrate import solve_ivp  # noqa: E402
from scipy.optimize import brentq  # noqa: E402

RESULTS = Path(__file__).resolve().parent / "results"

L, B, H, E, NU, P, STEPS = 10.0, 1.0, 0.1, 1.2e6, 0.0, 4.0, 10
CASES = {"full": [(64, 10), (128, 20)], "quick": [(16, 2), (32, 4)]}
WARMUP = (8, 2)
RTOL = 1e-9
KRATOS_LINEAR = "sparse_lu"     # LinearSolversApplication: Eigen SparseLU
CODES = ("shellritz", "kratos", "shellritz-adaptive")


def elastica(alpha, axial=0.0):
    """Tip of the elastica of a cantilever under a dead end load normal to
    its axis, alpha = P L^2 / EI: (u, w, end rotation), u along the axis, w
    in the load direction, per unit length.  axial = P / EA adds the
    extension of the axis by the axial force P sin(theta) / EA (0: the
    classical inextensible elastica)."""
    def rhs(s, y):
        th, k = y[0], y[1]
        stretch = 1.0 + axial * np.sin(th)
        return [k, -alpha * stretch * np.cos(th), stretch * np.cos(th), stretch * np.sin(th)]

    def tip(k0):                       # theta(0) = 0, theta'(0) = k0; moment-free end: theta'(1) = 0
        return solve_ivp(rhs, (0.0, 1.0), [0.0, k0, 0.0, 0.0], rtol=1e-13, atol=1e-14).y[:, -1]

    k0 = brentq(lambda k: tip(k)[1], 0.1 * alpha, alpha, xtol=1e-15)
    th, _, x, z = tip(k0)
    return x - 1.0, z, th


def strip(nx, ny):
    from shellritz import shapes
    mesh = shapes.rectangle(nx, ny, lx=L, ly=B)
    clamped = mesh.nodes_on_plane("x", 0.0)
    tip = mesh.nodes_on_plane("x", L)
    return mesh, clamped, tip


def tip_forces(mesh, tip):
    """z-forces on the free-edge nodes: trapezoid weights of the traction P / b."""
    y = mesh.vertices[tip, 1]
    order = np.argsort(y)
    half = 0.5 * np.diff(y[order])
    w = np.zeros(len(tip))
    w[order[:-1]] += half
    w[order[1:]] += half
    return P / B * w


# ------------------------------------------------------------------ shellritz
def run_shellritz(mesh, clamped, tip, adaptive=False, membrane="dkt"):
    """10 equal load steps (the protocol), or adaptive ones from 10."""
    from shellritz import Shell, StVenantKirchhoff
    t0, c0 = time.perf_counter(), time.process_time()
    shell = Shell(mesh, H, StVenantKirchhoff.from_young(E, NU), level="consistent", membrane=membrane)
    shell.clamp(clamped)
    shell.edge_load(tip, [0.0, 0.0, P / B])
    res = shell.solve(steps=STEPS, verbose=False, rtol=RTOL, max_dt=None if adaptive else 1.0 / STEPS)
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    h = res.history
    steps = [t for t, ok in h.steps[1:] if ok]            # h.steps[0] is the start state t = 0
    u = res.displacement[tip].mean(axis=0)
    g = shell.evaluate(shell.free_state(), 1)[1]          # at t = 1, outside the timing
    return {"wall_s": wall, "cpu_s": cpu, "newton_its": len(h.iterations),
            "tip_u": float(u[0]), "tip_w": float(u[2]), "tip_v": float(u[1]),
            "load_steps": len(steps), "failed_steps": sum(not ok for _, ok in h.steps),
            "step_ends": [round(t, 12) for t in steps],
            "its_per_step": _its_per_step(h), "factorizations": h.factorizations,
            "assemblies": h.assemblies, "linear": h.linear,
            "residual_rel": float(np.linalg.norm(g) / np.linalg.norm(tip_forces(mesh, tip)))}


def _its_per_step(history):
    ts = [it.t for it in history.iterations]
    return [ts.count(t) for t in sorted(set(ts))]


# ------------------------------------------------------------------ Kratos
KRATOS_DOFS = ("DISPLACEMENT_X", "DISPLACEMENT_Y", "DISPLACEMENT_Z", "ROTATION_X", "ROTATION_Y", "ROTATION_Z")
KRATOS_REACTIONS = ("REACTION_X", "REACTION_Y", "REACTION_Z",
                    "REACTION_MOMENT_X", "REACTION_MOMENT_Y", "REACTION_MOMENT_Z")


def import_kratos():
    try:
        import KratosMultiphysics as KM
        import KratosMultiphysics.LinearSolversApplication  # noqa: F401  (registers sparse_lu)
        import KratosMultiphysics.StructuralMechanicsApplication as SMA
    except ImportError as exc:
        raise SystemExit(f"bench/peers.py needs Kratos ({exc}); install the extra: pip install -e '.[peers]'")
    KM.Logger.GetDefaultOutput().SetSeverity(KM.Logger.Severity.WARNING)
    KM.ParallelUtilities.SetNumThreads(THREADS)
    return KM, SMA


def run_kratos(mesh, clamped, tip):
    KM, SMA = import_kratos()
    F = tip_forces(mesh, tip)
    t0, c0 = time.perf_counter(), time.process_time()
    model = KM.Model()
    mp = model.CreateModelPart("strip")
    mp.SetBufferSize(2)
    mp.ProcessInfo[KM.DOMAIN_SIZE] = 3
    for var in (KM.DISPLACEMENT, KM.ROTATION, KM.REACTION, KM.REACTION_MOMENT, SMA.POINT_LOAD):
        mp.AddNodalSolutionStepVariable(var)
    prop = mp.GetProperties()[1]
    prop.SetValue(KM.YOUNG_MODULUS, E)
    prop.SetValue(KM.POISSON_RATIO, NU)
    prop.SetValue(KM.THICKNESS, H)
    prop.SetValue(KM.DENSITY, 1.0)                  # required by the element's Check; static run
    prop.SetValue(KM.CONSTITUTIVE_LAW, SMA.LinearElasticPlaneStress2DLaw())
    for i, x in enumerate(mesh.vertices):
        mp.CreateNewNode(i + 1, *x)
    dofs = [getattr(KM, name) for name in KRATOS_DOFS]
    for dof, reaction in zip(dofs, KRATOS_REACTIONS):
        KM.VariableUtils().AddDof(dof, getattr(KM, reaction), mp)
    for e, tri in enumerate(mesh.triangles):
        mp.CreateNewElement("ShellThinElementCorotational3D3N", e + 1, [int(k) + 1 for k in tri], prop)
    for k in clamped:
        node = mp.Nodes[int(k) + 1]
        for dof in dofs:
            node.Fix(dof)
    for c, k in enumerate(tip):
        mp.CreateNewCondition("PointLoadCondition3D1N", c + 1, [int(k) + 1], prop)
    linear = KM.LinearSolverFactory().Create(KM.Parameters(json.dumps({"solver_type": KRATOS_LINEAR})))
    builder = KM.ResidualBasedBlockBuilderAndSolver(linear)
    scheme = KM.ResidualBasedIncrementalUpdateStaticScheme()
    criterion = KM.DisplacementCriteria(RTOL, 0.0)
    strategy = KM.ResidualBasedNewtonRaphsonStrategy(mp, scheme, criterion, builder, 40,
                                                     False, False, True)   # reactions, reform dofs, move mesh
    strategy.SetEchoLevel(0)
    strategy.Check()
    its = []
    for step in range(1, STEPS + 1):
        mp.CloneTimeStep(float(step))
        mp.ProcessInfo[KM.STEP] = step
        for c, k in enumerate(tip):
            mp.Nodes[int(k) + 1].SetSolutionStepValue(SMA.POINT_LOAD, 0, [0.0, 0.0, step / STEPS * F[c]])
        strategy.Solve()
        its.append(mp.ProcessInfo[KM.NL_ITERATION_NUMBER])
        if not strategy.IsConverged():
            raise RuntimeError(f"Kratos: load step {step} did not converge in 40 Newton iterations")
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    u = np.array([mp.Nodes[int(k) + 1].GetSolutionStepValue(KM.DISPLACEMENT) for k in tip]).mean(axis=0)
    # residual of the final state over the free DOFs (the block builder zeroes the fixed rows)
    b = strategy.GetSystemVector()
    KM.UblasSparseSpace().SetToZeroVector(b)
    builder.BuildRHS(scheme, mp, b)
    out = {"wall_s": wall, "cpu_s": cpu, "newton_its": int(sum(its)),
           "tip_u": float(u[0]), "tip_w": float(u[2]), "tip_v": float(u[1]),
           "load_steps": STEPS, "failed_steps": 0, "its_per_step": [int(i) for i in its],
           "linear": KRATOS_LINEAR,
           "residual_rel": float(np.linalg.norm(np.array(b)) / np.linalg.norm(F))}
    builder.Clear()
    strategy.Clear()
    return out


# ------------------------------------------------------------------ machine
def peer_machine_info():
    """bench/machine.py's record plus Kratos' build and threads."""
    from machine import machine_info
    KM, _ = import_kratos()
    info = machine_info(extra_libraries=("KratosMultiphysics", "KratosStructuralMechanicsApplication",
                                         "KratosLinearSolversApplication"))
    info.update(kratos_build=KM.KratosGlobals.Kernel.Version(),
                kratos_threads=KM.ParallelUtilities.GetNumThreads())
    return info


# ------------------------------------------------------------------ run
def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--quick", action="store_true", help="one repeat on 64 and 256 triangles")
    ap.add_argument("--membrane", choices=("dkt", "regge"), default="dkt",
                    help="shellritz's membrane metric (regge: written to peers_regge.*)")
    args = ap.parse_args()
    repeats = 1 if args.quick else args.repeats
    if repeats < 1:
        ap.error("--repeats must be at least 1")
    import numba
    numba.set_num_threads(THREADS)
    import_kratos()

    ref = {}
    for name, axial in (("elastica", 0.0), ("extensible_elastica", P / (E * B * H))):
        u, w, th = elastica(P * L ** 2 / (E * B * H ** 3 / 12), axial)
        ref[name] = {"tip_u": u * L, "tip_w": w * L, "tip_rotation": th}
    print(f"elastica: tip u = {ref['elastica']['tip_u']:.6f} (along x), w = {ref['elastica']['tip_w']:.6f} (z)")

    from shellritz.batch import prepare_kernels
    kernels_s, compiled = prepare_kernels(args.membrane)     # Numba: compile, or load from the disk cache
    warm = strip(*WARMUP)
    t = time.perf_counter()
    run_shellritz(*warm, membrane=args.membrane)
    compile_info = {"shellritz_kernels_s": kernels_s, "shellritz_kernels_compiled": compiled,
                    "warmup_mesh": f"{WARMUP[0]}x{WARMUP[1]}", "warmup_triangles": warm[0].n_triangles,
                    "shellritz_warmup_s": time.perf_counter() - t,
                    "kratos_warmup_s": run_kratos(*warm)["wall_s"]}
    print(f"kernels {'compiled' if compiled else 'loaded'} in {kernels_s:.1f} s; warm-up solves: shellritz "
          f"{compile_info['shellritz_warmup_s']:.1f} s, Kratos {compile_info['kratos_warmup_s']:.1f} s", flush=True)

    machine = peer_machine_info()
    runs, rows = [], []
    for nx, ny in CASES["quick" if args.quick else "full"]:
        mesh = strip(nx, ny)
        case = f"{nx}x{ny}"
        per_code = {code: [] for code in CODES}
        for r in range(repeats):
            for code, fn in (("shellritz", lambda *m: run_shellritz(*m, membrane=args.membrane)),
                             ("kratos", run_kratos),
                             ("shellritz-adaptive",
                              lambda *m: run_shellritz(*m, adaptive=True, membrane=args.membrane))):
                out = fn(*mesh)
                per_code[code].append(out)
                runs.append({"case": case, "code": code, "repeat": r, **out})
                print(f"{case:7s} {mesh[0].n_triangles:5d} triangles {code:18s} run {r}: {out['wall_s']:7.2f} s, "
                      f"{out['newton_its']} Newton its, tip u {out['tip_u']:.5f} w {out['tip_w']:.5f}", flush=True)
        for code, outs in per_code.items():
            last = outs[-1]
            wall = float(np.median([o["wall_s"] for o in outs]))
            rows.append({"case": case, "n_triangles": mesh[0].n_triangles, "code": code, "wall_s": wall,
                         "newton_its": last["newton_its"], "tip_u": last["tip_u"], "tip_w": last["tip_w"],
                         "err_u": last["tip_u"] / ref["elastica"]["tip_u"] - 1,
                         "err_w": last["tip_w"] / ref["elastica"]["tip_w"] - 1,
                         "s_per_newton_it": wall / last["newton_its"],
                         "cpu_s": float(np.median([o["cpu_s"] for o in outs])),
                         "load_steps": last["load_steps"], "its_per_step": last["its_per_step"],
                         "residual_rel": last["residual_rel"],
                         "newton_its_all_runs": sorted({o["newton_its"] for o in outs}),
                         "wall_s_runs": [o["wall_s"] for o in outs]})
    kratos_wall = {r["case"]: r["wall_s"] for r in rows if r["code"] == "kratos"}
    kratos_runs = {r["case"]: r["wall_s_runs"] for r in rows if r["code"] == "kratos"}
    for r in rows:
        r["wall_over_kratos"] = r["wall_s"] / kratos_wall[r["case"]]
        # each repeat runs the codes back to back: the median of the per-repeat
        # ratios sees each pair on the machine of its moment (this VM's speed
        # drifts by 10-30 % over minutes)
        r["wall_over_kratos_paired"] = float(np.median(np.divide(r["wall_s_runs"], kratos_runs[r["case"]])))
    machine["load_average_end"] = list(os.getloadavg())
    out = {
        "benchmark": "Sze et al. 2004 section 3.1: cantilever strip under end shear, shellritz vs Kratos",
        "problem": {"L": L, "b": B, "h": H, "E": E, "nu": NU, "P": P, "load_steps": STEPS,
                    "load": "dead, total P on the free edge x = L in +z, ramped linearly",
                    "mesh": "shapes.rectangle(nx, ny, lx=10, ly=1): nx x ny quads split by alternating "
                            "diagonals; identical vertices and triangles for both codes",
                    "tip": "mean displacement of the free-edge nodes"},
        "convention": "tip_u: displacement along the strip (x, horizontal, negative = shortening); "
                      "tip_w: displacement in the load direction (z, vertical deflection). The issue's "
                      "'6.700 / -3.289' is (w, u) in these names.",
        "reference": ref,
        "errors": "err_u, err_w relative to the (inextensible) elastica",
        "shellritz": {"law": "StVenantKirchhoff.from_young(1.2e6, 0.0)", "level": "consistent",
                      "membrane": args.membrane,
                      "solve": f"solve(steps={STEPS}, rtol={RTOL}, max_dt={1 / STEPS}) defaults: trust-region "
                               "Newton, linear='auto', predictor='tangent'; code shellritz-adaptive: without "
                               "max_dt (steps doubled after easy ones)",
                      "convergence": "|g| <= rtol max(|g| at step start, |load at t|) or a Newton correction "
                                     "at round-off"},
        "kratos": {"element": "ShellThinElementCorotational3D3N",
                   "law": "LinearElasticPlaneStress2DLaw (small strain in the corotated frame)",
                   "strategy": "ResidualBasedNewtonRaphsonStrategy, ResidualBasedIncrementalUpdateStaticScheme, "
                               "ResidualBasedBlockBuilderAndSolver, max 40 iterations per step",
                   "linear_solver": f"{KRATOS_LINEAR!r} of LinearSolversApplication: Eigen SparseLU (COLAMD "
                                    "ordering, analysis and factorization at every iteration); the wheel has no MKL, "
                                    "so no pardiso_lu/ldlt/llt; faster here than skyline_lu_factorization and "
                                    "sparse_qr (module docstring)",
                   "convergence": f"DisplacementCriteria({RTOL}, 0): |dx| <= {RTOL} |x| over the free DOFs "
                                  "(translations and rotations)",
                   "loads": "PointLoadCondition3D1N, trapezoid weights of P / b along the free edge"},
        "threads": THREADS, "repeats": repeats, "machine": machine, "compile": compile_info,
        "rows": rows, "runs": runs,
    }
    RESULTS.mkdir(exist_ok=True)
    name = ("peers_quick" if args.quick else "peers") + ("" if args.membrane == "dkt" else f"_{args.membrane}")
    (RESULTS / f"{name}.json").write_text(json.dumps(out, indent=2))
    chart(rows, RESULTS / f"{name}.png", machine)
    for r in rows:
        print(f"{r['case']:7s} {r['code']:18s} {r['wall_s']:7.2f} s ({r['wall_over_kratos']:.2f} x Kratos; "
              f"paired {r['wall_over_kratos_paired']:.2f})  "
              f"{r['newton_its']:3d} its  "
              f"err u {r['err_u']:+.2e} w {r['err_w']:+.2e}  residual/load {r['residual_rel']:.1e}")


def chart(rows, path, machine):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    cases = list(dict.fromkeys(r["case"] for r in rows))
    codes = CODES
    get = {(r["case"], r["code"]): r for r in rows}
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(10, 4))
    x = np.arange(len(cases))
    for j, code in enumerate(codes):
        rr = [get[c, code] for c in cases]
        bars = a1.bar(x + (j - 1) * 0.27, [r["wall_s"] for r in rr], 0.27,
                      label=f"{code} ({rr[0]['load_steps']} steps)")
        for b, r in zip(bars, rr):
            a1.annotate(f"{r['newton_its']} its", (b.get_x() + b.get_width() / 2, b.get_height()),
                        ha="center", va="bottom", fontsize=8)
        for k, (comp, marker) in enumerate((("err_u", "o"), ("err_w", "s"))):
            a2.semilogy(x + (j - 1) * 0.1, [abs(r[comp]) for r in rr], marker, ls="-",
                        color=f"C{j}", label=f"{code} {'u (x)' if comp == 'err_u' else 'w (z)'}",
                        mfc="none" if k else None)
    labels = [f"{c}\n{get[c, codes[0]]['n_triangles']} triangles" for c in cases]
    a1.set_xticks(x, labels)
    a1.set_ylabel(f"wall time (s, {machine['numba_threads']} threads, median)")
    a1.set_title("Sze cantilever, 10 load steps (adaptive: from 10)")
    a1.legend()
    a2.axhline(1e-3, color="gray", ls=":", lw=1)
    a2.annotate("0.1 %", (x[-1], 1e-3), fontsize=7, color="gray", va="bottom", ha="right")
    a2.set_xticks(x, labels)
    a2.set_ylabel("|tip displacement / elastica - 1|")
    a2.set_title("tip error against the elastica")
    a2.legend(fontsize=7)
    fig.suptitle(f"{machine['cpu']}, load average {machine['load_average'][0]:.1f}", fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)


if __name__ == "__main__":
    main()
