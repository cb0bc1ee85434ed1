"""Time to solution against accuracy of the DKT triangle engine (issue:
general shells).

Two scenes with exact solutions, solved from the reference by the default
solver (`Shell.solve`: trust-region Newton, direct linear solver) at several
mesh sizes:

* strip: the gradient-growth strip rolled into a full circle (eq:x0z0asy),
  nx = 10 ... 160 (4 nx triangles), 8 initial continuation steps;
  error = max distance of the nodes to the exact middle surface / radius;
* cylinder: growing cylinder under outer traction, quarter ring with symmetry
  planes, h = 0.1, n = 16 ... 512 (2 n triangles), 4 initial continuation
  steps; error = |r0 - r0_exact| / r0_exact (eq:r0ex), r0 the mean radius of
  the nodes.

Measured per mesh: the wall time of `solve()` (model set-up excluded), median
of --repeats runs, each on a freshly built model; and a machine-independent
cost: one Hessian assembly of that mesh at the solution (median of the
calls of `shell.evaluate(shell.free_state(), 2)` timed after every run, at
least 3 and 0.3 s per run), the solve in such assemblies
(`solve_in_assemblies = wall_s / assembly_s`), and from the solver history
the Newton iterations, factorizations and Hessian assemblies it took.
Compile time is excluded: warm-up solves run first (the strip at 40
triangles, the cylinder at 16 and at 64, where its elements are shorter than
h and the strain-gradient kernels come in; with an empty Numba cache the
warm-up compiles for about 2 minutes).  2 threads: OMP_NUM_THREADS,
NUMBA_NUM_THREADS and MKL_NUM_THREADS are set before numpy and numba load,
plus numba.set_num_threads; the machine (CPU, library versions, thread
settings, load average) is recorded, and the load average per row.

Writes bench/results/solve.json ("machine", "threads", "repeats",
"warmup_s", "source" (the shellritz that ran: path, repository commit,
uncommitted files under src/) and "rows": scene, size, n_triangles, dofs, wall_s (median),
wall_runs_s (all runs), assembly_s, assembly_calls, solve_in_assemblies, newton_its
(trust-region iterations, rejected steps included), factorizations,
assemblies, load_steps, failed_steps, escapes, linear, stable,
strain_gradient, error, load_average) and bench/results/solve.png (error
against wall time, log-log, annotated with the triangle counts).  --quick:
the two smallest meshes of each scene, one run, written to solve_quick.json
/ solve_quick.png (the full run's files are left alone).

Run:  python bench/solve.py [--repeats 3] [--quick]        (full: ~2 min with the Numba cache warm)
"""

import os

THREADS = 2
for _var in ("OMP_NUM_THREADS", "NUMBA_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = str(THREADS)      # before numpy, numba and MKL load

import argparse  # noqa: E402
import json  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent / "tests"))     # test_closed_forms (exact cylinder)
sys.path.insert(0, str(HERE))                      # machine.py

from machine import machine_info  # noqa: E402
from shellritz import CubicStretch, NeoHookean, Shell, shapes  # noqa: E402
from test_closed_forms import exact_cylinder_r0  # noqa: E402

RESULTS = HERE / "results"
SIZES = {"strip": (10, 20, 40, 80, 160), "cylinder": (16, 32, 64, 128, 256, 512)}
# compile / warm up: both scenes, and a cylinder whose elements are shorter than h
# (the strain-gradient kernels, which the 32-triangle cylinder does not use)
WARMUP = (("strip", 10), ("cylinder", 8), ("cylinder", 32))
ASSEMBLY_CALLS = 3          # per run: at least 3 calls and 0.3 s
ASSEMBLY_MIN_S = 0.3


def strip(nx):
    """The model, its continuation steps and the error of a solution."""
    g0, g1, h = 1.2, 2.0, 0.02
    half = np.pi / g1
    mesh = shapes.rectangle(nx, 2, lx=half, ly=0.1, origin=(0, -0.05))
    s = Shell(mesh, h, NeoHookean(1.0, D=2.0))
    s.set_growth(G0=np.diag([g0, 1, 1]), G1=np.diag([g1, 0, 0]))
    s.symmetry("x", 0.0)
    s.pin(mesh.nodes_where(lambda X: (np.abs(X[:, 0]) < 1e-12) & (np.abs(X[:, 1]) < 1e-12)))
    s.pin(mesh.nodes_on_plane("x", 0.0), components="z")     # no rigid rotation about x

    def error(res):
        X = mesh.vertices
        x0 = g0 / g1 * np.sin(g1 * X[:, 0])
        z0 = g0 / g1 * (np.cos(g1 * X[:, 0]) - 1)
        d = np.sqrt((res.r[:, 0] - x0) ** 2 + (res.r[:, 2] - z0) ** 2 + (res.r[:, 1] - X[:, 1]) ** 2)
        return float(d.max() / (g0 / g1))

    return s, 8, error


def cylinder(n):
    h, gamma, q = 0.1, 1.2, 0.3
    Lz = np.pi / 2 / n
    mesh = shapes.cylinder(n, 1, radius=1.0, length=Lz, theta=(0, np.pi / 2))
    s = Shell(mesh, h, CubicStretch(1.0))
    ez = np.array([0, 0, 1.0])
    s.set_growth(G0=gamma * (np.eye(3) - np.outer(ez, ez)) + np.outer(ez, ez))
    s.face_tractions(q_plus=lambda X, N: q * h * N)
    s.symmetry("x").symmetry("y").symmetry("z", 0.0).symmetry("z", Lz)

    def error(res):
        r0 = np.hypot(res.r[:, 0], res.r[:, 1]).mean()
        ex = exact_cylinder_r0(gamma, q * h, h)[2]
        return float(abs(r0 - ex) / ex)

    return s, 4, error


