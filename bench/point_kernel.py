"""Point-kernel throughput (issue: foundation).

Points per second of the consistent-model point kernel (compressible
neo-Hookean, through-thickness growth gradient G1, loads, curved reference in
skew coordinates) for energy, energy+gradient and energy+gradient+Hessian, on
1 and 2 threads.  Timings are medians of repeated runs over N points with the
director y1 warm-started from the previous evaluation, as inside a Newton
solve; the cold start (y1 solved from scratch) is reported separately.
Compile time is measured in a fresh process with an empty Numba cache.

Writes bench/results/point_kernel.json and bench/results/point_kernel.png.
Run:  python bench/point_kernel.py  [--points N] [--repeats R]
"""

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
RESULTS = HERE / "results"


def make_points(n, seed=0):
    """Random admissible states on a sphere (see tests/pointdata.py)."""
    sys.path.insert(0, str(HERE.parent / "tests"))
    from pointdata import random_state
    rng = np.random.default_rng(seed)
    base = [random_state(rng, "sphere") for _ in range(64)]
    idx = np.arange(n) % len(base)
    pick = lambda f: np.ascontiguousarray(np.array([f(base[i]) for i in idx]))
    return dict(V=pick(lambda b: b[1]), REF=pick(lambda b: b[0]),
                G0=pick(lambda b: b[2]["G0"]), G1=pick(lambda b: b[2]["G1"]),
                dG0=pick(lambda b: b[2]["dG0"]), QBAR=pick(lambda b: b[2]["qbar"]),
                M=pick(lambda b: b[2]["m"]), DM=pick(lambda b: b[2]["dm"]))


def run(mode, level, law, pts, out, h=0.1):
    from shellritz.kernels.point import evaluate_points
    evaluate_points(mode, level, law.kind, law.psi, law.params, h, pts["V"], pts["REF"],
                    pts["G0"], pts["G1"], pts["dG0"], pts["QBAR"], pts["M"], pts["DM"],
                    out["Y1"], out["Y2"], out["L"], out["GRAD"], out["HESS"], out["STATUS"])
    if out["STATUS"].max() != 0:
        raise RuntimeError("point kernel failed in the benchmark")


def buffers(n):
    return dict(Y1=np.zeros((n, 3)), Y2=np.zeros((n, 3)), L=np.zeros(n),
                GRAD=np.zeros((n, 15)), HESS=np.zeros((n, 15, 15)),
                STATUS=np.zeros(n, np.int64))


def compile_time():
    """First call of every mode in a fresh process with an empty cache."""
    code = ("import time; t = time.perf_counter(); import numpy as np\n"
            "from shellritz.materials import NeoHookean\n"
            f"import sys; sys.path.insert(0, {str(HERE)!r})\n"
            "from point_kernel import make_points, buffers, run\n"
            "t_import = time.perf_counter() - t\n"
            "law = NeoHookean(1.0, nu=0.3); pts = make_points(8); out = buffers(8)\n"
            "t = time.perf_counter()\n"
            "for mode in (0, 1, 2): run(mode, 2, law, pts, out)\n"
            "print(t_import, time.perf_counter() - t)\n")
    with tempfile.TemporaryDirectory() as cache:
        env = dict(os.environ, NUMBA_CACHE_DIR=cache)
        cold = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True,
                              text=True, check=True).stdout.split()
        warm = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True,
                              text=True, check=True).stdout.split()
    return float(cold[1]), float(warm[1]), float(warm[0])


def material_profile(law, repeats, n=20000):
    """Micro-timings (us) of the material-layer building blocks at one point."""
    import numba
    from shellritz.kernels.material import (mat_combination, mat_d3, mat_d3_vec,
                                            mat_prepare, new_state)

    @numba.njit
    def loop(n, what, kind, psi, params, A, mv, mm, mp, c, C, D, w, out, v9):
        for _ in range(n):
            if what == 0:
                mat_prepare(kind, psi, params, A, mv, mm, mp)
            elif what == 1:
                mat_d3(mv, mm, mp, c, out)
            elif what == 2:
                mat_d3_vec(mv, mm, mp, c, C[0], v9)
            else:
                mat_combination(mv, mm, mp, 1.0, c, C, D, w, out)

    rng = np.random.default_rng(1)
    A = np.eye(3) + 0.1 * rng.standard_normal((3, 3))
    st = new_state()
    args = (law.kind, law.psi, law.params, A, *st, rng.standard_normal(9),
            rng.standard_normal((3, 9)), rng.standard_normal((3, 9)), np.ones(3),
            np.zeros((9, 9)), np.zeros(9))
    loop(1, 0, *args)
    names = ["prepare (W, P, AA)", "D3 block 9x9", "D3 vector", "AA + D3 + 3 x D4 block"]
    return {name: 1e6 * median_time(lambda: loop(n, k, *args), repeats) / n
            for k, name in enumerate(names)}


