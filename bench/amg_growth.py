"""How the AMG preconditioner's CG iterations grow with the mesh (issue 10:
"Krylov iterations per Newton step growing at most logarithmically"), and
what makes them grow on the leaf.

The leaf scene (meshes/leaf.toml) on shapes.disc(rings), at its thickness
h = 0.02 and at h = 0.005, solved by ``solve_nested`` with PARDISO to a
relative gradient of 1e-8; on the Hessian K at the solution, CG to a
relative residual of 1e-8 (fixed random right side, the measure of
bench/scaling.py's amg_cg_1e8_its), preconditioned by one W-cycle of the
default smoothed-aggregation hierarchy (shellritz.linalg.AMGSolver):

* ``full``: the hierarchy built on K (what the solver does);
* ``no_sg``: K without the strain-gradient term (strain_gradient.py; only
  where the term is active, i.e. elements shorter than h): the hierarchy on
  that matrix, CG on that matrix;
* ``split``: the hierarchy built on K without the term, its finest level
  (residuals and smoother) on K: coarse levels without the term's
  mesh-scale stiffness, CG on K;
* ``more_levels``: where the solver's hierarchy on K stops at its level
  cap (linalg.AMG_MAX_LEVELS), the same without the cap (pyamg coarsens on
  to AMG_COARSE_BLOCKS blocks).

Rows carry ``max_levels`` (the cap in effect; rows without it were
measured before the cap existed, i.e. with unlimited levels).

Rows: h, rings, n_triangles, dofs, active (fraction of elements carrying
the strain-gradient term), variant, cg_its, reason, setup_s, cg_s, levels.
Writes bench/results/amg_growth.json (rows of the cases run replace
those of the same h and rings already there).
Run:  python bench/amg_growth.py [--rings 45 91 129] [--thickness 0.02 0.005]
"""

import argparse
import json
import os
import subprocess
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
RESULTS = HERE / "results"
THREADS = 2

CHILD = r"""
import json, sys, time
import numpy as np
from importlib.resources import files
from pyamg.relaxation.smoothing import change_smoothers
from shellritz import solve_nested
from shellritz.linalg import (AMG_MAX_LEVELS, free_rigid_modes, lower_matvec, make_linear_solver,
                              projector, steihaug_cg)
from shellritz.meshdata import Surface
from shellritz.scenefile import load_scene
from shellritz import shapes
rings, h = int(sys.argv[1]), float(sys.argv[2])
scene = load_scene(files("shellritz.meshes") / "leaf.toml")
build = lambda mesh: scene.build(Surface(mesh), thickness=h)[0]
res = solve_nested(build, shapes.disc(rings), verbose=False, linear="pardiso", rtol=1e-8)
shell = res.shell
x = shell.free_state()
E, g, K = shell.evaluate(x, 2)
base = dict(h=h, rings=rings, n_triangles=int(len(shell.mesh.triangles)), dofs=int(len(x)),
            active=0.0 if shell.strain_gradient is None else float(shell.strain_gradient.active.mean()))
variants = [("full", K, K, {})]
if shell.strain_gradient is not None:
    U = shell.U.copy()
    U.reshape(-1)[shell.free] = x
    data = np.zeros(shell._nnz)
    shell.strain_gradient.add(2, shell, U, np.zeros_like(shell._Le), np.zeros_like(shell._G), data)
    Ksg = K.copy()
    Ksg.data[:] = data
    K0 = (K - Ksg).tocsr()
    K0.sort_indices()
    variants += [("no_sg", K0, K0, {}), ("split", K0, K, {})]
layout = shell.block_layout()
project = projector(free_rigid_modes(layout))
b = np.random.default_rng(0).standard_normal(K.shape[0])
b = project(b) if project is not None else b
for name, Kh, Kcg, options in variants:
    amg = make_linear_solver("amg", Kh.shape[0], Kh.indptr, Kh.indices, layout)
    amg.options = options
    t = time.perf_counter()
    amg.factorize(Kh)
    if Kcg is not Kh:
        smoother = ("block_gauss_seidel", {"sweep": "symmetric", "iterations": 2})
        amg._ml.levels[0].A = amg._embed(Kcg)
        change_smoothers(amg._ml, smoother, smoother)
    setup = time.perf_counter() - t
    t = time.perf_counter()
    _, info = steihaug_cg(lower_matvec(Kcg), -b, amg.preconditioner(), rtol=1e-8, maxiter=1000,
                          project=project)
    row = dict(base, variant=name, cg_its=info["iterations"], reason=info["reason"], setup_s=setup,
               cg_s=time.perf_counter() - t, levels=len(amg._ml.levels),
               max_levels=options.get("max_levels", AMG_MAX_LEVELS))
    amg.release()
    print("ROW " + json.dumps(row), flush=True)
    if name == "full" and row["levels"] == AMG_MAX_LEVELS:
        variants.append(("more_levels", K, K, {"max_levels": 10}))
"""


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--rings", type=int, nargs="+", default=[45, 91, 129])
    ap.add_argument("--thickness", type=float, nargs="+", default=[0.02, 0.005])
    args = ap.parse_args()
    env = dict(os.environ, NUMBA_NUM_THREADS=str(THREADS), OMP_NUM_THREADS=str(THREADS),
               MKL_NUM_THREADS=str(THREADS))
    sys.path.insert(0, str(HERE))
    from machine import machine_info
    RESULTS.mkdir(exist_ok=True)
    path = RESULTS / "amg_growth.json"
    rows = json.loads(path.read_text())["rows"] if path.exists() else []
    for h in args.thickness:
        for rings in args.rings:
            out = subprocess.run([sys.executable, "-c", CHILD, str(rings), str(h)], env=env,
                                 capture_output=True, text=True)
            got = [json.loads(line[4:]) for line in out.stdout.splitlines() if line.startswith("ROW ")]
            if not got:
                got = [dict(h=h, rings=rings, variant="full", error=out.stderr.strip().splitlines()[-1:])]
            for r in got:
                print(json.dumps(r), flush=True)
            rows = [r for r in rows if (r["h"], r["rings"]) != (h, rings)] + got
            # written after every case: a long run stopped early keeps what it measured
            path.write_text(json.dumps(
                {"benchmark": "AMG CG iterations to 1e-8 on the leaf Hessian at the solution",
                 "threads": THREADS, "machine": machine_info(), "rows": rows}, indent=2))


if __name__ == "__main__":
    main()
