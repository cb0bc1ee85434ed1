"""The linear shell obstacle course (MacNeal & Harder 1985; Belytschko et al.
1985) at small loads, and a membrane-locking study, for both membrane metrics
of the triangle engine (``Shell(membrane="dkt" | "regge")``, README: Membrane
locking).

* Scordelis-Lo roof: R = 25, L = 50, t = 0.25, E = 4.32e8, nu = 0, rigid
  diaphragms, gravity 90 per unit area; vertical displacement at the midspan
  of the free edge, reference 0.3024.
* Pinched cylinder with diaphragms: R = 300, L = 600, t = 3, E = 3e6,
  nu = 0.3, P = 1; radial displacement under the load, reference 1.8248e-5.
* Pinched hemisphere with an 18 degree hole: R = 10, t = 0.04, E = 6.825e7,
  nu = 0.3, F = 1 at each load point of the quarter model (F = 2 on the whole
  hemisphere, as in MacNeal & Harder); displacement under the load, reference
  0.0924.

Symmetric parts (quarter/octant) of each are meshed with n x n elements.  The
model is the geometrically exact consistent shell with the linear isotropic
law; loads are scaled down (displacements rescaled) to stay linear.

Locking study: cylindrical panel R = 1, +-40 degrees, length 2, uniform normal
load, linear response (tangent stiffness at the reference), E = t^-3 (bending
stiffness O(1)), for t/R = 1e-2, 1e-3, 1e-4:
  - clamped along one straight generator: bending dominated, C E t^3 / q^2
    (C = f.u the compliance) tends to a t-independent limit;
  - clamped along one curved edge: membrane dominated (no inextensional
    motion), C E t^3 / q^2 depends on t; the cure must converge to the same
    answer as the DKT metric (the rejected attempt in shared/notes did not).

Large load (--large-load): the pinched hemisphere at F = 100 per load point
(St Venant-Kirchhoff, same constants; strongly nonlinear), both metrics,
the finest DKT mesh standing in for the converged answer.

Fine reference (--fine): the membrane-dominated panel at n = 256 for
t/R = 1e-3 and 1e-4 and the pinched cylinder at n = 256, both metrics
(about 7 minutes).  Cost (--cost): the
energy, gradient and Hessian assembly times of both metrics on one mesh.
Leaf (--leaf): the default scene (the grown disc buckling into a saddle) at
16, 32, 64 rings, both metrics: energy and saddle height against the mesh.
Anisotropic (--aniso): the bending-dominated panel on meshes of long thin
elements, both metrics.

Writes bench/results/obstacle.json, obstacle.png, locking.json, locking.png
(with the machine), hemisphere_large_load.json, locking_fine.json,
membrane_cost.json, leaf_membrane.json or locking_aniso.json.
Run:  python bench/obstacle.py [--quick] [--large-load] [--fine] [--cost] [--leaf] [--aniso]
(quick: n <= 16 / 32, a few minutes once compiled).
"""

import argparse
import json
import time
from pathlib import Path

import numpy as np

from machine import machine_info
from shellritz import LinearIsotropic, Shell, StVenantKirchhoff, shapes

RESULTS = Path(__file__).resolve().parent / "results"
SCALE = {"roof": 1e-3, "cylinder": 1.0, "hemisphere": 1e-2}


def lame(E, nu):
    return LinearIsotropic(E * nu / ((1 + nu) * (1 - 2 * nu)), E / (2 * (1 + nu)))


def scordelis_lo(n, membrane="dkt"):
    R, L, t = 25.0, 50.0, 0.25
    mesh = shapes.cylinder(n, n, radius=R, length=L / 2, theta=(np.pi / 2, np.pi / 2 + np.radians(40)))
    s = Shell(mesh, t, lame(4.32e8, 0.0), membrane=membrane)
    s.symmetry("x", 0.0).symmetry("z", L / 2)
    s.diaphragm(mesh.nodes_on_plane("z", 0.0), "z")
    g = np.array([0.0, -90.0 * SCALE["roof"] / 2, 0.0])      # gravity split over both faces
    s.face_tractions(q_plus=g, q_minus=g)
    res = s.solve(verbose=False)
    X = mesh.vertices
    k = np.argmin(np.linalg.norm(X - [R * np.cos(np.pi / 2 + np.radians(40)),
                                      R * np.sin(np.pi / 2 + np.radians(40)), L / 2], axis=1))
    return -res.displacement[k, 1] / SCALE["roof"], 0.3024, mesh.n_triangles


