"""Onset of necking of a plane-strain block against h/l (docs/necking.md):

* E_1d analysis: w'' + (pi h / l)^2 C / 12 = 0 (shellritz.necking.onset_stretch);
* the plane-strain shell engine: first negative eigenvalue of its Hessian on
  the displacement-controlled homogeneous path, bisected (n = 5, 10, 20
  elements);
* the 2D solid: the exact incremental solution of the block
  (necking_2d.exact_onset) and the scikit-fem Q2 model (necking_2d.fe_onset,
  nz = 2, 4, 8 elements across the half thickness).

Run: python bench/necking.py [--quick]
  -> bench/results/necking_onset.json and necking_onset.png
"""

import json
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
RESULTS = HERE / "results"
sys.path.insert(0, str(HERE))

from necking_2d import exact_onset, fe_onset, machine_info  # noqa: E402
from shellritz.necking import (considere_stretch, default_law, engine_onset,  # noqa: E402
                               onset_stretch)


def study(quick):
    law = default_law()
    lam_m = considere_stretch(law)
    ratios = (0.1, 0.2) if quick else (0.05, 0.1, 0.2)
    rows = []
    for r in ratios:
        row = {"h_over_l": r, "considere": lam_m, "e1d": onset_stretch(law, r),
               "exact_2d": exact_onset(law, r), "engine": [], "fe_2d": []}
        for n in ((5, 10) if quick else (5, 10, 20)):
            t0 = time.perf_counter()
            lam, n_hi, gmax = engine_onset(law, r, 1.0, n, lam_m, row["e1d"] + 2e-3)
            row["engine"].append({"n": n, "lam": lam, "max_gradient": gmax,
                                  "wall_s": time.perf_counter() - t0})
        for nz in ((1, 2) if quick else (2, 4, 8)):
            t0 = time.perf_counter()
            lam, info = fe_onset(law, r, nz)
            info.update(lam=lam, wall_s=time.perf_counter() - t0)
            row["fe_2d"].append(info)
        rows.append(row)
        eng, fe = row["engine"][-1], row["fe_2d"][-1]
        print(f"h/l = {r}: Considere {lam_m:.9f}  E_1d {row['e1d']:.9f}  engine(n={eng['n']}) "
              f"{eng['lam']:.9f}  2D exact {row['exact_2d']:.9f}  2D FE(nz={fe['nz']}) "
              f"{fe['lam']:.9f}", flush=True)
        print(f"    engine - E_1d {eng['lam'] - row['e1d']:.2e}   E_1d - 2D exact "
              f"{row['e1d'] - row['exact_2d']:.2e}   FE - exact {fe['lam'] - row['exact_2d']:.2e}"
              f"   E_1d - Considere {row['e1d'] - lam_m:.2e}", flush=True)
    return {"machine": machine_info(), "law": repr(law), "rows": rows}


def chart(out, path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    rows = out["rows"]
    r = np.array([row["h_over_l"] for row in rows])
    fig, ax = plt.subplots(figsize=(6, 4.2))
    ax.loglog(r, [row["e1d"] - row["considere"] for row in rows], "o-",
              label=r"$\lambda_{1d} - \lambda_{Considere}$ (gradient correction)")
    ax.loglog(r, [abs(row["e1d"] - row["exact_2d"]) for row in rows], "s-",
              label=r"$|\lambda_{1d} - \lambda_{2D\,exact}|$ (model error)")
    ax.loglog(r, [abs(row["engine"][-1]["lam"] - row["e1d"]) for row in rows], "^-",
              label=r"$|\lambda_{engine} - \lambda_{1d}|$ (20 elements)")
    ax.loglog(r, [abs(row["fe_2d"][-1]["lam"] - row["exact_2d"]) for row in rows], "v-",
              label=r"$|\lambda_{2D\,FE} - \lambda_{2D\,exact}|$")
    ax.loglog(r, 0.5 * (r / r[-1]) ** 2 * (rows[-1]["e1d"] - rows[-1]["considere"]), "k:", lw=0.8,
              label=r"$(h/l)^2$, $(h/l)^4$")
    ax.loglog(r, 0.5 * (r / r[-1]) ** 4 * abs(rows[-1]["e1d"] - rows[-1]["exact_2d"]), "k:", lw=0.8)
    ax.set_xlabel("h / l")
    ax.set_ylabel("stretch difference")
    ax.set_title("onset of necking, plane strain, power-law solid n = 0.2")
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=130)


def main():
    quick = "--quick" in sys.argv
    RESULTS.mkdir(exist_ok=True)
    out = study(quick)
    name = "necking_onset_quick" if quick else "necking_onset"
    (RESULTS / f"{name}.json").write_text(json.dumps(out, indent=1))
    chart(out, RESULTS / f"{name}.png")


if __name__ == "__main__":
    main()
