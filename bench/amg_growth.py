"""How the AMG preconditioner's CG iterations grow with the mesh (issue 10:
"Krylov iterations per Newton step growing at most logarithmically"), and
what makes them grow on the leaf.

The leaf scene (meshes/leaf.toml) on shapes.disc(rings), at its thickness
h = 0.02 and at h = 0.005, solved by ``solve_nested`` with PARDISO to a
relative gradient of 1e-8; on the Hessian K at the solution, the measure
of bench/amg_cg.py (also scaling.py's amg_cg_1e8_its: CG to a relative
residual of 1e-8, one W-cycle of shellritz's AMG hierarchy per iteration):

* ``full``: the hierarchy built on K (what the solver does);
* ``no_sg``: K without the strain-gradient term (strain_gradient.py; only
  where the term is active, i.e. elements shorter than h): the hierarchy on
  that matrix, CG on that matrix;
* ``split``: the hierarchy built on K without the term, its finest level
  (residuals and smoother) on K: coarse levels without the term's
  mesh-scale stiffness, CG on K;
* ``more_levels``: where the solver's hierarchy on K stopped at its level
  cap (linalg.AMG_MAX_LEVELS) above AMG_COARSE_BLOCKS, the same without the
  cap (pyamg coarsens on to AMG_COARSE_BLOCKS blocks).

Rows carry ``max_levels`` (the cap in effect; rows without it were
measured before the cap existed, i.e. with unlimited levels) and
``strength_theta`` (linalg.AMG_STRENGTH_THETA; rows without it: 0).

Rows: h, rings, n_triangles, dofs, active (fraction of elements carrying
the strain-gradient term), variant, cg_its, reason, setup_s, cg_s, levels,
coarsest_blocks (newer rows).
Writes bench/results/amg_growth.json (rows of the cases run replace
those of the same h and rings already there).
Run:  python bench/amg_growth.py [--rings 45 91 129] [--thickness 0.02 0.005]
"""

CHILD = r"""
import json, sys
import numpy as np
from importlib.resources import files
from amg_cg import amg_cg_iterations
from shellritz import shapes, solve_nested
from shellritz.linalg import AMG_COARSE_BLOCKS, AMG_MAX_LEVELS, AMG_STRENGTH_THETA
from shellritz.meshdata import Surface
from shellritz.scenefile import load_scene
rings, h = int(sys.argv[1]), float(sys.argv[2])
scene = load_scene(files("shellritz.meshes") / "leaf.toml")
# the DKT membrane metric, as the results were measured (the scene file's is regge since 2026-12-07)
build = lambda mesh: scene.build(Surface(mesh), thickness=h, membrane="dkt")[0]
shell = solve_nested(build, shapes.disc(rings), verbose=False, linear="pardiso", rtol=1e-8).shell
x = shell.free_state()
_, _, K = shell.evaluate(x, 2)
base = dict(h=h, rings=rings, n_triangles=int(len(shell.mesh.triangles)), dofs=int(len(x)),
            active=0.0 if shell.strain_gradient is None else float(shell.strain_gradient.active.mean()))
variants = [("full", K, None, {})]       # (name, hierarchy on, finest level, pyamg options)
if shell.strain_gradient is not None:
    U = shell.U.copy()
    U.reshape(-1)[shell.free] = x
    data = np.zeros(shell._nnz)           # the term's Hessian alone, in K's pattern
    shell.strain_gradient.add(2, shell, U, np.zeros_like(shell._Le), np.zeros_like(shell._G), data)
    Ksg = K.copy()
    Ksg.data[:] = data
    K0 = (K - Ksg).tocsr()
    K0.sort_indices()
    variants += [("no_sg", K0, None, {}), ("split", K0, K, {})]
layout = shell.block_layout()
for name, Kh, finest, options in variants:
    m = amg_cg_iterations(Kh, layout, finest, options)
    row = dict(base, variant=name, cg_its=m["its"], reason=m["reason"], setup_s=m["setup_s"],
               cg_s=m["cg_s"], levels=m["levels"], coarsest_blocks=m["coarsest_blocks"],
               max_levels=options.get("max_levels", AMG_MAX_LEVELS), strength_theta=AMG_STRENGTH_THETA)
    print("ROW " + json.dumps(row), flush=True)
    if name == "full" and m["levels"] == AMG_MAX_LEVELS and m["coarsest_blocks"] > AMG_COARSE_BLOCKS:
        variants.append(("more_levels", K, None, {"max_levels": 10}))
"""


def main():
    from amg_cg import study
    study(__doc__, "amg_growth.json", "AMG CG iterations to 1e-8 on the leaf Hessian at the solution", CHILD,
          [("rings", "rings", int, [45, 91, 129], None), ("thickness", "h", float, [0.02, 0.005], None)])


if __name__ == "__main__":
    main()
