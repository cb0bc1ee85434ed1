"""Stability map of the solver (issue 10 item 6): hard scenes against every
solver configuration.

Scenes (src/shellritz/benchmark_scenes.py, scenes.leaf):

* ``thin panel``: clamped cylindrical panel, h/R = 1e-3, normal load;
* ``incompressible disc``: clamped disc, neo-Hookean nu = 0.499, inflated;
* ``grown strip``: strip clamped at both ends grown to twice its length
  (growth stretch 2), buckles into an arch;
* ``leaf``: the default growing leaf on a smaller disc (``scenes.leaf(rings)``);
* ``snapping cap``: clamped shallow cap snapping through (arc length);
* ``pulled cylinder``: Sze et al. 2004 section 3.5 (arc length).

Configurations: globalization ``line-search`` / ``trust-region`` x linear
solver ``direct`` (PARDISO where installed, else SuperLU) / ``amg``.  The
arc-length scenes need a factorization (the bordered systems of the
corrector solve with it, and its inertia tells limit from bifurcation
points): with ``amg`` the solver falls back to the direct one for the path
(``linear_used`` "amg->pardiso", a history note).

Each run is a separate process with a time limit per solve; the solve alone is timed
(kernels loaded and the linear solver's library initialized by a small
untimed solve first), the median of ``--repeat`` solves.  A failure is a row
with ``converged`` false and the error.  Writes
bench/results/stability_map.json (rows ``scene``, ``config``, ``converged``,
``newton_its``, ``krylov_its``, ``wall_s``, ``energy``, ``stable`` and more;
the machine) and bench/results/stability_map.png.

With ``--membrane regge`` the triangle scenes use the locking-free membrane
metric (README, Membrane locking; the snapping cap, a 1D scene, is the
same): bench/results/stability_map_regge.json and .png.

Run:  python bench/stability_map.py [--quick] [--threads 2] [--repeat 3] [--membrane regge]
"""

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))      # bench/machine.py
from machine import machine_info  # noqa: E402

RESULTS = Path(__file__).resolve().parent / "results"

GLOBALIZATIONS = ("line-search", "trust-region")
LINEAR = ("direct", "amg")
CONFIGS = [f"{g}/{lin}" for g in GLOBALIZATIONS for lin in LINEAR]

# name: (builder(size), engine kind, solve options, quick size, full size)
SCENES = {
    "thin panel": ("thin_panel", "dkt", {}, 4, 16),
    "incompressible disc": ("inflated_disc", "dkt", {}, 4, 12),
    "grown strip": ("grown_strip", "dkt", {}, 8, 32),
    "leaf": ("leaf", "dkt", {}, 4, 10),
    "snapping cap": ("snapping_cap", "line", {"path": "arclength", "steps": 5}, 20, 40),
    "pulled cylinder": ("pulled_cylinder", "dkt",
                        {"path": "arclength", "steps": 10, "arc_max_ds": 0.05}, 8, 16),
}


def build(scene, size, membrane="dkt"):
    from shellritz import benchmark_scenes, scenes
    name, kind = SCENES[scene][:2]
    module = scenes if name == "leaf" else benchmark_scenes
    if kind == "line":
        return getattr(module, name)(size)
    return getattr(module, name)(size, membrane=membrane)


def direct_method():
    from shellritz.linalg import pardiso_available
    return "pardiso" if pardiso_available() else "superlu"


def solver_options(scene, config):
    globalization, linear = config.split("/")
    opts = dict(SCENES[scene][2])
    opts.update(globalization=globalization, linear=direct_method() if linear == "direct" else "amg")
    return opts


def warm_up(kind, linear):
    """Load the Numba kernels and the linear solver's library (untimed)."""
    from shellritz.benchmark_scenes import snapping_cap, thin_panel
    if kind == "line":
        snapping_cap(n=4, factor=0.1).solve(steps=1, verbose=False, linear=direct_method())
    else:
        thin_panel(n=2, load=1.0).solve(steps=1, verbose=False,
                                        linear=linear if linear != "amg" else direct_method())


