"""Accuracy against cost: every (discretization, model level, mesh size) of
four scenes, and a 3D solid finite-element solution of the same scenes
(bench/fe3d.py, scikit-fem; install with `pip install '.[bench]'`).

Scenes (neo-Hookean, C = 1 throughout; the 3D models solve the same bodies):

* tube: growing thick tube in plane strain, h = 0.1, D = 4, growth 1.2 in the
  radial and hoop directions, dead outer traction 0.03; error = |r0 - exact| /
  exact, exact: radially symmetric 3D solution (shellritz.reference);
  shell engines: axisym (meridian along the axis), planestrain (quarter
  ring), dkt (quarter ring of triangles);
* strip: gradient-growth strip rolled into a full circle (paper 5.2,
  h = 0.02, D = 2); error = max distance to eq:x0z0asy (exact in 3D: the
  growth metric is flat) / radius 0.6; planestrain, dkt;
* sphere: growing thick sphere (h = 0.1, D = 4, tangential growth
  1.05 + 0.9 Z) inflated by a dead inner traction 0.03; error = |R - exact| /
  exact, exact: radially symmetric 3D solution; axisym, dkt (quarter sphere);
* invagination: shellritz.scenes.invagination() (h = 0.1, nu = 0.4); no exact
  solution: error = max distance of the thickness-averaged meridian to that
  of the finest 3D solution / sphere radius 1; axisym, dkt.

Levels: membrane, bending, consistent wherever the level determines the
shape (the strip has no membrane answer: without bending stiffness its shape
is undetermined).  Wall time: the whole solve including building the engine,
2 threads, compile excluded (a warm-up solve first), median of 3 runs (one
run when a run takes over 20 s).

Writes bench/results/accuracy_vs_cost.json (a list of rows: scene, method,
level, n, dofs, wall_s, error, iterations) and accuracy_vs_cost.png.

    python bench/accuracy_vs_cost.py            # everything
    python bench/accuracy_vs_cost.py --shell    # shell rows only, 3D rows kept from the last run
"""

import json
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
RESULTS = HERE / "results"
sys.path.insert(0, str(HERE))

from shellritz import NeoHookean  # noqa: E402
from shellritz.discretize.planestrain import PlaneStrainShell  # noqa: E402
from shellritz.reference import thick_shell_r0  # noqa: E402
from shellritz.scenes import RevolutionScene, StripScene, invagination  # noqa: E402

LEVELS = ("membrane", "bending", "consistent")

# ---------------------------------------------------------------- scenes
TUBE = dict(h=0.1, D=4.0, gamma=1.2, q=0.03)
STRIP = dict(h=0.02, D=2.0, g0=1.2, g1=2.0)
SPHERE = dict(h=0.1, D=4.0, g0=1.05, g1=0.9, q=0.03)


def tube_exact():
    return thick_shell_r0("tube", TUBE["h"], 1.0, TUBE["D"], TUBE["gamma"], TUBE["gamma"], q_outer=TUBE["q"])


def sphere_exact():
    return thick_shell_r0("sphere", SPHERE["h"], 1.0, SPHERE["D"], 1.0, SPHERE["g0"], SPHERE["g1"],
                          q_inner=SPHERE["q"])


def tube_scene():
    p = TUBE
    return RevolutionScene(lambda s: (1 + 0 * s, s.copy(), 0 * s, 1 + 0 * s), (0.0, 0.1), p["h"],
                           NeoHookean(1.0, D=p["D"]), gamma1=p["gamma"], gamma_n=p["gamma"],
                           q_plus=lambda s: (p["q"] + 0 * s, 0 * s), ends=("symmetry_z", "symmetry_z"))


