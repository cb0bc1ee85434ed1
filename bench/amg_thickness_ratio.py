"""What the AMG preconditioner's CG iterations depend on: the mesh size or
the ratio of the thickness to the element length, h/l (issue 10: "Krylov
iterations per Newton step growing at most logarithmically").

Refining the default leaf (h = 0.02) raises h/l with the mesh (1.8 at 50k
triangles, 3.3 at 199k, 7 at 1M); where elements are shorter than h the
strain-gradient term (R = C |grad grad eps|^2) makes the operator of sixth
order at the mesh scale.  This benchmark keeps the two apart: the leaf
(meshes/leaf.toml) on shapes.disc(rings) with its thickness set to
h = ratio / rings (rings ~ 1 / l), and on its reference stiffness (the
Hessian at the flat reference state, t = 0: no solve needed, symmetric
positive semi-definite with the six rigid modes) the measure of
bench/amg_cg.py: CG to a relative residual of 1e-8, one W-cycle of
shellritz's AMG hierarchy per iteration, free rigid motions projected out.

Rows: rings, n_triangles, dofs, h, h_over_l, strain_gradient (the term
on), cg_its, reason, setup_s, cg_s, levels, coarsest_blocks.  The file
also keeps ``before``: the same measure with the code of commit 539d236
(2026-12-05: prolongation smoothing weighted by the row sums of |A|),
copied from that run, ``before_near_null``: that of commit 64b8d37,
whose near null space kept candidates that vanish on the planar reference,
and ``before_diagonal``: that of commit 4a70aae (prolongation smoothing by
the scalar diagonal instead of the nodal blocks).
Writes bench/results/amg_thickness_ratio.json (rows of the cases run
replace those of the same rings and ratio).
Run:  python bench/amg_thickness_ratio.py [--rings 45 91 129] [--ratios 0.5 1.8 3.6 7.3]
"""

CHILD = r"""
import json, sys
from amg_cg import amg_cg_iterations, leaf_reference
rings, ratio = int(sys.argv[1]), float(sys.argv[2])
shell, K, _ = leaf_reference(rings, ratio)
m = amg_cg_iterations(K, shell.block_layout())
print("ROW " + json.dumps(dict(rings=rings, n_triangles=int(shell.mesh.n_triangles), dofs=int(K.shape[0]),
                               h=ratio / rings, h_over_l=ratio,
                               strain_gradient=shell.strain_gradient is not None,
                               cg_its=m["its"], reason=m["reason"], setup_s=m["setup_s"], cg_s=m["cg_s"],
                               levels=m["levels"], coarsest_blocks=m["coarsest_blocks"])), flush=True)
"""

# commit 539d236, the same measure (2026-12-05, 2 threads, one run each)
BEFORE = [dict(rings=45, n_triangles=12150, h_over_l=0.5, cg_its=24),
          dict(rings=45, n_triangles=12150, h_over_l=1.8, cg_its=23),
          dict(rings=45, n_triangles=12150, h_over_l=3.6, cg_its=55),
          dict(rings=45, n_triangles=12150, h_over_l=7.3, cg_its=186),
          dict(rings=91, n_triangles=49686, h_over_l=1.8, cg_its=28),
          dict(rings=91, n_triangles=49686, h_over_l=3.6, cg_its=58)]
# commit 64b8d37 (2026-12-05, night): the near null space with the candidates
# that vanish or are rigid rotations on the planar reference (3 bending modes,
# 3 strains), before they were left out for in-plane quadratic displacements
BEFORE_NEAR_NULL = [dict(rings=45, n_triangles=12150, h_over_l=r, cg_its=i)
                    for r, i in ((0.5, 12), (1.8, 13), (3.6, 44), (7.3, 136))] + \
                   [dict(rings=91, n_triangles=49686, h_over_l=r, cg_its=i)
                    for r, i in ((0.5, 23), (1.8, 14), (3.6, 48), (7.3, 150))]

# commit 4a70aae (2026-12-05, night, to 2026-12-07): prolongation smoothing
# by the scalar diagonal (pyamg's 'diagonal' weighting), before the nodal
# blocks (block Jacobi)
BEFORE_DIAGONAL = [dict(rings=rings, n_triangles=n, h_over_l=r, cg_its=i)
                   for rings, n, its in ((45, 12150, (12, 13, 29, 72)), (91, 49686, (12, 14, 32, 82)),
                                         (129, 99846, (13, 15, 33, 88)))
                   for r, i in zip((0.5, 1.8, 3.6, 7.3), its)]


def main():
    from amg_cg import study
    study(__doc__, "amg_thickness_ratio.json",
          "AMG CG iterations to 1e-8 on the leaf's reference stiffness against h/l", CHILD,
          [("rings", "rings", int, [45, 91, 129], None), ("ratios", "h_over_l", float, [0.5, 1.8, 3.6, 7.3], None)],
          extra={"before": {"commit": "539d236", "rows": BEFORE},
                 "before_near_null": {"commit": "64b8d37", "rows": BEFORE_NEAR_NULL},
                 "before_diagonal": {"commit": "4a70aae", "rows": BEFORE_DIAGONAL}})


if __name__ == "__main__":
    main()