SCENES = {"strip": strip, "cylinder": cylinder}


def solve_once(scene, size):
    shell, steps, error = SCENES[scene](size)
    t = time.perf_counter()
    res = shell.solve(steps=steps, verbose=False)
    return shell, res, time.perf_counter() - t, error(res)


def time_assembly(shell, times):
    """Append the times of Hessian assemblies at the current state: at least
    ASSEMBLY_CALLS calls and ASSEMBLY_MIN_S seconds (a few milliseconds
    each on the small meshes: one call would catch the machine's noise)."""
    x = shell.free_state()
    start, calls = time.perf_counter(), 0
    while calls < ASSEMBLY_CALLS or (time.perf_counter() - start < ASSEMBLY_MIN_S and calls < 500):
        t = time.perf_counter()
        shell.evaluate(x, 2)
        times.append(time.perf_counter() - t)
        calls += 1


def measure(scene, size, repeats):
    walls, its, times = [], [], []
    for _ in range(repeats):
        shell, res, wall, err = solve_once(scene, size)
        walls.append(wall)
        its.append(len(res.history.iterations))
        # one Hessian assembly at the solution, the unit of cost: timed after
        # every run (the same stretch of machine load as the solves), median
        time_assembly(shell, times)
    x = shell.free_state()
    h = res.history
    row = {"scene": scene, "size": size, "n_triangles": int(shell.mesh.n_triangles), "dofs": int(len(x)),
           "wall_s": float(np.median(walls)), "wall_runs_s": walls,
           "assembly_s": float(np.median(times)), "assembly_calls": len(times),
           "newton_its": len(h.iterations), "factorizations": int(h.factorizations),
           "assemblies": int(h.assemblies),
           # h.steps[0] is the equilibrium at t = 0; then one entry per continuation step tried
           "load_steps": sum(ok for _, ok in h.steps[1:]),
           "failed_steps": sum(not ok for _, ok in h.steps[1:]),
           "escapes": len(h.escapes),
           "linear": h.linear, "stable": h.stable, "error": err,
           # the h^5 strain-gradient term is on (elements shorter than h: the cylinder from 64 triangles)
           "strain_gradient": shell.strain_gradient is not None,
           "load_average": list(os.getloadavg())}
    row["solve_in_assemblies"] = row["wall_s"] / row["assembly_s"]
    if len(set(its)) > 1:
        row["newton_its_runs"] = its            # the runs differed (should not happen)
    return row


def source():
    """Which shellritz ran: its path, and the commit and uncommitted source
    files of this repository (read-only git queries)."""
    import subprocess
    import shellritz
    repo = HERE.parent
    file = Path(shellritz.__file__).resolve()

    def git(*cmd):
        try:
            return subprocess.run(["git", "--no-optional-locks", "-C", str(repo), *cmd], capture_output=True,
                                  text=True, timeout=30).stdout.rstrip("\n")
        except (OSError, subprocess.SubprocessError):
            return None
    status = git("status", "--porcelain", "--", "src")
    return {"shellritz_file": str(file),
            "from": "this repository's working tree" if repo in file.parents else "outside this repository",
            "repository_commit": (git("rev-parse", "HEAD") or "").strip() or None,
            "uncommitted_src": None if status is None else [ln[3:] for ln in status.splitlines()]}


def chart(rows, path, repeats):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(6.4, 4.4))
    for name in SIZES:
        rr = [r for r in rows if r["scene"] == name]
        if not rr:
            continue
        ax.loglog([r["wall_s"] for r in rr], [r["error"] for r in rr], "o-", label=name)
        for r in rr:
            ax.annotate(str(r["n_triangles"]), (r["wall_s"], r["error"]), fontsize=7,
                        xytext=(3, 3), textcoords="offset points")
    ax.set_xlabel(f"wall time to solution (s, {THREADS} threads)")
    ax.set_ylabel("relative error")
    runs = "median of %d runs" % repeats if repeats > 1 else "1 run"
    ax.set_title(f"DKT engine: accuracy against cost ({THREADS} threads, {runs})\n"
                 "labels: triangles", fontsize=10)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=110)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeats", type=int, default=3, help="runs per mesh (the median is reported)")
    ap.add_argument("--quick", action="store_true",
                    help="two smallest meshes per scene, one run (solve_quick.json / .png)")
    args = ap.parse_args()
    repeats = 1 if args.quick else args.repeats
    out = RESULTS / ("solve_quick.json" if args.quick else "solve.json")
    import numba
    numba.set_num_threads(THREADS)
    t = time.perf_counter()
    for scene, size in WARMUP:
        solve_once(scene, size)
    warmup_s = time.perf_counter() - t
    machine = machine_info()
    code = source()
    RESULTS.mkdir(exist_ok=True)
    rows = []
    for scene, sizes in SIZES.items():
        for size in sizes[:2] if args.quick else sizes:
            r = measure(scene, size, repeats)
            rows.append(r)
            print(f"{scene:8s} {r['n_triangles']:6d} triangles: {r['wall_s']:7.2f} s "
                  f"= {r['solve_in_assemblies']:7.1f} assemblies, error {r['error']:.2e}, "
                  f"{r['newton_its']} Newton, {r['factorizations']} factorizations, "
                  f"{r['assemblies']} assemblies", flush=True)
            out.write_text(json.dumps({"benchmark": "DKT engine: time to solution against accuracy",
                                       "threads": THREADS, "repeats": repeats, "warmup_s": warmup_s,
                                       "machine": machine, "source": code, "rows": rows}, indent=1))
    chart(rows, out.with_suffix(".png"), repeats)


if __name__ == "__main__":
    main()
