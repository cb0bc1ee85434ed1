"""Command-line entry point: ``shellritz`` runs the embedded default scene.

Until the triangle engine lands, the default scene is a point-kernel
demonstration on the paper's gradient-growth strip (section 5.2): the energy
density L of the three model levels as a function of the imposed bending
curvature of the middle surface.  The exact 3D solution is stress free at the
curvature gamma1 (eq:x0z0asy), where the consistent and bending energies
vanish with zero gradient.
"""

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np


def strip_scene(out_dir, n=81):
    from .materials import NeoHookean
    from .model import LEVELS, evaluate_point

    g0, g1, h, D = 1.2, 0.8, 0.1, 2.0
    law = NeoHookean(1.0, D=D)
    growth = dict(G0=np.diag([g0, 1.0, 1.0]), G1=np.diag([g1, 0.0, 0.0]))
    ref = np.zeros(15)
    ref[0] = ref[4] = 1.0
    curv = np.linspace(-0.5 * g1, 2.5 * g1, n)   # curvature of the middle surface (1/length)
    result = {"scene": "gradient-growth strip at a point (paper section 5.2)",
              "law": f"neo-Hookean C=1 D={D}", "h": h, "gamma0": g0, "gamma1": g1,
              "curvature": curv.tolist(), "energy_density": {}, "y1_at_exact": None}
    for level in LEVELS:
        L = []
        for k in curv:
            # middle surface x0' = g0 (1, 0, 0), x0'' = g0 k (0, 0, -1) at X = 0
            v = ref.copy()
            v[0] = g0
            v[8] = -g0 * k
            L.append(evaluate_point(law, v, ref, h, level, **growth, mode="energy").L)
        result["energy_density"][level] = L
        if level == "membrane":
            print(f"  {level:>10}: L = {L[0]:.3e} for every curvature (no bending energy)")
        else:
            print(f"  {level:>10}: min L = {min(L):.3e} at curvature "
                  f"{curv[int(np.argmin(L))]:.3f} (exact stress-free curvature {g1})", flush=True)
    v = ref.copy()
    v[0] = g0
    v[8] = -g0 * g1
    r = evaluate_point(law, v, ref, h, "consistent", **growth)
    result["at_exact_curvature"] = {"L": r.L, "max_abs_gradient": float(np.abs(r.grad).max()),
                                    "y1": r.y1.tolist(), "y2": r.y2.tolist()}
    print(f"  at the exact curvature: L = {r.L:.2e}, |dL/dv| = {np.abs(r.grad).max():.2e}")
    (out_dir / "strip_point.json").write_text(json.dumps(result, indent=2))

    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(6, 4))
    for level, L in result["energy_density"].items():
        ax.plot(curv, L, label=level)
    ax.axvline(g1, color="k", ls="--", lw=1, label="exact stress-free curvature")
    ax.set_xlabel("bending curvature of the middle surface")
    ax.set_ylabel("energy density L (per unit reference area)")
    ax.set_title("growing strip, G = diag(1.2 + 0.8 Z, 1, 1), h = 0.1")
    ax.legend()
    fig.tight_layout()
    fig.savefig(out_dir / "strip_point.png", dpi=110)
    return result


def main(argv=None):
    ap = argparse.ArgumentParser(prog="shellritz", description=__doc__.splitlines()[0])
    ap.add_argument("-o", "--out", default="shellritz-output",
                    help="output directory (default: ./shellritz-output)")
    args = ap.parse_args(argv)
    out_dir = Path(args.out)
    out_dir.mkdir(parents=True, exist_ok=True)
    t = time.perf_counter()
    print("shellritz: default scene (first run compiles the Numba kernels, about a minute)",
          flush=True)
    strip_scene(out_dir)
    print(f"wrote {out_dir / 'strip_point.json'} and {out_dir / 'strip_point.png'} "
          f"in {time.perf_counter() - t:.1f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
