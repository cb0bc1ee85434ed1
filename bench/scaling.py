"""Solver scaling on the leaf growth scene (issue 10, item 6).

The default scene (meshes/leaf.toml: a disc of radius 1 grown in its plane by
1 + 0.3 rho^2 buckles into a saddle) on shapes.disc(rings) meshes of about
6 rings^2 triangles, solved to a relative gradient of 1e-8 in one adaptive
continuation step, with every linear method where it fits: "pardiso",
"superlu" (small meshes), "amg"; and "pardiso-nested": PARDISO with nested
iteration (the leaf solved on coarser discs first, each level starting from
the previous equilibrium, Shell.solve(start=...), with linear="auto" as a
user would: PARDISO below AUTO_DIRECT_MAX_DOFS, and to the tolerance
solve_nested gives coarse levels, nested.coarse_rtol, since 2026-12-06; all
levels inside the timed span, their Newton iterations and factorizations in nested_levels;
newton_its, krylov_its and factorizations are those of the finest level),
"amg-nested": the same with AMG on the finest level (the method for
meshes whose factors do not fit in memory), and "pardiso-coarsened" /
"amg-coarsened": nested iteration with the coarse meshes made from the fine
disc by shellritz.solve_nested, as for a user's mesh that has no coarser
versions (coarsening times in nested_levels).  Each run is a fresh process on 2 threads
(NUMBA/OMP/MKL_NUM_THREADS = 2) that first loads the compiled kernels and
solves a tiny leaf, and a thick one with a two-level AMG hierarchy (the
strain-gradient and AMG kernels; compile time excluded, reported
separately as warmup_s), then
solves the scene and times one Hessian assembly at the solution (the unit
of cost: the whole solve in Hessian assemblies is a ratio that transfers
between machines), and reports its peak resident memory.

With --membrane regge the leaf uses the locking-free membrane metric
(README, Membrane locking): rows in bench/results/scaling_regge.json, logs
with a _regge suffix.

With --repeats N each size and method runs in N fresh processes: the row
of the median wall time is kept (all walls in wall_runs_s), with the median
of the N ratios solve / assembly (each of one process) as
solve_in_assemblies.

Writes bench/results/scaling.json (rows: n_triangles, dofs, solver, thickness, wall_s,
assembly_s, solve_in_assemblies, peak_mem_gb, newton_its, krylov_its,
krylov_per_newton, factorizations, nested_levels, energy, grad_rel (final |g| over
that of the flat disc at t = 1), stable, converged, error, user_s / system_s /
minor_faults (the timed span's CPU time, the kernel's apart, and page faults:
machine.memory_info); for the AMG methods
also amg_cg_1e8_its: CG iterations to a relative residual of 1e-8 on the
Hessian at the solution with a hierarchy built on it, the measure of the
preconditioner apart from the Newton forcing terms, with amg_levels,
amg_setup_s, amg_cg_1e8_s, amg_strength_theta: linalg.AMG_STRENGTH_THETA,
absent in rows measured before it existed, i.e. with 0; post_error: the
process failed after the solve and its assembly timing, whose row is kept
without the measurements after them), bench/results/scaling.png and the
child processes' output (their Newton iterations) in bench/results/logs/.

--thickness h runs the leaf thinner than its 0.02 (rows carry thickness;
rows without it are at 0.02): elements of the 1M-triangle disc are 0.0027
long, h = 0.005 keeps them about as long as the thickness, where the shell
model needs them (docs/validity.md).  --thickness-path 0.02,0.01: the first
solve (the coarsest level of nested iteration) by continuation in the
thickness through those (Shell.solve(thickness_path=...); rows carry
thickness_path).

Run:  python bench/scaling.py [--rings 16 45 91 129 182 408] [--solvers pardiso superlu amg pardiso-nested amg-nested pardiso-coarsened amg-coarsened] [--repeats 3] [--time-limit 1200] [--thickness 0.02] [--thickness-path 0.02,0.01] [--redo]
      python bench/scaling.py --quick        (rings 8 and 16)
"""

import argparse
import json
import os
import resource
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

from shellritz.nested import COARSEST, FACTOR

HERE = Path(__file__).resolve().parent
RESULTS = HERE / "results"
sys.path.insert(0, str(HERE))

