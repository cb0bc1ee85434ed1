"""Invagination of a spherical cell sheet (the paper's section 6 scene).

A sphere of radius 1 and thickness h = 0.1 (neo-Hookean, nu = 0.4) grows with
the stretches of eq:gg in a band around the equator: azimuthal compression
(gamma1 < 1), meridional extension (gamma2 > 1) and a through-thickness
gradient of the meridional growth.  The sheet folds inwards into a furrow.

The scene is axisymmetric, so the meridian engine solves it (128 Hermite
elements, well under a second); the triangle engine on a quarter of the
sphere confirms it.  Writes invagination.png, invagination.vtu (the meridian)
and invagination_dkt.vtu (the triangulated quarter sphere with all fields).

    python examples/invagination.py [output directory]
"""

import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from shellritz.scenes import invagination  # noqa: E402


def main(out=Path(".")):
    out.mkdir(parents=True, exist_ok=True)
    scene = invagination()
    one_d = scene.solve("axisym", n=128, steps=8)
    print(f"axisymmetric engine: {one_d.dofs} unknowns, {one_d.iterations} Newton iterations, "
          f"{one_d.wall_s:.2f} s")
    tri = scene.solve("dkt", n=32, steps=8)
    a, b = one_d.raw.at(tri.s)
    print(f"triangle engine (quarter sphere): {tri.dofs} unknowns, {tri.wall_s:.1f} s; "
          f"max distance between the meridians {np.hypot(tri.a - a, tri.b - b).max():.1e}")
    one_d.raw.save(out / "invagination.vtu")
    tri.raw.save(out / "invagination_dkt.vtu")

    s = np.linspace(0, np.pi, 400)
    g1, g2, _, _, g2z = (f(s) for f in scene.gamma)
    fig, (ax0, ax1) = plt.subplots(1, 2, figsize=(10, 5), gridspec_kw={"width_ratios": [1, 1.2]})
    ax0.plot(s, g1, label=r"$\gamma_1$ (azimuthal)")
    ax0.plot(s, g2, label=r"$\gamma_2$ (meridional)")
    ax0.plot(s, g2 + scene.h / 2 * g2z, "--", label=r"$\gamma_2$ on the outer face")
    ax0.set_xlabel("polar angle s of the reference sphere")
    ax0.set_title("growth stretches (eq:gg)")
    ax0.legend()
    ref_a, ref_b = np.sin(s), 1 - np.cos(s)
    a_fine, b_fine = one_d.raw.at(s)
    for sign in (1, -1):
        ax1.plot(sign * ref_a, ref_b, ":", color="0.5", label="reference" if sign > 0 else None)
        ax1.plot(sign * a_fine, b_fine, color="C0", label="axisymmetric engine" if sign > 0 else None)
    ax1.plot(tri.a, tri.b, "o", ms=3, color="C3", label="triangle engine (n = 32)")
    ax1.set_aspect("equal")
    ax1.set_title("meridian section: reference and grown")
    ax1.legend(loc="lower center", fontsize=8)
    fig.tight_layout()
    fig.savefig(out / "invagination.png", dpi=110)
    print(f"wrote {out / 'invagination.png'}, {out / 'invagination.vtu'}, {out / 'invagination_dkt.vtu'}")


if __name__ == "__main__":
    main(Path(sys.argv[1]) if len(sys.argv) > 1 else Path("."))
