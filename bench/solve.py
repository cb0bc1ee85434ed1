"""Time to solution against accuracy (issue: general shells).

Two scenes with exact solutions, solved from the reference on 2 threads at
several mesh sizes; wall time (compile excluded: a warm-up solve runs first)
and the achieved error:

* strip: the gradient-growth strip rolled into a full circle (eq:x0z0asy),
  error = max distance of the nodes to the exact middle surface / radius;
* cylinder: growing cylinder under outer traction, quarter ring with symmetry
  planes, h = 0.1, error = |r0 - r0_exact| / r0_exact (eq:r0ex).

Writes bench/results/solve.json (rows: scene, n_triangles, wall_s, error) and
bench/results/solve.png.  Run:  python bench/solve.py
"""

import json
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent / "tests"))

from shellritz import CubicStretch, NeoHookean, Shell, shapes  # noqa: E402
from test_closed_forms import exact_cylinder_r0  # noqa: E402

RESULTS = HERE / "results"


def strip(nx):
    g0, g1, h = 1.2, 2.0, 0.02
    half = np.pi / g1
    mesh = shapes.rectangle(nx, 2, lx=half, ly=0.1, origin=(0, -0.05))
    s = Shell(mesh, h, NeoHookean(1.0, D=2.0))
    s.set_growth(G0=np.diag([g0, 1, 1]), G1=np.diag([g1, 0, 0]))
    s.symmetry("x", 0.0)
    s.pin(mesh.nodes_where(lambda X: (np.abs(X[:, 0]) < 1e-12) & (np.abs(X[:, 1]) < 1e-12)))
    s.pin(mesh.nodes_on_plane("x", 0.0), components="z")     # no rigid rotation about x
    t = time.perf_counter()
    res = s.solve(steps=8, verbose=False)
    wall = time.perf_counter() - t
    X = mesh.vertices
    x0 = g0 / g1 * np.sin(g1 * X[:, 0])
    z0 = g0 / g1 * (np.cos(g1 * X[:, 0]) - 1)
    err = np.sqrt((res.r[:, 0] - x0) ** 2 + (res.r[:, 2] - z0) ** 2 + (res.r[:, 1] - X[:, 1]) ** 2).max()
    return mesh.n_triangles, wall, err / (g0 / g1), len(res.history.iterations)


def cylinder(n):
    h, gamma, q = 0.1, 1.2, 0.3
    Lz = np.pi / 2 / n
    mesh = shapes.cylinder(n, 1, radius=1.0, length=Lz, theta=(0, np.pi / 2))
    s = Shell(mesh, h, CubicStretch(1.0))
    ez = np.array([0, 0, 1.0])
    s.set_growth(G0=gamma * (np.eye(3) - np.outer(ez, ez)) + np.outer(ez, ez))
    s.face_tractions(q_plus=lambda X, N: q * h * N)
    s.symmetry("x").symmetry("y").symmetry("z", 0.0).symmetry("z", Lz)
    t = time.perf_counter()
    res = s.solve(steps=4, verbose=False)
    wall = time.perf_counter() - t
    r0 = np.hypot(res.r[:, 0], res.r[:, 1]).mean()
    ex = exact_cylinder_r0(gamma, q * h, h)[2]
    return mesh.n_triangles, wall, abs(r0 - ex) / ex, len(res.history.iterations)


def main():
    import numba
    numba.set_num_threads(2)
    strip(10)
    cylinder(8)                              # compile / warm up
    rows = []
    for name, fn, sizes in (("strip", strip, (10, 20, 40, 80, 160)),
                            ("cylinder", cylinder, (16, 32, 64, 128, 256, 512))):
        for n in sizes:
            ne, wall, err, its = fn(n)
            rows.append({"scene": name, "n_triangles": ne, "wall_s": wall, "error": err,
                         "newton_iterations": its})
            print(f"{name:8s} {ne:6d} triangles: {wall:7.2f} s, error {err:.2e}, {its} iterations",
                  flush=True)
    RESULTS.mkdir(exist_ok=True)
    (RESULTS / "solve.json").write_text(json.dumps({"threads": 2, "rows": rows}, indent=2))
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(6, 4))
    for name in ("strip", "cylinder"):
        rr = [r for r in rows if r["scene"] == name]
        ax.loglog([r["wall_s"] for r in rr], [r["error"] for r in rr], "o-", label=name)
        for r in rr:
            ax.annotate(str(r["n_triangles"]), (r["wall_s"], r["error"]), fontsize=7)
    ax.set_xlabel("wall time to solution (s, 2 threads)")
    ax.set_ylabel("relative error")
    ax.set_title("DKT engine: accuracy against cost")
    ax.legend()
    fig.tight_layout()
    fig.savefig(RESULTS / "solve.png", dpi=110)


if __name__ == "__main__":
    main()