def pinched_cylinder(n, membrane="dkt"):
    R, L, t = 300.0, 600.0, 3.0
    mesh = shapes.cylinder(n, n, radius=R, length=L / 2, theta=(0, np.pi / 2))
    s = Shell(mesh, t, lame(3e6, 0.3), membrane=membrane)
    s.symmetry("x", 0.0).symmetry("y", 0.0).symmetry("z", L / 2)
    s.diaphragm(mesh.nodes_on_plane("z", 0.0), "z")
    k = np.argmin(np.linalg.norm(mesh.vertices - [0, R, L / 2], axis=1))
    s.point_force([k], [0, -SCALE["cylinder"] / 4, 0])
    res = s.solve(verbose=False)
    return -res.displacement[k, 1] / SCALE["cylinder"], 1.8248e-5, mesh.n_triangles


def pinched_hemisphere(n, membrane="dkt"):
    R, t = 10.0, 0.04
    mesh = shapes.hemisphere(n, n, radius=R, hole_deg=18.0, phi=(0, np.pi / 2))
    s = Shell(mesh, t, lame(6.825e7, 0.3), membrane=membrane)
    s.symmetry("x", 0.0).symmetry("y", 0.0)
    X = mesh.vertices
    kx = np.argmin(np.linalg.norm(X - [R, 0, 0], axis=1))
    ky = np.argmin(np.linalg.norm(X - [0, R, 0], axis=1))
    F = SCALE["hemisphere"]                        # 1.0 on each point of the quarter
    s.point_force([kx], [F, 0, 0]).point_force([ky], [0, -F, 0])
    res = s.solve(verbose=False)
    return res.displacement[kx, 0] / F, 0.0924, mesh.n_triangles


def hemisphere_large_load(n, membrane="dkt", F=100.0, steps=10):
    """The pinched hemisphere of the obstacle course at a large load (F on
    each loaded point of the quarter; linear response would be 9.2, about R):
    St Venant-Kirchhoff law with the same Lame constants, continuation in
    `steps` steps.  Returns (outward u_A, inward u_B, triangles)."""
    R, t = 10.0, 0.04
    mesh = shapes.hemisphere(n, n, radius=R, hole_deg=18.0, phi=(0, np.pi / 2))
    law = lame(6.825e7, 0.3)
    s = Shell(mesh, t, StVenantKirchhoff(*law.params), membrane=membrane)
    s.symmetry("x", 0.0).symmetry("y", 0.0)
    X = mesh.vertices
    kx = np.argmin(np.linalg.norm(X - [R, 0, 0], axis=1))
    ky = np.argmin(np.linalg.norm(X - [0, R, 0], axis=1))
    s.point_force([kx], [F, 0, 0]).point_force([ky], [0, -F, 0])
    res = s.solve(steps=steps, verbose=False)
    return float(res.displacement[kx, 0]), float(-res.displacement[ky, 1]), mesh.n_triangles


def large_load(quick):
    """bench/results/hemisphere_large_load.json: the finest DKT mesh is the
    stand-in for the converged answer."""
    runs = [(8, "dkt"), (8, "regge"), (16, "dkt"), (16, "regge")] if quick else \
        [(16, "dkt"), (16, "regge"), (32, "dkt"), (32, "regge"), (64, "dkt"), (64, "regge")]
    rows = []
    for n, membrane in runs:
        t0 = time.perf_counter()
        ua, ub, ne = hemisphere_large_load(n, membrane)
        rows.append({"n": n, "membrane": membrane, "n_triangles": ne, "u_A_outward": ua,
                     "u_B_inward": ub, "wall_s": time.perf_counter() - t0})
        print(f"large-load hemisphere {membrane:5s} n={n:3d}: u_A {ua:.5g}, u_B {ub:.5g}", flush=True)
    out = {"machine": machine_info(), "F": 100.0, "law": "StVenantKirchhoff, E 6.825e7, nu 0.3",
           "runs": rows}
    (RESULTS / "hemisphere_large_load.json").write_text(json.dumps(out, indent=2))