def tube_quarter_ring(level, n):
    """Plane strain: a quarter of the ring x = cos s, z = -sin s with mirror ends."""
    p = TUBE
    curve = lambda s: (np.cos(s), -np.sin(s), -np.sin(s), -np.cos(s))
    t = time.perf_counter()
    ps = PlaneStrainShell(np.linspace(0, np.pi / 2, n + 1), curve, p["h"], NeoHookean(1.0, D=p["D"]), level)
    ps.set_stretch_growth(1.0, p["gamma"], p["gamma"])     # generator (axial), along the ring, normal
    ps.face_tractions(q_plus=lambda s: p["q"] * np.c_[np.cos(s), 0 * s, -np.sin(s)])
    ps.symmetry(0, "b").symmetry(-1, "a")
    r = ps.solve(verbose=False)
    wall = time.perf_counter() - t
    return dict(dofs=len(ps.free), wall_s=wall, iterations=len(r.history.iterations),
                value=np.hypot(r.a, r.b).mean())


def strip_scene():
    p = STRIP
    return StripScene(lambda s: (s.copy(), 0 * s, 1 + 0 * s, 0 * s), (0.0, np.pi / p["g1"]), p["h"],
                      NeoHookean(1.0, D=p["D"]), gamma2=p["g0"], gamma2_z=p["g1"])


def strip_error(s, a, b):
    g0, g1 = STRIP["g0"], STRIP["g1"]
    radius = g0 / g1
    return np.hypot(a - radius * np.sin(g1 * s), b - radius * (np.cos(g1 * s) - 1)).max() / radius


def sphere_scene():
    p = SPHERE
    return RevolutionScene(lambda s: (np.sin(s), 1 - np.cos(s), np.cos(s), np.sin(s)), (0.0, np.pi), p["h"],
                           NeoHookean(1.0, D=p["D"]), gamma1=p["g0"], gamma2=p["g0"],
                           gamma1_z=p["g1"], gamma2_z=p["g1"],
                           q_minus=lambda s: (p["q"] * np.sin(s), -p["q"] * np.cos(s)))


def sphere_radius(a, b):
    return np.hypot(a, b - 0.5 * (b[0] + b[-1])).mean()


# ---------------------------------------------------------------- runs
def timed(fn, repeats=3):
    out = fn()
    runs = [out]
    if out["wall_s"] < 20:
        runs += [fn() for _ in range(repeats - 1)]
    out = dict(runs[0])
    out["wall_s"] = float(np.median([r["wall_s"] for r in runs]))
    return out


def scene_run(scene, method, level, n, measure, steps=4, **kw):
    def fn():
        res = scene.solve(method, level=level, n=n, steps=steps, **kw)
        return dict(dofs=res.dofs, wall_s=res.wall_s, iterations=res.iterations, result=res)
    out = timed(fn)
    out["error"] = float(measure(out.pop("result")))
    return out