def run_one(scene, config, size, repeat=1, membrane="dkt"):
    """Solve ``scene`` at ``size`` with ``config`` (in this process): the
    row of the map.  wall_s is the median over ``repeat`` solves; the other
    entries are those of the last."""
    from shellritz import SolveError
    kind = SCENES[scene][1]
    opts = solver_options(scene, config)
    warm_up(kind, opts["linear"])
    walls = []
    for _ in range(repeat):
        eng = build(scene, size, membrane)
        error = None
        t0 = time.perf_counter()
        try:
            res = eng.solve(verbose=False, **opts)
            history = res.history
        except (SolveError, ValueError, RuntimeError) as exc:    # LinearSolverError is a RuntimeError
            res = getattr(exc, "result", None)
            history = getattr(exc, "history", None)
            error = f"{type(exc).__name__}: {exc}"
        walls.append(time.perf_counter() - t0)
    its = history.iterations if history is not None else []
    energy = getattr(res, "energy", None) if res is not None else None
    return {
        "scene": scene, "config": config, "size": size,
        "membrane": getattr(eng, "membrane", None),
        "globalization": opts["globalization"], "linear": opts["linear"],
        "linear_used": history.linear if history is not None else None,
        "dofs": len(eng.free) if hasattr(eng, "free") else None,
        "converged": error is None,
        "newton_its": len(its),
        "krylov_its": int(sum(i.krylov_its for i in its)),
        "wall_s": float(np.median(walls)), "wall_s_all": walls,
        "energy": None if energy is None or not np.isfinite(energy) else float(energy),
        "stable": history.stable if history is not None else None,
        "unstable_modes": history.unstable_modes if history is not None else None,
        "t_reached": float(res.t) if res is not None and res.t is not None else None,
        "factorizations": history.factorizations if history is not None else None,
        "assemblies": history.assemblies if history is not None else None,
        "path_points": len(history.path) if history is not None else None,
        "escapes": len(history.escapes) if history is not None else None,
        "notes": history.notes[:6] if history is not None else [],
        "error": error,
        "machine": machine_info(),         # of this process, after its kernels ran
    }


def run_isolated(scene, config, size, repeat, threads, time_limit, membrane="dkt"):
    """run_one in a fresh process with a time limit (per solve, plus two
    minutes for the start and the warm-up); a crash or the limit gives a
    failed row."""
    env = dict(os.environ, NUMBA_NUM_THREADS=str(threads), OMP_NUM_THREADS=str(threads),
               MKL_NUM_THREADS=str(threads), OPENBLAS_NUM_THREADS=str(threads))
    cmd = [sys.executable, __file__, "--one", scene, config, "--size", str(size), "--repeat", str(repeat),
           "--membrane", membrane]
    base = {"scene": scene, "config": config, "size": size, "converged": False, "newton_its": None,
            "krylov_its": None, "energy": None, "stable": None}
    t0 = time.perf_counter()
    try:
        p = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=time_limit * repeat + 120)
    except subprocess.TimeoutExpired:
        return dict(base, wall_s=time.perf_counter() - t0,
                    error=f"time limit {time_limit:g} s per solve exceeded ({repeat} solves)")
    lines = [l for l in p.stdout.splitlines() if l.startswith("{")]
    if p.returncode != 0 or not lines:
        tail = (p.stderr.strip().splitlines() or ["no output"])[-1]
        return dict(base, wall_s=time.perf_counter() - t0, error=f"process exit {p.returncode}: {tail}")
    return json.loads(lines[-1])