def locking_panel(n, t, membrane="dkt", clamp="generator", n_z=None):
    """C E t^3 / q^2 of the cylindrical panel clamped along a straight
    generator (bending dominated) or a curved edge (membrane dominated), by a
    linear solve at the reference (the tangent stiffness; a Newton solve of a
    load small enough to stay linear for t/R = 1e-4 is below the solver's
    round-off floor, the membrane stiffness being 1e8 times the bending one).
    E = t^-3 keeps the bending stiffness O(1) and the arithmetic well scaled.
    The solve: the product's direct solver (linalg, method "auto").  n
    elements along the arc, n_z (default n) along the length."""
    from shellritz.linalg import make_linear_solver
    mesh = shapes.cylinder(n, n if n_z is None else n_z, radius=1.0, length=2.0,
                           theta=(-np.radians(40), np.radians(40)))
    s = Shell(mesh, t, lame(t ** -3, 0.0), membrane=membrane)
    if clamp == "generator":
        edge = lambda X: np.abs(np.arctan2(X[:, 1], X[:, 0]) + np.radians(40)) < 1e-9
    else:
        edge = lambda X: X[:, 2] < 1e-9
    s.clamp(mesh.nodes_where(edge))
    s.face_tractions(q_plus=lambda X, N: -N / 2, q_minus=lambda X, N: -N / 2)   # q = 1
    s._setup()
    s.set_parameter(1.0)
    _, g, K = s.evaluate(s.free_state(), 2)      # g = -f at the stress-free reference (K: lower CSR)
    solver = make_linear_solver("auto", K.shape[0], K.indptr, K.indices)
    try:
        negative = solver.factorize(K)
        if negative:
            raise RuntimeError(f"the panel's stiffness has {negative} negative eigenvalues")
        return float(g @ solver.solve(g))
    finally:
        solver.release()


ANISO = ((8, 8), (8, 32), (8, 64), (16, 64), (64, 16), (64, 8))


def anisotropic():
    """bench/results/locking_aniso.json: the bending-dominated panel on
    meshes of n_arc x n_z elements (long thin elements either way), both
    metrics, t/R = 1e-3 and 1e-4, relative to the converged value."""
    out = {"machine": machine_info(), "converged": 5.047, "rows": []}
    for t in THICKNESS[1:]:
        for n, nz in ANISO:
            row = {"t": t, "n_arc": n, "n_z": nz}
            for membrane in MEMBRANES:
                row[membrane] = locking_panel(n, t, membrane, n_z=nz) / out["converged"]
            out["rows"].append(row)
            print(f"t/R={t:g} {n:3d} x {nz:3d}: dkt {row['dkt']:.4f}, regge {row['regge']:.4f}", flush=True)
    (RESULTS / "locking_aniso.json").write_text(json.dumps(out, indent=2))


def fine_reference():
    """bench/results/locking_fine.json: the membrane-dominated panel at n = 256
    (131k triangles) for t/R = 1e-3 and 1e-4, both metrics: where the DKT
    metric no longer locks much at 1e-3, the converged value the coarse
    meshes are judged against; and the pinched cylinder at n = 256, both
    metrics (displacement / classical reference): where the two converge."""
    out = {"n": 256, "curved": {}, "pinched_cylinder": {}}
    for membrane in MEMBRANES:
        t0 = time.perf_counter()
        u, ref, _ = pinched_cylinder(256, membrane)
        out["pinched_cylinder"][membrane] = u / ref
        print(f"pinched cylinder {membrane:5s} n=256: {u / ref:.6f} ({time.perf_counter() - t0:.0f} s)",
              flush=True)
    for membrane in MEMBRANES:
        out["curved"][membrane] = {}
        for t in (1e-3, 1e-4):
            t0 = time.perf_counter()
            v = locking_panel(256, t, membrane, "curved")
            out["curved"][membrane][str(t)] = v
            print(f"curved    {membrane:5s} t/R={t:g} n=256: {v:.6g} ({time.perf_counter() - t0:.0f} s)",
                  flush=True)
    out = {"machine": machine_info(), **out}
    (RESULTS / "locking_fine.json").write_text(json.dumps(out, indent=2))


