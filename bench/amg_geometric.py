"""Multigrid over nested meshes against smoothed aggregation where the
elements are shorter than the thickness (issue 10: "Krylov iterations per
Newton step growing at most logarithmically"; bench/amg_thickness_ratio.py
found that the AMG iterations follow h/l, not the mesh size).

The measure of bench/amg_thickness_ratio.py (the leaf, meshes/leaf.toml, on
shapes.disc(rings) at h = ratio / rings, its reference stiffness, CG to a
relative residual of 1e-8, one W-cycle per iteration, also where the
product cycles differently: bench/amg_cycle.py) with four hierarchies:

* ``sa``: the product's smoothed aggregation (AMGSolver: 18 near-null
  vectors, three levels);
* ``geometric``: the coarse spaces of the discs of rings / 2, rings / 4, ...
  (down to at least 11 rings, the last one solved directly), the
  prolongators the interpolation of nested iteration linearized
  (transfer.interpolation_jacobian at the reference state), coarse
  operators P^T A P;
* ``geometric-smoothed-finest``: the same with the finest prolongator
  smoothed by one block Jacobi step (as smoothed aggregation smooths its
  tentative one);
* ``geometric-smoothed``: every prolongator smoothed.

Rows: method, rings, n_triangles, dofs, h_over_l, cg_its, reason, setup_s,
cg_s, levels, level_dofs, complexity (values of all levels' operators over
the finest one's: memory).  Writes bench/results/amg_geometric.json (rows of
the cases run replace those of the same method, rings and ratio).
Run:  python bench/amg_geometric.py [--rings 45 91] [--ratios 0.5 1.8 3.6 7.3 14.6]
      [--methods sa geometric geometric-smoothed-finest geometric-smoothed]
"""

METHODS = ("sa", "geometric", "geometric-smoothed-finest", "geometric-smoothed")
COARSEST_RINGS = 11

CHILD = r"""
import json, sys
from amg_cg import amg_cg_iterations, leaf_reference
method, rings, ratio, coarsest = sys.argv[1], int(sys.argv[2]), float(sys.argv[3]), int(sys.argv[4])
shell, K, prolongators = leaf_reference(rings, ratio, nested=method != "sa", coarsest=coarsest)
options = dict(cycle="W")
if method != "sa":
    options["smoothed_levels"] = {"geometric": 0, "geometric-smoothed-finest": 1}.get(method, len(prolongators))
m = amg_cg_iterations(K, shell.block_layout(), options=options, prolongators=prolongators)
print("ROW " + json.dumps(dict(method=method, rings=rings, n_triangles=int(shell.mesh.n_triangles), dofs=int(K.shape[0]),
                               h_over_l=ratio, cg_its=m["its"], reason=m["reason"], setup_s=m["setup_s"],
                               cg_s=m["cg_s"], levels=m["levels"], complexity=m["complexity"])), flush=True)
"""


def main():
    from amg_cg import study
    study(__doc__, "amg_geometric.json",
          "CG iterations to 1e-8 on the leaf's reference stiffness: smoothed aggregation "
          "against multigrid over nested meshes", CHILD,
          [("methods", "method", str, METHODS, METHODS), ("rings", "rings", int, [45, 91], None),
           ("ratios", "h_over_l", float, [0.5, 1.8, 3.6, 7.3, 14.6], None),
           ("coarsest", "coarsest", int, [COARSEST_RINGS], None)])


if __name__ == "__main__":
    main()
