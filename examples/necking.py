"""Necking of a plane-strain block (paper section 4.3, docs/necking.md).

A block of length l = 1 and thickness h = 0.2 of the power-law hardening
solid (shellritz.necking.default_law: n = 0.2, Considere maximum at a stretch
of 1.2422) is pulled by shear-free grips.  A thickness imperfection of 1e-3
(growth gamma_n = 1 - 1e-3 cos(pi X / l)) puts the neck at X = 0.

* The 2D solid reference (bench/necking_2d.py: scikit-fem Q2, pseudo-arclength
  continuation through the fold where the neck snaps back, up to the loss of
  strong ellipticity in the neck) is read from
  bench/results/necking_2d_path.json.
* The plane-strain shell engine (20 Hermite elements, symmetric kinematics:
  the middle surface held on z = 0) is solved under displacement control at
  the 2D path's stretches up to the fold and just past it, where its
  continuation must fail: the end displacement turns back there and
  displacement control cannot follow (arc-length continuation in the solver
  is needed for the rest of the path).

Writes necking.png (force against elongation, thickness profiles) and
necking.json (the engine's path and its differences to the 2D solid).

    python examples/necking.py [output directory]
"""

import json
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from shellritz import SolveError  # noqa: E402
from shellritz.necking import (considere_stretch, default_law, end_force,  # noqa: E402
                               necking_strip, onset_stretch)

H, LENGTH, N_ELEMENTS, IMPERFECTION = 0.2, 1.0, 20, 1e-3
SOLID_PATH = Path(__file__).resolve().parent.parent / "bench" / "results" / "necking_2d_path.json"


def engine_state(law, lam):
    """The engine at end stretch lam (a continuation from the reference)."""
    eng = necking_strip(law, H, LENGTH, N_ELEMENTS, lam, imperfection=IMPERFECTION,
                        symmetric=True)
    res = eng.solve(steps=20, verbose=False, max_iter=20, min_dt=1e-3)
    x, _ = res.at(eng.sq)
    return {"lam": float(lam), "force": end_force(eng), "stable": bool(res.history.stable),
            "x": x.tolist(), "thickness": (H * np.linalg.norm(res.y1, axis=1)).tolist()}


def main(out=Path(".")):
    out.mkdir(parents=True, exist_ok=True)
    law = default_law()
    lam_m, lam_c = considere_stretch(law), onset_stretch(law, H / LENGTH)
    if not SOLID_PATH.exists():
        raise SystemExit(f"{SOLID_PATH} missing: run python bench/necking_2d.py first")
    solid = json.loads(SOLID_PATH.read_text())
    srows = solid["rows"]
    k_fold = next(k for k, r in enumerate(srows) if r["negative_eigenvalues"] > 0)
    before = srows[:k_fold]
    lam_fold = max(r["lam"] for r in srows)
    rows, failed = [], None
    for lam in [r["lam"] for r in before] + [lam_fold + 2e-3]:
        try:
            rows.append(engine_state(law, lam))
        except SolveError as exc:
            failed = 1.0 + exc.last_t * (lam - 1.0)
            break
    past_fold = (f"the continuation fails beyond {failed:.5f}" if failed
                 else f"converged at {lam_fold + 2e-3:.5f}, past the 2D fold (unexpected)")
    rows = rows[:len(before)]
    before = before[:len(rows)]
    df = [abs(e["force"] - s["force"]) / s["force"] for e, s in zip(rows, before)]
    dt = [abs(min(e["thickness"]) - s["t_min"]) / H for e, s in zip(rows, before)]
    print(f"2D solid: {len(srows)} points, fold (largest stretch) at {lam_fold:.5f}, "
          f"{solid['stop']}")
    print(f"shell engine at the {len(rows)} stretches before the fold: force within "
          f"{max(df):.1e} (relative), thinnest section within {max(dt):.1e} h of the 2D solid; "
          f"under displacement control {past_fold}")
    (out / "necking.json").write_text(json.dumps(
        {"h": H, "length": LENGTH, "n": N_ELEMENTS, "imperfection": IMPERFECTION, "rows": rows,
         "lam_fold_2d": lam_fold, "past_fold": past_fold, "force_rel_diff": df,
         "thickness_diff_over_h": dt}))

    fig, (ax, bx) = plt.subplots(1, 2, figsize=(11, 4.3))
    inset = ax.inset_axes([0.42, 0.12, 0.55, 0.5])
    for a in (ax, inset):
        a.plot([r["lam"] for r in srows], [r["force"] / H for r in srows], "-", color="0.4",
               label=f"2D solid (Q2, {solid['nz']} elements in h/2), arc length")
        a.plot([r["lam"] for r in rows], [r["force"] / H for r in rows], "o", ms=3,
               label="shell engine (20 elements), displacement control")
    inset.set_xlim(1.16, 1.25)
    inset.set_ylim(0.0885, 0.0918)
    for lam, name in ((lam_m, "Considere"), (lam_c, "onset, perfect block")):
        inset.axvline(lam, color="k", ls=":", lw=0.8)
        inset.text(lam, 0.0886, " " + name, rotation=90, va="bottom", fontsize=6)
    inset.tick_params(labelsize=6)
    ax.set_xlabel("end stretch  x(l) / l")
    ax.set_ylabel("nominal stress  N / (h mu)")
    ax.set_title("force against elongation, h/l = 0.2")
    ax.set_ylim(0, 0.115)
    ax.legend(fontsize=7, loc="upper left")
    shown = np.unique(np.linspace(0, len(rows) - 1, 6).astype(int))
    for k, c in zip(shown, plt.cm.viridis(np.linspace(0, 0.9, len(shown)))):
        r, s = rows[k], before[k]
        bx.plot(r["x"], np.asarray(r["thickness"]) / H, "-", color=c, lw=1.2,
                label=f"stretch {r['lam']:.4f}")
        bx.plot(s["x"], np.asarray(s["thickness"]) / H, "--", color=c, lw=0.8)
    for s in srows[k_fold::3] + srows[-1:]:
        bx.plot(s["x"], np.asarray(s["thickness"]) / H, "-", color="0.6", lw=0.7)
    bx.set_xlabel("current position x")
    bx.set_ylabel("thickness / h")
    bx.set_title("neck: engine (solid), 2D solid (dashed; grey past the fold)")
    bx.legend(fontsize=7, loc="lower right")
    fig.tight_layout()
    fig.savefig(out / "necking.png", dpi=130)


if __name__ == "__main__":
    main(Path(sys.argv[1]) if len(sys.argv) > 1 else Path("."))