RTOL = 1e-8
THREADS = 2
# where a method is run (triangles): SuperLU's fill and time grow too fast
# beyond 50k triangles; PARDISO's two factors of a 1M-triangle mesh (4.5M
# DOFs; analysis and one factor 8.8 KB per DOF at 226k DOFs, growing) do not
# fit in 24 GB
LIMITS = {"superlu": 60_000, "pardiso": 250_000, "amg": None, "pardiso-nested": 250_000,
          "amg-nested": None, "pardiso-coarsened": 250_000, "amg-coarsened": None}
# "pardiso-nested": nested iteration (Shell.solve(start=...)): the leaf on
# discs of rings/2, rings/4, ... (at least NESTED_COARSEST rings, the
# default leaf's mesh) first, each level from the previous one's
# equilibrium, all inside the timed span (16 -> 32 rings: 5 Newton
# iterations instead of 18 from the flat disc).
# "pardiso-coarsened": nested iteration as on a user's mesh, which has no
# coarser versions: shellritz.solve_nested makes them from the fine disc
# (1/4, 1/16, ... of its triangles, at least 1,500), all levels with PARDISO;
# "amg-coarsened": the same with AMG on the given mesh (the coarse levels
# choose their solver by size, as solve_nested does)
NESTED_COARSEST = 16
TIME_LIMIT_S = 1200
# the leaf's thickness (meshes/leaf.toml); --thickness runs the scene thinner
# (rows carry "thickness"; rows without it were measured at this one)
LEAF_THICKNESS = 0.02
# the membrane metric of the leaf (--membrane): "dkt", as issue 10's figures were
# measured (the scene file's is regge since 2026-12-07: scaling_regge.json)
MEMBRANE = "dkt"
LOG_TAG = ""     # the logs of runs written elsewhere than scaling{_regge}.json: their own names