MEMBRANES = Shell.MEMBRANES
THICKNESS = (1e-2, 1e-3, 1e-4)


def leaf(rings, membrane):
    """The default scene (meshes/leaf.toml: a disc grown by 1 + 0.3 rho^2
    buckles into a saddle, h = 0.02) on shapes.disc(rings) with the given
    membrane metric, solved as the scene says.  Returns a dict."""
    from importlib.resources import files
    from shellritz.meshdata import Surface
    from shellritz.scenefile import load_scene
    scene = load_scene(files("shellritz.meshes") / "leaf.toml")
    surf = Surface(shapes.disc(rings))
    shell = scene.build(surf, membrane=membrane)[0]
    t0 = time.perf_counter()
    res = scene.solve(surf, shell)
    z = res.r[:, 2]
    return {"rings": rings, "n_triangles": shell.mesh.n_triangles, "membrane": shell.membrane,
            "energy": res.energy, "z_max": float(z.max()), "z_min": float(z.min()),
            "newton_its": len(res.history.iterations), "stable": res.history.stable,
            "converged": res.converged, "wall_s": time.perf_counter() - t0}


def leaf_study():
    """bench/results/leaf_membrane.json: the default leaf's energy and saddle
    height against the mesh, both metrics."""
    rows = []
    for rings in (16, 32, 64):
        for membrane in MEMBRANES:
            rows.append(leaf(rings, membrane))
            r = rows[-1]
            print(f"leaf {rings:3d} rings ({r['n_triangles']:6d} triangles) {membrane:5s}: "
                  f"energy {r['energy']:.5g}, z {r['z_min']:.5f} / {r['z_max']:.5f}, "
                  f"{r['newton_its']} Newton, stable {r['stable']}, {r['wall_s']:.1f} s", flush=True)
    out = {"machine": machine_info(), "rows": rows}
    (RESULTS / "leaf_membrane.json").write_text(json.dumps(out, indent=2))


