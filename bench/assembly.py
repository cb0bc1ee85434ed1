"""DKT assembly throughput (issue: general shells).

Energy, gradient and Hessian assembly time against the number of triangles
(1k to 200k) for the consistent model (compressible neo-Hookean, growth with a
through-thickness gradient, a deformed curved state), on 2 threads; medians of
repeated runs; compile time measured separately in a fresh process with an
empty Numba cache.  The Hessian time includes the scatter into the sparse
matrix of the free DOFs.  Memory: the arrays the engine keeps between
evaluations (pattern, element map, warm starts, ...) and the peak resident
size of the process (it grows with the largest mesh so far).

Writes bench/results/assembly.json (rows: n_triangles, energy_s, gradient_s,
hessian_s, engine_mb, peak_rss_mb) and bench/results/assembly.png.
Run:  python bench/assembly.py [--max 200000] [--repeats 5]
"""

import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
RESULTS = HERE / "results"


def scene(n_target, level="consistent"):
    """A cylinder with ~n_target triangles, deformed, with growth."""
    from shellritz import NeoHookean, Shell, shapes
    nz = max(2, int(np.sqrt(n_target / 2 / np.pi)))
    nt = max(8, int(n_target / (2 * nz)))
    mesh = shapes.cylinder(nt, nz, radius=1.0, length=2 * np.pi * 1.0 * nz / nt)
    s = Shell(mesh, 0.02, NeoHookean(1.0, nu=0.4), level=level)
    ez = np.array([0, 0, 1.0])
    s.set_growth(G0=1.1 * np.eye(3) - 0.1 * np.outer(ez, ez), G1=np.diag([0.5, 0.5, 0.0]))
    s.pin([0])
    s._setup()
    s.set_parameter(1.0)
    rng = np.random.default_rng(0)
    # a generic state, admissible (F0 + Z F1 does not fold: perturbation 1 % of the element size)
    size = np.linalg.norm(mesh.vertices[mesh.edges[:, 1]] - mesh.vertices[mesh.edges[:, 0]], axis=1).mean()
    x = s.free_state() + 0.01 * size * rng.standard_normal(len(s.free))
    s.evaluate(x, 2)                 # warm starts of y1
    return s, x


def compile_time():
    """Set-up and first evaluation of every mode, in a fresh process with an
    empty cache minus the same with the cache filled: the JIT compile time."""
    code = ("import sys, time; t = time.perf_counter(); sys.path.insert(0, %r)\n"
            "from assembly import scene\n"
            "s, x = scene(1000)\n"
            "for mode in (0, 1, 2): s.evaluate(x, mode)\n"
            "print(time.perf_counter() - t)\n") % str(HERE)
    with tempfile.TemporaryDirectory() as cache:
        env = dict(os.environ, NUMBA_CACHE_DIR=cache)
        runs = [float(subprocess.run([sys.executable, "-c", code], env=env, capture_output=True,
                                     text=True, check=True).stdout.split()[-1]) for _ in range(2)]
    return runs[0] - runs[1]


def median(fn, repeats):
    ts = []
    for _ in range(repeats):
        t = time.perf_counter()
        fn()
        ts.append(time.perf_counter() - t)
    return float(np.median(ts))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--max", type=int, default=200_000)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--no-compile", action="store_true",
                    help="skip the cold-compile measurement (bench/first_run.py measures the whole first run)")
    args = ap.parse_args()
    import numba
    numba.set_num_threads(2)
    sizes = [n for n in (1_000, 4_000, 16_000, 50_000, 100_000, 200_000) if n <= args.max]
    rows = []
    compile_s = compile_time() if not args.no_compile else None
    if compile_s is not None:
        print(f"compile (cold cache, 3 modes): {compile_s:.1f} s")
    for n in sizes:
        s, x = scene(n)
        ne = s.mesh.n_triangles
        reps = args.repeats if ne < 60_000 else max(3, args.repeats // 2)
        row = {"n_triangles": ne, "n_dofs": len(s.free)}
        for mode, name in ((0, "energy_s"), (1, "gradient_s"), (2, "hessian_s")):
            row[name] = median(lambda: s.evaluate(x, mode), reps)
        row["hessian_triangles_per_s"] = ne / row["hessian_s"]
        row["engine_mb"] = sum(v.nbytes for v in vars(s).values()
                               if isinstance(v, np.ndarray)) / 2**20
        row["peak_rss_mb"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 2**10
        rows.append(row)
        print(f"{ne:>7} triangles: energy {row['energy_s']:.3f} s, gradient {row['gradient_s']:.3f} s, "
              f"Hessian {row['hessian_s']:.3f} s ({row['hessian_triangles_per_s']:,.0f} triangles/s), "
              f"engine {row['engine_mb']:.0f} MB, peak RSS {row['peak_rss_mb']:.0f} MB",
              flush=True)
        del s
    levels = {}
    for level in ("membrane", "bending", "consistent"):
        s, x = scene(16_000, level)
        levels[level] = s.mesh.n_triangles / median(lambda: s.evaluate(x, 2), args.repeats)
        print(f"Hessian assembly, {level}: {levels[level]:,.0f} triangles/s", flush=True)
    from machine import machine_info
    RESULTS.mkdir(exist_ok=True)
    out = {"threads": 2, "model": "consistent, neo-Hookean, G1 != 0, 6-point rule",
           "compile_s": compile_s, "rows": rows, "machine": machine_info(), "hessian_triangles_per_s_by_level_16k": levels}
    (RESULTS / "assembly.json").write_text(json.dumps(out, indent=2))
    chart(rows)


def chart(rows):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    n = [r["n_triangles"] for r in rows]
    fig, (ax, bx) = plt.subplots(1, 2, figsize=(10, 4))
    for key, label in (("energy_s", "energy"), ("gradient_s", "gradient"), ("hessian_s", "Hessian")):
        ax.loglog(n, [r[key] for r in rows], "o-", label=label)
    ax.set_xlabel("triangles")
    ax.set_ylabel("assembly time (s, 2 threads)")
    ax.legend()
    bx.semilogx(n, [r["n_triangles"] / r["hessian_s"] / 1e3 for r in rows], "o-")
    bx.axhline(30, color="k", ls="--", lw=1, label="target")
    bx.set_xlabel("triangles")
    bx.set_ylabel("Hessian assembly, thousand triangles / s")
    bx.legend()
    fig.tight_layout()
    fig.savefig(RESULTS / "assembly.png", dpi=110)


if __name__ == "__main__":
    main()
