"""The linear shell obstacle course (MacNeal & Harder 1985; Belytschko et al.
1985) at small loads, and a membrane-locking study.

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

Locking study: cylindrical panel R = 1, +-40 degrees, length 2, clamped along
one straight generator, uniform normal load; the compliance C t^3 (C = f.u)
against its mesh-converged value, for t/R = 1e-2, 1e-3, 1e-4.

Writes bench/results/obstacle.json, bench/results/obstacle.png,
bench/results/locking.json, bench/results/locking.png.
Run:  python bench/obstacle.py [--quick]
"""

import argparse
import json
import time
from pathlib import Path

import numpy as np

from shellritz import LinearIsotropic, Shell, shapes

RESULTS = Path(__file__).resolve().parent / "results"
SCALE = {"roof": 1e-3, "cylinder": 1.0, "hemisphere": 1e-2, "panel": 1e-3}


def lame(E, nu):
    return LinearIsotropic(E * nu / ((1 + nu) * (1 - 2 * nu)), E / (2 * (1 + nu)))


def scordelis_lo(n):
    R, L, t = 25.0, 50.0, 0.25
    mesh = shapes.cylinder(n, n, radius=R, length=L / 2, theta=(np.pi / 2, np.pi / 2 + np.radians(40)))
    s = Shell(mesh, t, lame(4.32e8, 0.0))
    s.symmetry("x", 0.0).symmetry("z", L / 2)
    s.diaphragm(mesh.nodes_on_plane("z", 0.0), "z")
    g = np.array([0.0, -90.0 * SCALE["roof"] / 2, 0.0])      # gravity split over both faces
    s.face_tractions(q_plus=g, q_minus=g)
    res = s.solve(verbose=False)
    X = mesh.vertices
    k = np.argmin(np.linalg.norm(X - [R * np.cos(np.pi / 2 + np.radians(40)),
                                      R * np.sin(np.pi / 2 + np.radians(40)), L / 2], axis=1))
    return -res.displacement[k, 1] / SCALE["roof"], 0.3024, mesh.n_triangles


def pinched_cylinder(n):
    R, L, t = 300.0, 600.0, 3.0
    mesh = shapes.cylinder(n, n, radius=R, length=L / 2, theta=(0, np.pi / 2))
    s = Shell(mesh, t, lame(3e6, 0.3))
    s.symmetry("x", 0.0).symmetry("y", 0.0).symmetry("z", L / 2)
    s.diaphragm(mesh.nodes_on_plane("z", 0.0), "z")
    k = np.argmin(np.linalg.norm(mesh.vertices - [0, R, L / 2], axis=1))
    s.point_force([k], [0, -SCALE["cylinder"] / 4, 0])
    res = s.solve(verbose=False)
    return -res.displacement[k, 1] / SCALE["cylinder"], 1.8248e-5, mesh.n_triangles


def pinched_hemisphere(n):
    R, t = 10.0, 0.04
    mesh = shapes.hemisphere(n, n, radius=R, hole_deg=18.0, phi=(0, np.pi / 2))
    s = Shell(mesh, t, lame(6.825e7, 0.3))
    s.symmetry("x", 0.0).symmetry("y", 0.0)
    X = mesh.vertices
    kx = np.argmin(np.linalg.norm(X - [R, 0, 0], axis=1))
    ky = np.argmin(np.linalg.norm(X - [0, R, 0], axis=1))
    F = SCALE["hemisphere"]                        # 1.0 on each point of the quarter
    s.point_force([kx], [F, 0, 0]).point_force([ky], [0, -F, 0])
    res = s.solve(verbose=False)
    return res.displacement[kx, 0] / F, 0.0924, mesh.n_triangles


def locking_panel(n, t):
    """C E t^3 / q^2 (t-independent when bending dominates); E = t^-3 keeps the
    bending stiffness O(1) and the arithmetic well scaled."""
    mesh = shapes.cylinder(n, n, radius=1.0, length=2.0, theta=(-np.radians(40), np.radians(40)))
    s = Shell(mesh, t, lame(t ** -3, 0.0))
    s.clamp(mesh.nodes_where(lambda X: np.abs(np.arctan2(X[:, 1], X[:, 0]) + np.radians(40)) < 1e-9))
    q = SCALE["panel"]                             # deflection ~ SCALE: linear response
    s.face_tractions(q_plus=lambda X, N: -q * N / 2, q_minus=lambda X, N: -q * N / 2)
    res = s.solve(verbose=False)
    return float(np.sum(s._f_faces * res.displacement)) / q ** 2


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true")
    args = ap.parse_args()
    RESULTS.mkdir(exist_ok=True)
    ns = [4, 8, 16, 32] if args.quick else [4, 8, 16, 32, 64]
    out = {}
    for name, fn in (("Scordelis-Lo roof", scordelis_lo), ("pinched cylinder", pinched_cylinder),
                     ("pinched hemisphere", pinched_hemisphere)):
        rows = []
        for n in ns:
            t0 = time.perf_counter()
            u, ref, ne = fn(n)
            rows.append({"n": n, "n_triangles": ne, "displacement": u, "reference": ref,
                         "normalized": u / ref, "wall_s": time.perf_counter() - t0})
            print(f"{name:20s} n={n:3d} ({ne:6d} triangles): {u:.5g} / {ref:.5g} = {u / ref:.4f}",
                  flush=True)
        out[name] = rows
    (RESULTS / "obstacle.json").write_text(json.dumps(out, indent=2))
    lock = {}
    lns = [4, 8, 16, 32] if args.quick else [4, 8, 16, 32, 64, 128]
    for t in (1e-2, 1e-3, 1e-4):
        vals = [locking_panel(n, t) for n in lns]
        lock[str(t)] = {"n": lns, "Ct3": vals}
        print(f"locking t/R={t:g}: " + ", ".join(f"{v:.4g}" for v in vals), flush=True)
    ref = lock["0.01"]["Ct3"][-1]
    for key in lock:
        lock[key]["normalized"] = [v / ref for v in lock[key]["Ct3"]]
    (RESULTS / "locking.json").write_text(json.dumps(lock, indent=2))
    charts(out, lock)


def charts(out, lock):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(6, 4))
    for name, rows in out.items():
        ax.semilogx([r["n_triangles"] for r in rows], [r["normalized"] for r in rows], "o-", label=name)
    ax.axhline(1.0, color="k", lw=1)
    ax.set_xlabel("triangles (symmetric part)")
    ax.set_ylabel("displacement / reference")
    ax.set_title("linear obstacle course")
    ax.legend()
    fig.tight_layout()
    fig.savefig(RESULTS / "obstacle.png", dpi=110)
    fig, ax = plt.subplots(figsize=(6, 4))
    for key, d in lock.items():
        ax.semilogx(d["n"], d["normalized"], "o-", label=f"t/R = {float(key):g}")
    ax.axhline(1.0, color="k", lw=1)
    ax.set_xlabel("elements along the generator")
    ax.set_ylabel("C E t^3 / q^2, relative to the converged t/R = 1e-2 value")
    ax.set_title("membrane locking, clamped cylindrical panel")
    ax.legend()
    fig.tight_layout()
    fig.savefig(RESULTS / "locking.png", dpi=110)


if __name__ == "__main__":
    main()