def membrane_cost(rings=40, repeats=5):
    """bench/results/membrane_cost.json: the energy, gradient and Hessian
    assembly of both metrics on the same mesh (a disc of `rings` rings,
    in-plane growth, a perturbed state), medians of `repeats` in one process
    after a first call whose time (compilation included) is reported apart."""
    mesh = shapes.disc(rings)
    out = {"n_triangles": mesh.n_triangles, "repeats": repeats, "metrics": {}}
    for membrane in MEMBRANES:
        s = Shell(mesh, 0.01, lame(1.0, 0.3), membrane=membrane)
        s.set_growth(G0=np.diag([1.1, 1.05, 1.0]))
        s._setup()
        s.set_parameter(1.0)
        x = s.free_state() + 1e-3 * np.random.default_rng(0).standard_normal(len(s.free))
        t0 = time.perf_counter()
        s.evaluate(x, 2)
        first = time.perf_counter() - t0
        times = {0: [], 1: [], 2: []}
        for _ in range(repeats):
            for mode in times:
                t0 = time.perf_counter()
                s.evaluate(x, mode)
                times[mode].append(time.perf_counter() - t0)
        out["metrics"][membrane] = {"first_hessian_s": first,
                                    **{f"{k}_s": float(np.median(times[m]))
                                       for m, k in ((0, "energy"), (1, "gradient"), (2, "hessian"))}}
        print(membrane, out["metrics"][membrane], flush=True)
    out["regge_over_dkt"] = {k: out["metrics"]["regge"][k] / out["metrics"]["dkt"][k]
                             for k in ("energy_s", "gradient_s", "hessian_s")}
    print("regge / dkt:", out["regge_over_dkt"])
    out = {"machine": machine_info(), **out}
    (RESULTS / "membrane_cost.json").write_text(json.dumps(out, indent=2))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--large-load", action="store_true",
                    help="only the pinched hemisphere at a large load (both metrics)")
    ap.add_argument("--fine", action="store_true",
                    help="only the membrane-dominated panel and the pinched cylinder at n = 256 (both metrics)")
    ap.add_argument("--aniso", action="store_true",
                    help="only the bending-dominated panel on anisotropic meshes (both metrics)")
    ap.add_argument("--cost", action="store_true",
                    help="only the assembly time of both metrics on one mesh")
    ap.add_argument("--leaf", action="store_true",
                    help="only the default leaf at 16, 32, 64 rings (both metrics)")
    args = ap.parse_args()
    RESULTS.mkdir(exist_ok=True)
    if args.cost:
        return membrane_cost()
    if args.aniso:
        return anisotropic()
    if args.leaf:
        return leaf_study()
    if args.large_load:
        return large_load(args.quick)
    if args.fine:
        return fine_reference()
    ns = [4, 8, 16] if args.quick else [4, 8, 16, 32, 64, 128]
    out = {"courses": {}}
    for name, fn in (("Scordelis-Lo roof", scordelis_lo), ("pinched cylinder", pinched_cylinder),
                     ("pinched hemisphere", pinched_hemisphere)):
        out["courses"][name] = {}
        for membrane in MEMBRANES:
            rows = []
            for n in ns:
                t0 = time.perf_counter()
                u, ref, ne = fn(n, membrane)
                rows.append({"n": n, "n_triangles": ne, "displacement": u, "reference": ref,
                             "normalized": u / ref, "wall_s": time.perf_counter() - t0})
                print(f"{name:20s} {membrane:5s} n={n:3d} ({ne:6d} triangles): "
                      f"{u:.5g} / {ref:.5g} = {u / ref:.4f}", flush=True)
            out["courses"][name][membrane] = rows
    out = {"machine": machine_info(), **out}       # after the kernels ran (machine.py)
    (RESULTS / "obstacle.json").write_text(json.dumps(out, indent=2))
    lns = [4, 8, 16, 32] if args.quick else [4, 8, 16, 32, 64, 128]
    lock = {"machine": out["machine"], "n": lns, "generator": {}, "curved": {}}
    for clamp in ("generator", "curved"):
        for membrane in MEMBRANES:
            lock[clamp][membrane] = {}
            for t in THICKNESS:
                vals = [locking_panel(n, t, membrane, clamp) for n in lns]
                lock[clamp][membrane][str(t)] = vals
                print(f"{clamp:9s} {membrane:5s} t/R={t:g}: " + ", ".join(f"{v:.4g}" for v in vals),
                      flush=True)
    # bending dominated: relative to the finest t/R = 1e-2 value (both metrics agree there)
    lock["generator_reference"] = lock["generator"]["dkt"]["0.01"][-1]
    (RESULTS / "locking.json").write_text(json.dumps(lock, indent=2))
    charts(out, lock)


def charts(out, lock):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    style = {"dkt": "--", "regge": "-"}
    fig, ax = plt.subplots(figsize=(6.5, 4.2))
    for k, (name, by) in enumerate(out["courses"].items()):
        for membrane, rows in by.items():
            ax.semilogx([r["n"] for r in rows], [r["normalized"] for r in rows], "o" + style[membrane],
                        color=f"C{k}", label=f"{name} ({membrane})")
    ax.axhline(1.0, color="k", lw=1)
    ax.set_xlabel("elements per side (symmetric part)")
    ax.set_ylabel("displacement / reference")
    ax.set_title("linear obstacle course: dashed DKT metric, solid regge")
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(RESULTS / "obstacle.png", dpi=110)
    fig, axs = plt.subplots(1, 2, figsize=(11, 4.2))
    ref = lock["generator_reference"]
    for k, t in enumerate(THICKNESS):
        for membrane in MEMBRANES:
            axs[0].semilogx(lock["n"], np.array(lock["generator"][membrane][str(t)]) / ref,
                            "o" + style[membrane], color=f"C{k}", label=f"t/R = {t:g} ({membrane})")
            axs[1].loglog(lock["n"], lock["curved"][membrane][str(t)], "o" + style[membrane],
                          color=f"C{k}", label=f"t/R = {t:g} ({membrane})")
    axs[0].axhline(1.0, color="k", lw=1)
    axs[0].set_ylabel("C E t^3 / q^2, relative to the converged value")
    axs[0].set_title("bending dominated: clamped along a generator")
    axs[1].set_ylabel("C E t^3 / q^2")
    axs[1].set_title("membrane dominated: clamped along a curved edge")
    for ax in axs:
        ax.set_xlabel("elements per side")
        ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(RESULTS / "locking.png", dpi=110)


if __name__ == "__main__":
    main()
