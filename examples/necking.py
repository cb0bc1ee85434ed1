"""Necking of a plane-strain block past the force maximum (paper section 4.3,
docs/necking.md section 7).

A block of length l = 1 and thickness h = 0.2 of the power-law hardening
solid (shellritz.necking.default_law: Considere maximum at a plane-strain
stretch of 1.2422, strong ellipticity lost at 1.6023) is pulled by shear-free
grips to an end stretch of 1.3.  A thickness imperfection of 1e-3 (growth
gamma_n = 1 - 1e-3 cos(pi X / l)) puts the neck at X = 0.

* The plane-strain shell engine (symmetric kinematics: the middle surface
  held on z = 0; 20 and 40 Hermite elements) follows the path with the
  solver's pseudo-arc-length continuation (shellritz.necking.follow_neck):
  past the force maximum, through the fold where the neck snaps back, and on
  to the end stretch.
* The 2D solid reference (bench/necking_2d.py: scikit-fem Q2 block, its own
  pseudo-arclength continuation, up to the loss of strong ellipticity in the
  neck) is read from bench/results/necking_2d_path.json.

The two are compared along the path (the 2D path interpolated by cubic
splines): up to the force maximum at equal end stretch, past it at equal
thinnest section.  The shell path past the loss of ellipticity in the neck
is charted (dotted) but is no longer a model of the solid.

Writes necking.png (force against elongation, thinnest section, neck
profiles) and necking.json (landmarks, differences, the paths).

    python examples/necking.py [output directory]
"""

import json
import sys
import time
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from scipy.interpolate import CubicSpline  # noqa: E402

from shellritz.necking import (considere_stretch, default_law, ellipticity_stretch,  # noqa: E402
                               follow_neck, necking_strip, onset_stretch, path_landmarks)

H, LENGTH, IMPERFECTION, END_STRETCH = 0.2, 1.0, 1e-3, 1.3
MESHES, STEPS = (20, 40), 30
SOLID_PATH = Path(__file__).resolve().parent.parent / "bench" / "results" / "necking_2d_path.json"
PROFILE_T_MIN = (0.95, 0.87, 0.81, 0.75, 0.68)       # neck profiles drawn at these t_min / h
KNEE = 1.05     # compared past the yield knee (eps0 = 0.02), where the 2D path splines to < 1e-6


def shell_path(law, n, lam_e):
    eng = necking_strip(law, H, LENGTH, n, END_STRETCH, imperfection=IMPERFECTION, symmetric=True)
    t0 = time.perf_counter()
    rows, stop = follow_neck(eng, STEPS, max_ds=1.0 / STEPS)      # evenly sampled for the charts
    wall = time.perf_counter() - t0
    marks = path_landmarks([r["lam"] for r in rows], [r["force"] for r in rows],
                           [r["t_min"] for r in rows], [lam_e - r["stretch_max"] for r in rows])
    return {"n": n, "rows": rows, "stop": stop, "wall_s": wall, "landmarks": marks}


def compare(shell, srows, solid_marks):
    """Shell minus 2D solid along the path, the 2D path interpolated by cubic
    splines: from the yield knee to the 2D force maximum at equal end
    stretch (force, thinnest section), past it at equal thinnest section
    (end stretch, force), as far as the 2D path is strongly elliptic.
    Forces relative to the 2D maximum, sections to h."""
    k_max, k_lost = solid_marks["force_max"]["index"], solid_marks["ellipticity_loss"]["index"]
    rising, past = srows[:k_max + 1], srows[k_max:k_lost][::-1]
    fmax, t_max = solid_marks["force_max"]["force"], solid_marks["force_max"]["t_min"]
    spline = lambda rows, x, y: CubicSpline([r[x] for r in rows], [r[y] for r in rows])
    f_of_lam, t_of_lam = spline(rising, "lam", "force"), spline(rising, "lam", "t_min")
    lam_of_t, f_of_t = spline(past, "t_min", "lam"), spline(past, "t_min", "force")
    out = []
    for r in shell["rows"]:
        if r["t_min"] > t_max and KNEE <= r["lam"] <= rising[-1]["lam"]:
            out.append({"part": "rising", "lam": r["lam"], "t_min": r["t_min"],
                        "d_force": (r["force"] - float(f_of_lam(r["lam"]))) / fmax,
                        "d_t_min": (r["t_min"] - float(t_of_lam(r["lam"]))) / H})
        elif past[0]["t_min"] <= r["t_min"] <= t_max:
            out.append({"part": "past the maximum", "lam": r["lam"], "t_min": r["t_min"],
                        "d_lam": r["lam"] - float(lam_of_t(r["t_min"])),
                        "d_force": (r["force"] - float(f_of_t(r["t_min"]))) / fmax})
    return out


