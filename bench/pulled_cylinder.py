"""Pull-out of an open-ended cylinder (Sze, Liu & Lo 2004, section 3.5) by
arc length on the DKT engine, several meshes of the octant, against the
paper's reference table (benchmark_scenes.PULLED_CYLINDER_REFERENCE).

Writes bench/results/pulled_cylinder.json (per mesh: the path P, w_A, -u_B,
-u_C, inertia; wall time; the values at P = 40 000 and their deviation from
the reference), the paths as CSV (history.write_path), the machine (bench/machine.py) and the
chart bench/results/pulled_cylinder.png.

Run:  python bench/pulled_cylinder.py [--quick]      (quick: 8 x 8 and 12 x 12)
"""

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

from shellritz.benchmark_scenes import (PULLED_CYLINDER, PULLED_CYLINDER_REFERENCE, pulled_cylinder,
                                        pulled_cylinder_monitor)

sys.path.insert(0, str(Path(__file__).resolve().parent))      # bench/machine.py
from machine import machine_info  # noqa: E402

RESULTS = Path(__file__).resolve().parent / "results"


def run(n, arc_max_ds):
    shell = pulled_cylinder(n)
    t0 = time.perf_counter()
    res = shell.solve(steps=10, path="arclength", arc_max_ds=arc_max_ds, verbose=False,
                      monitor=pulled_cylinder_monitor)
    wall = time.perf_counter() - t0
    h = res.history
    h.write_path(RESULTS / f"pulled_cylinder_{n}x{n}.csv")
    t = np.array([p["t"] for p in h.path])
    w_a, u_b, u_c = np.array([p["monitor"] for p in h.path]).T
    final = np.array([w_a[-1], -u_b[-1], -u_c[-1]])
    ref = PULLED_CYLINDER_REFERENCE[-1, 1:]
    return {"n": n, "n_triangles": shell.mesh.n_triangles, "dofs": len(shell.free),
            "arc_max_ds": arc_max_ds, "wall_s": wall, "newton_its": len(h.iterations),
            "P": (PULLED_CYLINDER["P"] * t).tolist(), "w_A": w_a.tolist(), "minus_u_B": (-u_b).tolist(),
            "minus_u_C": (-u_c).tolist(), "negative": [p["negative"] for p in h.path],
            "at_P_max": dict(zip(("w_A", "minus_u_B", "minus_u_C"), final.tolist())),
            "relative_to_reference": dict(zip(("w_A", "minus_u_B", "minus_u_C"), (final / ref - 1).tolist()))}


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true")
    args = ap.parse_args()
    RESULTS.mkdir(exist_ok=True)
    meshes = [(8, 0.05), (12, 0.05)] if args.quick else [(8, 0.05), (16, 0.03), (24, 0.03), (32, 0.03)]
    out = {"reference": {"source": "Sze, Liu & Lo 2004, section 3.5 (24 x 36 S4R), as transcribed in "
                                   "MBDyn tests/plates/sze2004/sze35/sze35_ref.dat",
                         "columns": ["P/P_max", "w_A", "-u_B", "-u_C"],
                         "rows": PULLED_CYLINDER_REFERENCE.tolist()},
           "data": PULLED_CYLINDER, "runs": []}
    for n, ds in meshes:
        r = run(n, ds)
        out["runs"].append(r)
        d = r["relative_to_reference"]
        print(f"{n:3d} x {n:<3d} {r['wall_s']:7.1f} s {r['newton_its']:4d} its  at P_max: "
              + "  ".join(f"{k} {r['at_P_max'][k]:.4f} ({100 * d[k]:+.1f} %)" for k in d), flush=True)
    out["machine"] = machine_info()
    name = "pulled_cylinder_quick" if args.quick else "pulled_cylinder"
    (RESULTS / f"{name}.json").write_text(json.dumps(out, indent=1))
    chart(out, RESULTS / f"{name}.png")


def chart(out, path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    ref = np.array(out["reference"]["rows"])
    Pmax = out["data"]["P"]
    fig, ax = plt.subplots(figsize=(6.5, 4.5))
    for col, key, colour in ((1, "w_A", "C0"), (2, "minus_u_B", "C1"), (3, "minus_u_C", "C2")):
        ax.plot(ref[:, col], ref[:, 0] * Pmax, "o", mfc="none", color=colour,
                label=f"{out['reference']['columns'][col]}, Sze et al.")
        for k, r in enumerate(out["runs"]):
            ax.plot(r[key], r["P"], "-", color=colour, alpha=0.35 + 0.65 * (k + 1) / len(out["runs"]),
                    lw=1.2, label=f"{r['n']} x {r['n']}" if col == 1 else None)
    ax.set_xlabel("radial displacement")
    ax.set_ylabel("pulling force P")
    ax.set_title("pulled open cylinder (Sze et al. 2004, 3.5): arc length, DKT octant", fontsize=9)
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=110)


if __name__ == "__main__":
    main()