def median_time(fn, repeats):
    ts = []
    for _ in range(repeats):
        t = time.perf_counter()
        fn()
        ts.append(time.perf_counter() - t)
    return float(np.median(ts))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--points", type=int, default=20000)
    ap.add_argument("--repeats", type=int, default=7)
    ap.add_argument("--no-compile", action="store_true",
                    help="skip the cold-compile measurement (bench/first_run.py measures the whole first run)")
    args = ap.parse_args()
    import numba
    from shellritz.materials import NeoHookean
    law = NeoHookean(1.0, nu=0.3)
    n = args.points
    pts = make_points(n)
    out = buffers(n)
    compile_cold, compile_cached, import_s = compile_time() if not args.no_compile else (None, None, None)
    modes = {0: "energy", 1: "gradient", 2: "hessian"}
    levels = {0: "membrane", 1: "bending", 2: "consistent"}
    res = {"points": n, "repeats": args.repeats, "law": "neo-Hookean C=1 nu=0.3",
           "scene": "sphere, skew coordinates, G1 != 0, loads", "warm_start": True,
           "compile_s": compile_cold, "cached_load_s": compile_cached, "import_s": import_s,
           "threads": {}, "levels_1thread_us_per_point": {}}
    run(2, 2, law, pts, out)                # warm start for y1, compiled
    for threads in (1, 2):
        numba.set_num_threads(threads)
        row = {}
        for mode, name in modes.items():
            t = median_time(lambda: run(mode, 2, law, pts, out), args.repeats)
            row[f"{name}_pts_per_s"] = n / t
        res["threads"][str(threads)] = row
        print(f"{threads} thread(s): " + ", ".join(f"{k} {v:,.0f}" for k, v in row.items()))
    numba.set_num_threads(1)
    for level, lname in levels.items():
        res["levels_1thread_us_per_point"][lname] = {}
        for mode, name in modes.items():
            run(mode, level, law, pts, out)
            t = median_time(lambda: run(mode, level, law, pts, out), args.repeats)
            res["levels_1thread_us_per_point"][lname][name] = 1e6 * t / n
    # cold start: y1 solved from scratch every time
    def cold():
        out["Y1"][:] = 0.0
        run(0, 2, law, pts, out)
    res["cold_start_energy_1thread_pts_per_s"] = n / median_time(cold, args.repeats)
    res["material_profile_us"] = material_profile(law, args.repeats)
    numba.set_num_threads(2)
    for name in modes.values():
        res[f"{name}_pts_per_s"] = res["threads"]["2"][f"{name}_pts_per_s"]
    from machine import machine_info
    res["machine"] = machine_info()
    RESULTS.mkdir(exist_ok=True)
    (RESULTS / "point_kernel.json").write_text(json.dumps(res, indent=2))
    chart(res)
    print(json.dumps({k: res[k] for k in ("energy_pts_per_s", "gradient_pts_per_s",
                                          "hessian_pts_per_s", "compile_s")}, indent=2))


def chart(res):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    names = ["energy", "gradient", "hessian"]
    fig, (ax, bx) = plt.subplots(1, 2, figsize=(10, 4))
    x = np.arange(3)
    for k, threads in enumerate(("1", "2")):
        vals = [res["threads"][threads][f"{n}_pts_per_s"] / 1e3 for n in names]
        ax.bar(x + 0.38 * k, vals, 0.38, label=f"{threads} thread(s)")
    ax.axhline(100, color="k", ls="--", lw=1, label="target (Hessian, 2 threads)")
    ax.set_xticks(x + 0.19, names)
    ax.set_ylabel("thousand points / s")
    ax.set_title("consistent model, neo-Hookean")
    ax.legend(fontsize=8)
    lv = res["levels_1thread_us_per_point"]
    for k, lname in enumerate(lv):
        bx.bar(x + 0.27 * k, [lv[lname][n] for n in names], 0.27, label=lname)
    bx.set_xticks(x + 0.27, names)
    bx.set_ylabel("microseconds / point (1 thread)")
    bx.set_title("cost by model level")
    bx.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(RESULTS / "point_kernel.png", dpi=110)


if __name__ == "__main__":
    main()