def machine(threads):
    """bench/machine.py's record of this process (the runs' own, with
    Numba's threading layer, replace it from the first run) and the map's
    settings."""
    try:
        commit = subprocess.run(["git", "-C", str(RESULTS.parent), "rev-parse", "HEAD"],
                                capture_output=True, text=True).stdout.strip() or None
    except OSError:
        commit = None
    return dict(machine_info(), threads=threads, direct_solver=direct_method(), shellritz_commit=commit)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--quick", action="store_true", help="tiny sizes (a check that it works)")
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--repeat", type=int, default=None, help="solves per run (median; default 3, quick 1)")
    ap.add_argument("--time-limit", type=float, default=None, help="seconds per solve (default 900, quick 300)")
    ap.add_argument("--scenes", nargs="*", default=list(SCENES), choices=list(SCENES))
    ap.add_argument("--chart", action="store_true", help="only redraw the chart from the JSON")
    ap.add_argument("--membrane", choices=("dkt", "regge"), default="dkt",
                    help="membrane metric of the triangle scenes (regge: written to stability_map_regge.*)")
    ap.add_argument("--one", nargs=2, metavar=("SCENE", "CONFIG"), help=argparse.SUPPRESS)
    ap.add_argument("--size", type=int, help=argparse.SUPPRESS)
    args = ap.parse_args()
    repeat = args.repeat or (1 if args.quick else 3)
    if args.one:
        print(json.dumps(run_one(*args.one, args.size, repeat, args.membrane)), flush=True)
        return
    name = ("stability_map_quick" if args.quick else "stability_map") + (
        "_regge" if args.membrane == "regge" else "")
    if args.chart:
        chart(json.loads((RESULTS / f"{name}.json").read_text()), RESULTS / f"{name}.png")
        return
    limit = args.time_limit or (300.0 if args.quick else 900.0)
    out = {"machine": machine(args.threads), "quick": args.quick, "repeat": repeat, "time_limit_s": limit,
           "membrane": args.membrane, "configs": CONFIGS, "rows": []}
    for scene in args.scenes:
        size = SCENES[scene][3 if args.quick else 4]
        for config in CONFIGS:
            row = run_isolated(scene, config, size, repeat, args.threads, limit, args.membrane)
            run_machine = row.pop("machine", None)
            if run_machine and out["machine"].get("numba_threading_layer") is None:
                out["machine"].update(run_machine)       # as the runs saw it (threads, layer)
            out["rows"].append(row)
            status = "ok" if row["converged"] else "FAILED"
            print(f"{scene:20s} {config:25s} {status:6s} its={row['newton_its']} "
                  f"krylov={row['krylov_its']} {row['wall_s']:.2f} s stable={row['stable']}"
                  + (f"  ({row['error']})" if row.get("error") else ""), flush=True)
    out["machine"]["load_average_end"] = list(os.getloadavg())
    RESULTS.mkdir(exist_ok=True)
    (RESULTS / f"{name}.json").write_text(json.dumps(out, indent=2))
    chart(out, RESULTS / f"{name}.png")


def chart(out, path):
    """Scenes x configurations: converged and stable (green), converged after
    AMG fell back to the direct solver (orange), converged but unstable or
    not assessed (yellow), failed (red); Newton
    iterations, wall time and the energy above the scene's lowest in each
    cell."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.colors import ListedColormap
    rows = out["rows"]
    scenes = list(dict.fromkeys(r["scene"] for r in rows))
    configs = out["configs"]
    lowest = {s: min((r["energy"] for r in rows if r["scene"] == s and r["converged"]
                      and r["energy"] is not None), default=None) for s in scenes}
    code = np.full((len(scenes), len(configs)), 4)
    fig, ax = plt.subplots(figsize=(2.4 * len(configs) + 2.5, 0.85 * len(scenes) + 1.5))
    for r in rows:
        i, j = scenes.index(r["scene"]), configs.index(r["config"])
        if not r["converged"]:
            code[i, j], text = 1, "failed"
        else:
            fallback = r.get("linear_used") not in (None, r.get("linear"))
            code[i, j] = 3 if fallback else (4 if r["stable"] else 2)
            text = {True: "stable", False: "unstable", None: "stability n/a"}[r["stable"]]
            if fallback:
                text += f" ({r['linear_used']})"
            text += f"\n{r['newton_its']} its, {r['wall_s']:.1f} s"
            E0 = lowest[r["scene"]]
            if E0 is not None and r["energy"] is not None:
                text += f"\ndE/|E| = {(r['energy'] - E0) / max(abs(E0), 1e-300):.1e}"
        ax.text(j, i, text, ha="center", va="center", fontsize=7.5)
    ax.imshow(code, cmap=ListedColormap(["#f4a6a6", "#f7e08a", "#f7c08a", "#a8dba8"]),
              vmin=1, vmax=4, aspect="auto")
    ax.set_xticks(range(len(configs)), configs, fontsize=8)
    ax.set_yticks(range(len(scenes)), [f"{s}\n({next(r.get('dofs') for r in rows if r['scene'] == s)} DOFs)"
                                       for s in scenes], fontsize=8)
    m = out["machine"]
    ax.set_title(f"solver stability map{' (quick sizes)' if out['quick'] else ''}: {m['cpu']}, "
                 f"{m['threads']} thread(s), direct = {m['direct_solver']}", fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=110)


if __name__ == "__main__":
    main()