def largest(diffs, part, key):
    return max(abs(d[key]) for d in diffs if d["part"] == part)


def solid_profile(srows, t_min):
    """The 2D neck profile (x, thickness) at a thinnest section t_min,
    linear between the path points around it."""
    k = next(k for k, r in enumerate(srows) if r["t_min"] <= t_min)
    a, b = srows[k - 1], srows[k]
    w = (a["t_min"] - t_min) / (a["t_min"] - b["t_min"])
    mix = lambda key: (1 - w) * np.asarray(a[key]) + w * np.asarray(b[key])
    return mix("x"), mix("thickness")


def main(out=Path(".")):
    out.mkdir(parents=True, exist_ok=True)
    law = default_law()
    lam_m, lam_c, lam_e = considere_stretch(law), onset_stretch(law, H / LENGTH), ellipticity_stretch(law)
    if not SOLID_PATH.exists():
        raise SystemExit(f"{SOLID_PATH} missing: run python bench/necking_2d.py first")
    solid = json.loads(SOLID_PATH.read_text())
    srows = solid["rows"]
    solid_marks = path_landmarks([r["lam"] for r in srows], [r["force"] for r in srows],
                                 [r["t_min"] for r in srows], [r["ellipticity"] for r in srows])
    shells = [shell_path(law, n, lam_e) for n in MESHES]
    for sh in shells:
        sh["vs_2d"] = compare(sh, srows, solid_marks)
    print(f"Considere {lam_m:.5f}, onset of the perfect block {lam_c:.5f}, plane-strain tension "
          f"loses strong ellipticity at {lam_e:.5f}")

    def line(name, m):
        parts = [f"{k.replace('_', ' ')} {v['lam']:.5f} (t_min {v['t_min'] / H:.3f} h)"
                 for k, v in m.items() if v is not None]
        print(f"  {name}: " + ", ".join(parts))
    line(f"2D solid (nz = {solid['nz']})", solid_marks)
    for sh in shells:
        line(f"shell n = {sh['n']}", sh["landmarks"])
        d = sh["vs_2d"]
        print(f"    {len(sh['rows'])} path points, {sh['wall_s']:.0f} s, {sh['stop']}; against the 2D solid: "
              f"to its force maximum at equal stretch |d force| <= {largest(d, 'rising', 'd_force'):.1e} "
              f"F_max, |d t_min| <= {largest(d, 'rising', 'd_t_min'):.1e} h; past it (to t_min "
              f"{min(p['t_min'] for p in d) / H:.3f} h) at equal t_min |d lam| <= "
              f"{largest(d, 'past the maximum', 'd_lam'):.1e}, |d force| <= "
              f"{largest(d, 'past the maximum', 'd_force'):.1e} F_max")
    summary = {"h": H, "length": LENGTH, "imperfection": IMPERFECTION, "end_stretch": END_STRETCH,
               "considere": lam_m, "onset_perfect": lam_c, "ellipticity_stretch": lam_e,
               "solid": {"nz": solid["nz"], "stop": solid["stop"], "landmarks": solid_marks},
               "shell": [{k: sh[k] for k in ("n", "stop", "wall_s", "landmarks", "vs_2d")}
                         | {"path": [{k: r[k] for k in ("lam", "force", "t_min", "stretch_max", "negative")}
                                     for r in sh["rows"]]} for sh in shells]}
    (out / "necking.json").write_text(json.dumps(summary, indent=1))
    chart(shells, srows, solid_marks, solid["nz"], out / "necking.png")
    return summary