CHILD = r"""
import json, resource, sys, time
import numpy as np
from shellritz.batch import prepare_kernels
from shellritz.scenes import leaf
from shellritz import SolveError
from shellritz.nested import coarse_rtol
rings, solver, rtol = int(sys.argv[1]), sys.argv[2], float(sys.argv[3])
coarser = [int(k) for k in sys.argv[4].split(",") if k]
thickness = float(sys.argv[5])
path = [float(v) for v in sys.argv[6].split(",") if v] or None    # thickness_path of the first solve
membrane = sys.argv[7]
first = {} if path is None else {"thickness_path": path}
leaf_h = lambda k: leaf(k, thickness=thickness, membrane=membrane)
linear = solver.split("-")[0]
kernels_s, compiled = prepare_kernels(membrane)
t = time.perf_counter()
leaf(4, membrane=membrane).solve(verbose=False, linear=linear)
# kernels the tiny leaf does not reach, compiled on their first use (after a
# cache wipe: inside the timed span): the strain-gradient term (elements
# shorter than h) and a multilevel AMG hierarchy's set-up and smoother
import shellritz.linalg as linalg
one_level, linalg.AMG_ONE_LEVEL_BLOCKS = linalg.AMG_ONE_LEVEL_BLOCKS, 0
try:
    leaf(10, thickness=0.5, membrane=membrane).solve(verbose=False, linear="amg")
except SolveError:
    pass
linalg.AMG_ONE_LEVEL_BLOCKS = one_level
warm_s = time.perf_counter() - t
shell = leaf_h(rings)
row = dict(rings=rings, n_triangles=int(len(shell.mesh.triangles)), solver=solver, thickness=thickness,
           membrane=membrane,
           kernels_s=kernels_s, kernels_compiled=compiled, warmup_s=warm_s, nested_levels=[],
           **({} if path is None else {"thickness_path": path}))
t, usage = time.perf_counter(), resource.getrusage(resource.RUSAGE_SELF)
try:
    start = None
    if solver.endswith("-coarsened"):
        from importlib.resources import files
        from shellritz import solve_nested
        from shellritz.meshdata import Surface
        from shellritz.scenefile import load_scene
        scene = load_scene(files("shellritz.meshes") / "leaf.toml")
        mesh, shell = shell.mesh, None       # solve_nested builds the scene on the mesh: one Shell
        res = solve_nested(lambda mesh: scene.build(Surface(mesh), thickness=thickness, membrane=membrane)[0],
                           mesh, verbose=True,
                           linear=linear, rtol=rtol, **first)
        shell = res.shell
        row["nested_levels"] = res.history.nested
    for k in coarser:        # nested iteration: each level starts from the previous one
        tk = time.perf_counter()    # (coarse levels to the tolerance solve_nested gives them)
        start = leaf_h(k).solve(verbose=False, linear="auto", rtol=coarse_rtol(rtol), start=start,
                                **(first if start is None else {}))
        row["nested_levels"].append(dict(rings=k, n_triangles=int(len(start.shell.mesh.triangles)),
                                         wall_s=time.perf_counter() - tk,
                                         newton_its=len(start.history.iterations),
                                         factorizations=start.history.factorizations))
    if not solver.endswith("-coarsened"):
        res = shell.solve(verbose=True, linear=linear, rtol=rtol, start=start,
                          **(first if start is None else {}))
    h, converged, error = res.history, True, None
except SolveError as exc:
    h, converged, error = exc.history, False, str(exc)
    if shell is None:                     # solve_nested failed: time the assembly on a fresh leaf
        shell = leaf_h(rings)
row["wall_s"] = time.perf_counter() - t
# CPU time of the timed span, the kernel's apart (page faults: on a VM whose
# balloon reports free pages, about 3 s per GB first touched; machine.memory)
end = resource.getrusage(resource.RUSAGE_SELF)
row.update(user_s=end.ru_utime - usage.ru_utime, system_s=end.ru_stime - usage.ru_stime,
           minor_faults=end.ru_minflt - usage.ru_minflt)
x = shell.free_state()
times = []
for _ in range(3):
    t = time.perf_counter()
    E, g, K = shell.evaluate(x, 2)
    times.append(time.perf_counter() - t)
its = h.iterations
row.update(dofs=int(len(x)), assembly_s=float(np.median(times)), converged=converged, error=error,
           newton_its=len(its), krylov_its=int(sum(i.krylov_its for i in its)),
           krylov_per_newton=float(np.mean([i.krylov_its for i in its])) if its else None,
           krylov_max=int(max((i.krylov_its for i in its), default=0)),
           factorizations=h.factorizations, evaluations=list(h.evaluations),
           setup_s=float(sum(i.setup_s for i in its)), linear_solve_s=float(sum(i.solve_s for i in its)),
           energy=float(E), stable=h.stable, notes=h.notes[:5], linear_used=h.linear,
           peak_mem_gb=resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 2**20)
row["solve_in_assemblies"] = row["wall_s"] / row["assembly_s"]
from machine import machine_info
row["machine"] = machine_info()
print("SOLVED " + json.dumps(row), flush=True)     # kept if what follows fails (1M: 20 min more)
if solver.startswith("amg") and converged:
    # the preconditioner apart from the Newton forcing terms (bench/amg_cg.py)
    from amg_cg import amg_cg_iterations
    from shellritz.linalg import AMG_STRENGTH_THETA
    del res, start
    m = amg_cg_iterations(K, shell.block_layout())
    row.update(amg_setup_s=m["setup_s"], amg_levels=m["levels"], amg_cg_1e8_its=m["its"],
               amg_cg_1e8_reason=m["reason"], amg_cg_1e8_s=m["cg_s"], amg_strength_theta=AMG_STRENGTH_THETA)
# the final gradient relative to that of the reference (flat) state at t = 1,
# the scale rtol refers to for every method (solve(start=) included)
ref = leaf_h(rings)
ref._setup()
ref.set_parameter(1.0)
row["grad_rel"] = float(np.linalg.norm(g) / np.linalg.norm(ref.evaluate(ref.free_state(), 1)[1]))
print("ROW " + json.dumps(row))
"""


def nested_levels(rings):
    """The coarser discs a "-nested" method solves first, coarsest first:
    rings halved while at least NESTED_COARSEST."""
    levels = []
    while rings // 2 >= NESTED_COARSEST:
        rings //= 2
        levels.insert(0, rings)
    return levels


def thickness_of(row):
    return row.get("thickness", LEAF_THICKNESS)


def config_of(row):
    """(solver, thickness, thickness path): rows of one configuration form a series."""
    return row["solver"], thickness_of(row), tuple(row.get("thickness_path") or ())


def config_label(solver, h, path):
    return (solver + ("" if h == LEAF_THICKNESS else f", h = {h:g}")
            + (f", from h = {' > '.join(f'{v:g}' for v in path)}" if path else ""))


def keep_log(rings, solver, thickness, path, text):
    """The child's output (the finest solve's Newton iterations, verbose) in
    bench/results/logs/: what a run that failed or timed out got through."""
    h = "" if thickness == LEAF_THICKNESS else f"_h{thickness:g}"
    h += "".join(f"_from{v:g}" for v in path)
    h += "" if MEMBRANE == "dkt" else f"_{MEMBRANE}"
    log = RESULTS / "logs" / f"scaling_{rings}_{solver}{h}{LOG_TAG}.log"
    log.parent.mkdir(exist_ok=True)
    log.write_text(text)


