"""Which multigrid cycle for the hierarchy over nested meshes (issue 10:
the CG time of large solves; linalg.CYCLES, AMG option ``cycle``).

The second operator of multigrid over nested meshes has as many blocks as
the finest one (its prolongator is smoothed: about 10 blocks per row), so a
W-cycle, which visits it twice, costs about 1.6 finest-level cycles.  The
measure of bench/amg_geometric.py (the leaf, meshes/leaf.toml, on
shapes.disc(rings) at h = h_over_l / rings, its reference stiffness, CG to
a relative residual of 1e-8, the product's hierarchy over the discs of
rings / 2, rings / 4, ... down to 11 rings: amg_cg.leaf_reference) with
each cycle of linalg.CYCLES: "W" (every coarser level visited twice by its
parent), "V" (once), "VW" (the second level once, the coarser ones twice).

Rows: rings, n_triangles, h_over_l, cycle, cg_its, reason, setup_s, cg_s,
cycle_s (cg_s / cg_its: one iteration, a cycle and a product with the
Hessian), levels, level_blocks (nonzero 9 x 9 blocks of each level's
operator).  Writes bench/results/amg_cycle.json.
Run:  python bench/amg_cycle.py [--rings 45 91 129] [--ratios 3.6 7.3] [--cycles W V VW]
"""

CYCLES = ("W", "V", "VW")

CHILD = r"""
import json, sys
from amg_cg import amg_cg_iterations, leaf_reference
rings, ratio, cycle = int(sys.argv[1]), float(sys.argv[2]), sys.argv[3]
shell, K, prolongators = leaf_reference(rings, ratio, nested=True)
blocks = lambda amg: dict(level_blocks=[int(lv.A.indptr[-1]) for lv in amg._ml.levels])
m = amg_cg_iterations(K, shell.block_layout(), options=dict(cycle=cycle), prolongators=prolongators,
                      inspect=blocks)
print("ROW " + json.dumps(dict(rings=rings, n_triangles=int(shell.mesh.n_triangles), h_over_l=ratio, cycle=cycle,
                               cg_its=m["its"], reason=m["reason"], setup_s=m["setup_s"], cg_s=m["cg_s"],
                               cycle_s=m["cg_s"] / m["its"], levels=m["levels"],
                               level_blocks=m["level_blocks"])), flush=True)
"""


def main():
    from amg_cg import study
    study(__doc__, "amg_cycle.json",
          "AMG CG iterations and time to 1e-8 on the leaf's reference stiffness: the cycle of the "
          "hierarchy over nested meshes", CHILD,
          [("rings", "rings", int, [45, 91, 129], None), ("ratios", "h_over_l", float, [3.6, 7.3], None),
           ("cycles", "cycle", str, CYCLES, CYCLES)])


if __name__ == "__main__":
    main()