def chart(shells, srows, solid_marks, nz, path):
    fig, axes = plt.subplots(1, 3, figsize=(15, 4.8))
    ax, bx, cx = axes
    inset = ax.inset_axes([0.45, 0.1, 0.52, 0.5])
    k_lost = solid_marks["ellipticity_loss"]["index"]
    colors = ("C0", "C1")
    for a in (ax, inset, bx):
        y = (lambda r: r["force"] / H) if a is not bx else (lambda r: r["t_min"] / H)
        a.plot([r["lam"] for r in srows[:k_lost]], [y(r) for r in srows[:k_lost]], "-", color="k", lw=2.2,
               alpha=0.35, label=f"2D solid (Q2, {nz} elements in h/2)")
        for sh, c in zip(shells, colors):
            rows = sh["rows"]
            k = sh["landmarks"]["ellipticity_loss"]["index"]
            a.plot([r["lam"] for r in rows[:k]], [y(r) for r in rows[:k]], ".-", color=c, ms=3, lw=1,
                   label=f"shell engine, {sh['n']} elements, arc length")
            a.plot([r["lam"] for r in rows[k - 1:]], [y(r) for r in rows[k - 1:]], ":", color=c, lw=1)
        for m, c, name in ((shells[0]["landmarks"], "r", "shell: middle surface"),
                           (solid_marks, "0.3", "2D solid: anywhere")):
            m = m["ellipticity_loss"]
            a.plot(m["lam"], m["force"] / H if a is not bx else m["t_min"] / H, "x", color=c, ms=7,
                   label=f"strong ellipticity lost in the neck ({name})")
    inset.set_xlim(1.16, 1.236)
    inset.set_ylim(0.0884, 0.0918)
    inset.tick_params(labelsize=6)
    ax.set_xlabel("end stretch  x(l) / l")
    ax.set_ylabel("nominal stress  N / (h mu)")
    ax.set_title("force against elongation, h/l = 0.2", fontsize=10)
    ax.set_ylim(0, 0.115)
    bx.set_xlabel("end stretch  x(l) / l")
    bx.set_ylabel("thinnest section / h")
    bx.set_title("the neck snaps back (dotted: past the loss of ellipticity)", fontsize=10)
    sh = shells[0]
    for t, c in zip(PROFILE_T_MIN, plt.cm.viridis(np.linspace(0, 0.9, len(PROFILE_T_MIN)))):
        r = min(sh["rows"], key=lambda r: abs(r["t_min"] / H - t))
        x2, t2 = solid_profile(srows[:k_lost], r["t_min"])
        cx.plot(r["x"], np.asarray(r["thickness"]) / H, "-", color=c, lw=1.2,
                label=f"stretch {r['lam']:.4f}, t_min {r['t_min'] / H:.3f} h"
                      f"{' (unstable)' if r['negative'] else ''}")
        cx.plot(x2, t2 / H, "--", color=c, lw=0.9)
    cx.set_xlabel("current position x")
    cx.set_ylabel("thickness / h")
    cx.set_title(f"neck profiles: shell ({sh['n']} elements), 2D solid (dashed)", fontsize=10)
    cx.legend(fontsize=6.5, loc="lower right")
    handles, labels = bx.get_legend_handles_labels()
    fig.legend(handles, labels, loc="lower center", ncol=5, fontsize=8, frameon=False)
    fig.tight_layout(rect=(0, 0.06, 1, 1))
    fig.savefig(path, dpi=130)
    plt.close(fig)


if __name__ == "__main__":
    main(Path(sys.argv[1]) if len(sys.argv) > 1 else Path("."))