def solved_row(stdout, why):
    """The row the child printed after its solve and assembly timing (None if
    it did not get there), with why it did not finish as post_error."""
    for line in stdout.splitlines():
        if line.startswith("SOLVED "):
            return dict(json.loads(line[7:]), post_error=why)
    return None


def run(rings, solver, time_limit, thickness, path=()):
    env = dict(os.environ, NUMBA_NUM_THREADS=str(THREADS), OMP_NUM_THREADS=str(THREADS),
               MKL_NUM_THREADS=str(THREADS), PYTHONPATH=str(HERE))
    coarser = nested_levels(rings) if solver.endswith("-nested") else []
    t = time.perf_counter()
    peak_before = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 2**20
    try:
        p = subprocess.run([sys.executable, "-c", CHILD, str(rings), solver, str(RTOL),
                            ",".join(map(str, coarser)), str(thickness), ",".join(map(str, path)),
                            MEMBRANE],
                           env=env,
                           capture_output=True, text=True, timeout=time_limit)
    except subprocess.TimeoutExpired as exc:
        out = exc.stdout.decode() if isinstance(exc.stdout, bytes) else (exc.stdout or "")
        keep_log(rings, solver, thickness, path, out)
        return solved_row(out, f"time limit {time_limit} s") or {
            "rings": rings, "solver": solver, "thickness": thickness, "converged": False,
            **({"thickness_path": list(path)} if path else {}),
            "error": f"time limit {time_limit} s", "wall_s": time.perf_counter() - t}
    keep_log(rings, solver, thickness, path, p.stdout + p.stderr)
    for line in p.stdout.splitlines():
        if line.startswith("ROW "):
            return json.loads(line[4:])
    row = solved_row(p.stdout, f"exit {p.returncode}: {p.stderr.strip().splitlines()[-1:] or ''}")
    if row:
        return row
    row = {"rings": rings, "solver": solver, "thickness": thickness, "converged": False,
           "wall_s": time.perf_counter() - t, **({"thickness_path": list(path)} if path else {})}
    if p.returncode < 0:
        # killed by a signal: SIGKILL from outside this script is the kernel's
        # out-of-memory killer; the child's peak is the largest of this
        # script's children when it exceeds those before it
        name = signal.Signals(-p.returncode).name
        row["error"] = f"killed by {name}" + (" (out of memory)" if name == "SIGKILL" else "")
        peak = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 2**20
        if peak > peak_before:
            row["peak_mem_gb"] = peak
    else:
        row["error"] = f"exit {p.returncode}: {p.stderr.strip().splitlines()[-1:] or ''}"
    return row