def shell_rows(invagination_reference):
    rows = []

    def add(scene, method, level, n, out):
        row = dict(scene=scene, method=method, level=level, n=n, dofs=int(out["dofs"]),
                   wall_s=out["wall_s"], error=out["error"], iterations=int(out["iterations"]))
        rows.append(row)
        print(f"{scene:12s} {method:11s} {level:10s} n={n:4d} dofs={row['dofs']:6d} "
              f"wall={row['wall_s']:8.3f}s error={row['error']:.2e} its={row['iterations']}", flush=True)

    # tube
    exact = tube_exact()
    tube = tube_scene()
    for level in LEVELS:
        out = scene_run(tube, "axisym", level, 2, lambda r: abs(r.a.mean() - exact) / exact)
        add("tube", "axisym", level, 2, out)
        for n in (2, 4, 8, 16):
            out = timed(lambda: tube_quarter_ring(level, n))
            out["error"] = abs(out.pop("value") - exact) / exact
            add("tube", "planestrain", level, n, out)
        for m in (4, 8, 16, 32, 64):
            out = scene_run(tube, "dkt", level, 1, lambda r: abs(r.a.mean() - exact) / exact, nphi=m)
            add("tube", "dkt", level, m, out)
    # strip
    strip = strip_scene()
    for level in ("bending", "consistent"):
        for n in (5, 10, 20, 40):
            add("strip", "planestrain", level, n,
                scene_run(strip, "planestrain", level, n, lambda r: strip_error(r.s, r.a, r.b), steps=8))
        for n in (10, 20, 40, 80, 160):
            add("strip", "dkt", level, n,
                scene_run(strip, "dkt", level, n, lambda r: strip_error(r.s, r.a, r.b), steps=8))
    # sphere
    exact = sphere_exact()
    sphere = sphere_scene()
    for level in LEVELS:
        measure = lambda r: abs(sphere_radius(r.a, r.b) - exact) / exact
        for n in (4, 8, 16, 32):
            add("sphere", "axisym", level, n, scene_run(sphere, "axisym", level, n, measure))
        for n in (8, 16, 32, 64):
            add("sphere", "dkt", level, n, scene_run(sphere, "dkt", level, n, measure))
    # invagination
    if invagination_reference is None:
        print("invagination: no 3D reference, skipped")
        return rows
    inv = invagination()
    measure = lambda r: meridian_error(r.s, r.a, r.b, invagination_reference)
    for level in LEVELS:
        for n in (16, 32, 64, 128):
            add("invagination", "axisym", level, n, scene_run(inv, "axisym", level, n, measure, steps=8))
        # membrane: compressive growth without bending stiffness wrinkles at the
        # mesh scale (hundreds of Newton iterations, no converging answer): two sizes
        for n in (16, 32) if level == "membrane" else (16, 32, 64):
            add("invagination", "dkt", level, n, scene_run(inv, "dkt", level, n, measure, steps=8))
    return rows


def meridian_error(s, a, b, ref):
    """Max distance between (a, b)(s) and the reference meridian (both shifted
    so that the bottom pole is at height 0), at the samples s."""
    from scipy.interpolate import CubicSpline
    rs, ra, rb = (np.asarray(ref[k]) for k in ("s", "a", "b"))
    ia, ib = CubicSpline(rs, ra)(s), CubicSpline(rs, rb - rb[0])(s)
    return np.hypot(a - ia, (b - b[0]) - ib).max()


# ---------------------------------------------------------------- 3D
FE3D_SIZES = {"tube": (4, 8, 16, 32), "strip": (8, 16, 32, 64, 128), "sphere": (2, 4, 8, 16, 32),
              "invagination": (16, 32, 48, 64, 96)}


def fe3d_rows():
    import fe3d
    rows, runs = [], {}
    for scene, sizes in FE3D_SIZES.items():
        for n in sizes:
            out = timed(lambda: fe3d.solve(scene, n))
            runs[scene, n] = out
            print(f"3d {scene:12s} n={n:4d} dofs={out['dofs']:7d} wall={out['wall_s']:8.2f}s "
                  f"its={out['iterations']}", flush=True)
    exact = {"tube": tube_exact(), "sphere": sphere_exact()}
    finest = runs["invagination", FE3D_SIZES["invagination"][-1]]
    reference = {k: np.asarray(finest[k]).tolist() for k in ("s", "a", "b")}
    for (scene, n), out in runs.items():
        if scene in exact:
            error = abs(out["r0"] - exact[scene]) / exact[scene]
        elif scene == "strip":
            error = strip_error(np.asarray(out["s"]), np.asarray(out["a"]), np.asarray(out["b"]))
        elif n == FE3D_SIZES["invagination"][-1]:
            continue                         # the reference itself
        else:
            error = meridian_error(np.asarray(out["s"]), np.asarray(out["a"]), np.asarray(out["b"]), reference)
        rows.append(dict(scene=scene, method="3d", level="3d", n=n, dofs=int(out["dofs"]),
                         wall_s=float(out["wall_s"]), error=float(error), iterations=int(out["iterations"]),
                         element=out.get("element", "")))
    return rows, reference


