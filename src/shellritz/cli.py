"""Command-line entry point: ``shellritz`` runs the embedded default scene.

Default scene: a growing leaf.  A flat disc of radius 1 (the shipped mesh
``meshes/disc.vtu``), thickness 0.02, compressible neo-Hookean (nu = 0.4),
grows in its plane by gamma = 1 + 0.3 rho^2 (rho: distance from the centre),
so the rim has more length than a flat disc can hold; a small through-thickness
growth gradient G1 = diag(0.5, -0.5, 0) picks the orientation.  The disc
buckles into a saddle (negative Gaussian curvature), as growing leaves and
petals do.  The centre node is clamped (rigid motions only).

Writes ``leaf.vtu`` (deformed mesh with displacement, director, stretches and
stresses), ``leaf.png`` and ``leaf.json`` (energy, solver history, timings).
"""

import argparse
import json
import sys
import time
from importlib.resources import files
from pathlib import Path

import numpy as np


def leaf_scene(out_dir, steps=10, verbose=True):
    from . import Mesh, NeoHookean, Shell

    mesh = Mesh.read(files("shellritz.meshes") / "disc.vtu",
                     normal=lambda X: np.tile([0.0, 0.0, 1.0], (len(X), 1)))
    X = mesh.vertices
    gamma = 1.0 + 0.3 * (X[:, 0] ** 2 + X[:, 1] ** 2)
    G0 = np.zeros((mesh.n_nodes, 3, 3))
    G0[:, 0, 0] = G0[:, 1, 1] = gamma
    G0[:, 2, 2] = 1.0
    shell = Shell(mesh, thickness=0.02, material=NeoHookean(1.0, nu=0.4))
    shell.set_growth(G0=G0, G1=np.diag([0.5, -0.5, 0.0]))
    shell.clamp(mesh.nodes_where(lambda X: np.hypot(X[:, 0], X[:, 1]) < 1e-9))
    result = shell.solve(steps=steps, verbose=verbose)
    result.save(out_dir / "leaf.vtu")
    r = result.r
    summary = {
        "scene": "growing leaf: disc, in-plane growth 1 + 0.3 rho^2, G1 = diag(0.5, -0.5, 0)",
        "triangles": mesh.n_triangles, "free_dofs": int(len(shell.free)),
        "energy": result.energy, "wall_s": result.wall_s,
        "newton_iterations": len(result.history.iterations),
        "continuation_steps": [[float(t), bool(ok)] for t, ok in result.history.steps],
        "stable": bool(result.history.stable),
        "unstable_modes": result.history.unstable_modes,
        "height_range": [float(r[:, 2].min()), float(r[:, 2].max())],
    }
    (out_dir / "leaf.json").write_text(json.dumps(summary, indent=2))
    picture(mesh, r, out_dir / "leaf.png")
    return summary


def picture(mesh, r, path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig = plt.figure(figsize=(7, 5.5))
    ax = fig.add_subplot(projection="3d")
    surf = ax.plot_trisurf(r[:, 0], r[:, 1], r[:, 2], triangles=mesh.triangles, cmap="viridis",
                           linewidth=0.1, edgecolor=(0, 0, 0, 0.15), antialiased=True)
    fig.colorbar(surf, ax=ax, shrink=0.6, label="height z")
    span = np.ptp(r, axis=0).max() / 2
    c = r.mean(axis=0)
    ax.set_xlim(c[0] - span, c[0] + span)
    ax.set_ylim(c[1] - span, c[1] + span)
    ax.set_zlim(c[2] - span, c[2] + span)
    ax.set_title("growing leaf: saddle from excess rim growth")
    ax.view_init(elev=25, azim=-60)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main(argv=None):
    ap = argparse.ArgumentParser(prog="shellritz", description=__doc__.splitlines()[0])
    ap.add_argument("-o", "--out", default="shellritz-output",
                    help="output directory (default: ./shellritz-output)")
    ap.add_argument("-q", "--quiet", action="store_true", help="no per-iteration report")
    args = ap.parse_args(argv)
    out_dir = Path(args.out)
    out_dir.mkdir(parents=True, exist_ok=True)
    t = time.perf_counter()
    print("shellritz: default scene, a growing leaf (the first run compiles the Numba kernels, "
          "a few minutes; cached afterwards)", flush=True)
    summary = leaf_scene(out_dir, verbose=not args.quiet)
    print(f"saddle height range {summary['height_range'][0]:.3f} .. {summary['height_range'][1]:.3f}, "
          f"{summary['newton_iterations']} Newton iterations")
    print(f"wrote {out_dir / 'leaf.vtu'}, {out_dir / 'leaf.png'}, {out_dir / 'leaf.json'} "
          f"in {time.perf_counter() - t:.1f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