def chart(rows, path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(1, 3, figsize=(14, 4.2))
    for config in sorted({config_of(r) for r in rows}):
        rs = sorted((r for r in rows if config_of(r) == config and r.get("converged")),
                    key=lambda r: r["n_triangles"])
        if not rs:
            continue
        n = [r["n_triangles"] for r in rs]
        label = config_label(*config)
        ax[0].loglog(n, [r["wall_s"] for r in rs], "o-", label=label)
        ax[1].semilogx(n, [r["solve_in_assemblies"] for r in rs], "o-", label=label)
        ax[2].loglog(n, [r["peak_mem_gb"] for r in rs], "o-", label=label)
    rs = sorted((r for r in rows if "assembly_s" in r and thickness_of(r) == LEAF_THICKNESS),
                key=lambda r: r["n_triangles"])
    seen = {}
    for r in rs:
        seen.setdefault(r["n_triangles"], r["assembly_s"])
    ax[0].loglog(list(seen), list(seen.values()), "k--", label="one Hessian assembly")
    ax[0].set(xlabel="triangles", ylabel="wall time of the solve (s)", title="leaf (h = 0.02 unless said), 2 threads")
    ax[1].set(xlabel="triangles", ylabel="solve / one Hessian assembly", title="cost in assemblies")
    ax[2].set(xlabel="triangles", ylabel="peak resident memory (GB)", title="memory")
    for a in ax:
        a.grid(True, which="both", alpha=0.3)
        a.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=120)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--rings", type=int, nargs="+", default=[16, 45, 91, 129, 182, 408])
    ap.add_argument("--solvers", nargs="+",
                    default=["pardiso", "superlu", "amg", "pardiso-nested", "amg-nested", "pardiso-coarsened",
                             "amg-coarsened"])
    ap.add_argument("--time-limit", type=float, default=TIME_LIMIT_S,
                    help="seconds per process (the 1M-triangle run needs more)")
    ap.add_argument("--quick", action="store_true", help="rings 8 and 16")
    ap.add_argument("--repeats", type=int, default=1,
                    help="fresh processes per size and method; the row of the median wall time is kept")
    ap.add_argument("--thickness", type=float, default=LEAF_THICKNESS,
                    help="the leaf's thickness (disc radius 1; the scene file's: 0.02)")
    ap.add_argument("--thickness-path", default="",
                    help="comma-separated larger thicknesses the first solve passes through "
                         "(Shell.solve(thickness_path=...)), e.g. 0.02,0.01")
    ap.add_argument("--membrane", choices=("dkt", "regge"), default="dkt",
                    help="the leaf's membrane metric (regge: written to scaling_regge.json unless --out)")
    ap.add_argument("--out", default=None,
                    help="the results file (default bench/results/scaling.json, scaling_regge.json with "
                         "--membrane regge); another file's logs carry its name, e.g. --out "
                         "bench/results/scaling_crossover.json: logs/scaling_129_amg-nested_crossover.log")
    ap.add_argument("--redo", action="store_true",
                    help="rerun the sizes and methods the file already has (else they are skipped)")
    args = ap.parse_args()
    global MEMBRANE, LOG_TAG
    MEMBRANE = args.membrane
    suffix = "" if MEMBRANE == "dkt" else f"_{MEMBRANE}"
    rings = [8, 16] if args.quick else args.rings
    out = Path(args.out or RESULTS / f"scaling{suffix}.json") if not args.quick else \
        RESULTS / f"scaling_quick{suffix}.json"
    tag = out.stem.removeprefix("scaling").removesuffix(suffix)
    LOG_TAG = tag if not tag or tag.startswith("_") else f"_{tag}"
    rows = json.loads(out.read_text())["rows"] if out.exists() and not args.quick else []
    h = args.thickness
    path = tuple(float(v) for v in args.thickness_path.split(",") if v)
    done = {(r["rings"],) + config_of(r) for r in rows}
    for k in rings:
        n_est = 6 * k * k
        for solver in args.solvers:
            limit = LIMITS[solver]
            if (((k, solver, h, path) in done and not args.redo) or (limit is not None and n_est > limit)
                    or (solver.endswith("-nested") and not nested_levels(k))
                    or (solver.endswith("-coarsened") and n_est // FACTOR < COARSEST)):
                continue
            runs = [run(k, solver, args.time_limit, h, path) for _ in range(args.repeats)]
            ok = [r for r in runs if r.get("converged")]
            # the run of median wall time (all converged), with the walls of all runs
            row = sorted(ok, key=lambda r: r["wall_s"])[len(ok) // 2] if len(ok) == len(runs) else runs[-1]
            row["wall_runs_s"] = [r["wall_s"] for r in runs]
            row["solve_in_assemblies_runs"] = [r.get("solve_in_assemblies") for r in runs]
            if len(ok) == len(runs):
                # each run's ratio is of one process; their median (the timing
                # of one assembly after the solve varies by +-10 % between processes)
                row["solve_in_assemblies"] = float(np.median(row["solve_in_assemblies_runs"]))
            print(f"rings {k:4d} {config_label(solver, h, path)} " + (
                f"{row['n_triangles']:8d} tri {row['wall_s']:8.1f} s = {row['solve_in_assemblies']:6.1f} "
                f"assemblies, {row['newton_its']} Newton, {row['krylov_per_newton']:.1f} Krylov/Newton, "
                f"{row['peak_mem_gb']:.2f} GB" if row.get("converged") else f"FAILED {row.get('error')}"),
                flush=True)
            rows = [r for r in rows if (r["rings"],) + config_of(r) != (k, solver, h, path)] + [row]
            machine = next((r["machine"] for r in rows if "machine" in r), None)
            out.write_text(json.dumps({"benchmark": "leaf growth scene, solver scaling", "rtol": RTOL,
                                       "threads": THREADS, "machine": machine, "rows": rows}, indent=1))
    chart(rows, out.with_suffix(".png"))


if __name__ == "__main__":
    main()