# ---------------------------------------------------------------- report
STYLE = {"axisym": ("C0", "o"), "planestrain": ("C2", "s"), "dkt": ("C1", "^"), "3d": ("k", "D")}
LINE = {"membrane": ":", "bending": "--", "consistent": "-", "3d": "-"}


def chart(rows):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import matplotlib.ticker
    scenes = ["tube", "strip", "sphere", "invagination"]
    fig, axes = plt.subplots(2, 2, figsize=(11, 9))
    for ax, scene in zip(axes.ravel(), scenes):
        rr = [r for r in rows if r["scene"] == scene]
        for method in STYLE:
            for level in LINE:
                sel = sorted((r for r in rr if r["method"] == method and r["level"] == level),
                             key=lambda r: r["n"])
                if not sel:
                    continue
                color, marker = STYLE[method]
                ax.loglog([r["wall_s"] for r in sel], [max(r["error"], 1e-12) for r in sel],
                          LINE[level], color=color, marker=marker, ms=4,
                          label=method if level == "3d" else f"{method} {level}")
        ax.xaxis.set_minor_formatter(matplotlib.ticker.NullFormatter())
        ax.axhline(1e-3, color="0.7", lw=0.8)
        ax.set_title(scene)
        ax.set_xlabel("wall time (s, 2 threads)")
        ax.set_ylabel("relative error")
        ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(RESULTS / "accuracy_vs_cost.png", dpi=110)


def summary(rows, target=1e-3):
    """Per scene: the cheapest shell run reaching the target error and the
    cheapest 3D run that does; where no shell run reaches it, the same at the
    best error the shell runs reach (the model error)."""
    lines = []
    for scene in ("tube", "strip", "sphere", "invagination"):
        shell = [r for r in rows if r["scene"] == scene and r["method"] != "3d"]
        solid = [r for r in rows if r["scene"] == scene and r["method"] == "3d"]
        goal = target
        best = min(r["error"] for r in shell)
        text = f"{scene}: "
        if best > target:
            goal = 1.05 * best
            text += f"no shell run reaches {target:.0e} (best {best:.1e}); at {goal:.1e}: "
        cheap = min((r for r in shell if r["error"] <= goal), key=lambda r: r["wall_s"])
        text += (f"{cheap['method']} {cheap['level']} n={cheap['n']} error {cheap['error']:.1e} "
                 f"in {cheap['wall_s']:.3f} s")
        ref = min((r for r in solid if r["error"] <= goal), key=lambda r: r["wall_s"], default=None)
        if ref is None:
            text += f"; no 3D run reaches {goal:.1e}"
        else:
            text += (f"; 3D n={ref['n']} error {ref['error']:.1e} in {ref['wall_s']:.2f} s: "
                     f"speed-up {ref['wall_s'] / cheap['wall_s']:.0f}x")
        lines.append(text)
    return lines


def main():
    import numba
    numba.set_num_threads(2)
    RESULTS.mkdir(exist_ok=True)
    path = RESULTS / "accuracy_vs_cost.json"
    if "--shell" in sys.argv:
        old = json.loads(path.read_text())
        solid = [r for r in old if r["method"] == "3d"]
        reference = json.loads((RESULTS / "invagination_3d_reference.json").read_text())
    else:
        solid, reference = fe3d_rows()
        (RESULTS / "invagination_3d_reference.json").write_text(json.dumps(reference))
    # warm-up (compile) runs, not timed
    for scene, method in ((tube_scene(), "dkt"), (sphere_scene(), "axisym"), (strip_scene(), "planestrain")):
        for level in LEVELS if method != "planestrain" else ("consistent",):
            scene.solve(method, level=level, n=4 if method != "dkt" else 1, steps=2)
    rows = shell_rows(reference) + solid
    path.write_text(json.dumps(rows, indent=1))
    chart(rows)
    for line in summary(rows):
        print(line)


if __name__ == "__main__":
    main()
