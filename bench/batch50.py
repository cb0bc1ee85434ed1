"""The unattended batch of issue 11: 50 surface meshes of 2 000-20 000
triangles with growth arrays, mixed with bad inputs, converted by
``shellritz convert --workers 1``; the report's figures go to
bench/results/batch50.json.

Inputs (generated in --work): flat discs and rectangles with point data G0/G1
(in-plane growth and a through-thickness gradient: the sheets curl and
buckle), discs with cell data abar/bbar of spherical caps, hemispheres and
spheres grown uniformly, and bad inputs: an unreadable file, an empty file, a
non-manifold mesh, NaN coordinates, growth with det G0 < 0, and a mesh whose
growth the solver cannot follow.

    python bench/batch50.py              # 50 meshes, 2k-20k triangles (an hour or more on 2 cores)
    python bench/batch50.py --quick      # 10 meshes of 200-2 000 triangles
    python bench/batch50.py --membrane dkt   # the same with the DKT membrane metric -> batch50_dkt.json
    python bench/batch50.py --membranes  # the convert defaults' membrane metric (about 25 minutes)

--membranes: a curling disc (G0 = 1.05 in the plane, G1 = 1.25 e1 e1) and a
disc given the forms of a cap of radius 3 (abar/bbar), as in the batch, at
about 2k, 8k and 32k triangles, converted with the defaults and each membrane
metric; both grown shapes are stress-free up to the model's own terms, so
the energy falls to a small common value and its excess is the
discretization's.  Writes bench/results/convert_membrane.json.
"""

import argparse
import json
import re
import subprocess
import sys
import time
from importlib.resources import files
from pathlib import Path

import meshio
import numpy as np

from machine import machine_info
from shellritz import shapes
from shellritz.scenefile import load_scene

HERE = Path(__file__).resolve().parent


def write(path, mesh, point_data=None, cell_data=None):
    meshio.write(path, meshio.Mesh(mesh.vertices, [("triangle", mesh.triangles)],
                                   point_data=point_data or {},
                                   cell_data={k: [v] for k, v in (cell_data or {}).items()}))


def tensors(n, G0, G1):
    return {"G0": np.tile(np.asarray(G0, float).ravel(), (n, 1)),
            "G1": np.tile(np.asarray(G1, float).ravel(), (n, 1))}


def cap_forms(mesh, R):
    X = mesh.vertices
    rho, phi = np.hypot(X[:, 0], X[:, 1]), np.arctan2(X[:, 1], X[:, 0])
    Y = np.c_[R * np.sin(rho / R) * np.cos(phi), R * np.sin(rho / R) * np.sin(phi), R * np.cos(rho / R)]
    t = mesh.triangles
    E1, E2 = Y[t[:, 1]] - Y[t[:, 0]], Y[t[:, 2]] - Y[t[:, 0]]
    a = np.c_[(E1 * E1).sum(1), (E1 * E2).sum(1), (E2 * E2).sum(1)]
    return {"abar": a, "bbar": -a / R}


def disc_rings(triangles):
    return max(2, int(round(np.sqrt(triangles / 6))))       # 6 k^2 triangles


def make_inputs(folder, n_good, tri_range, seed=0):
    rng = np.random.default_rng(seed)
    folder.mkdir(parents=True, exist_ok=True)
    sizes = np.geomspace(*tri_range, n_good).round().astype(int)
    rng.shuffle(sizes)
    kinds = ["disc-curl", "rect-curl", "disc-cap", "hemisphere", "sphere"]
    expected = {}
    for k, ntri in enumerate(sizes):
        kind = kinds[k % len(kinds)]
        name = f"{k:02d}-{kind}"
        if kind == "disc-curl":
            m = shapes.disc(disc_rings(ntri))
            write(folder / f"{name}.vtu", m, tensors(m.n_nodes, np.diag([1.05, 1.05, 1.0]),
                                                      np.diag([rng.uniform(0.5, 2.0), 0.0, 0.0])))
        elif kind == "rect-curl":
            nx = max(2, int(np.sqrt(ntri)))
            m = shapes.rectangle(nx, max(1, ntri // (2 * nx)), lx=2.0, ly=1.0)
            write(folder / f"{name}.ply" if k % 2 else folder / f"{name}.vtu", m,
                  tensors(m.n_nodes, np.eye(3), np.diag([rng.uniform(0.5, 2.0), 0.0, 0.0])))
        elif kind == "disc-cap":
            m = shapes.disc(disc_rings(ntri))
            write(folder / f"{name}.vtu", m, cell_data=cap_forms(m, rng.uniform(2.0, 4.0)))
        elif kind == "hemisphere":
            nphi = max(8, int(np.sqrt(ntri)))
            m = shapes.hemisphere(nphi, max(2, ntri // (2 * nphi)))
            write(folder / f"{name}.vtu", m, tensors(m.n_nodes, 1.1 * np.eye(3), np.zeros((3, 3))))
        else:
            level = int(np.clip(np.round(np.log(ntri / 20) / np.log(4)), 1, 6))
            m = shapes.sphere(level)
            write(folder / f"{name}.vtu", m, tensors(m.n_nodes, np.diag([1.1, 1.1, 1.1]), np.zeros((3, 3))))
        expected[name] = "ok"
    # bad inputs
    (folder / "bad-unreadable.vtu").write_bytes(b"\x00 not a mesh " * 40)
    (folder / "bad-empty.stl").write_bytes(b"")
    X = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1.0]])
    meshio.write(folder / "bad-nonmanifold.obj",
                 meshio.Mesh(X, [("triangle", np.array([[0, 1, 2], [1, 0, 3], [0, 1, 4]]))]))
    m = shapes.disc(8)
    V = m.vertices.copy()
    V[17, 0] = np.nan
    meshio.write(folder / "bad-nan.vtu", meshio.Mesh(V, [("triangle", m.triangles)]))
    write(folder / "bad-inverted-growth.vtu", m, tensors(m.n_nodes, np.diag([-1.0, 1.0, 1.0]), np.zeros((3, 3))))
    write(folder / "bad-diverges.vtu", m, tensors(m.n_nodes, np.eye(3), np.diag([300.0, 0.0, 0.0])))
    for b in ("unreadable", "empty", "nonmanifold", "nan", "inverted-growth", "diverges"):
        expected[f"bad-{b}"] = "failed"
    return expected


DEFAULTS = Path(str(files("shellritz.meshes") / "convert-defaults.toml"))


def defaults_with(membrane, work):
    """The packaged convert defaults with the membrane metric replaced, written
    to work/defaults-{membrane}.toml; returns its path."""
    text, n = re.subn(r'^membrane = "\w+"', f'membrane = "{membrane}"', DEFAULTS.read_text(), flags=re.M)
    assert n == 1, "convert-defaults.toml names no membrane metric"
    scene = work / f"defaults-{membrane}.toml"
    scene.parent.mkdir(parents=True, exist_ok=True)
    scene.write_text(text)
    return scene


def membranes(work):
    """bench/results/convert_membrane.json: energy, Newton iterations and time
    of the curling disc and the cap at three sizes with each membrane metric,
    through `shellritz convert` with the packaged defaults, the metric
    replaced."""
    folder = work / "membranes-in"
    folder.mkdir(parents=True, exist_ok=True)
    for ntri in (2000, 8000, 32000):
        m = shapes.disc(disc_rings(ntri))
        write(folder / f"curl-{ntri}.vtu", m,
              tensors(m.n_nodes, np.diag([1.05, 1.05, 1.0]), np.diag([1.25, 0.0, 0.0])))
        write(folder / f"cap-{ntri}.vtu", m, cell_data=cap_forms(m, 3.0))
    rows = []
    for membrane in ("dkt", "regge"):
        out = work / f"membranes-{membrane}"
        subprocess.call([sys.executable, "-m", "shellritz.cli", "convert", str(folder), "-o", str(out),
                         "--scene", str(defaults_with(membrane, work)), "--force", "--no-progress"])
        for r in json.loads((out / "batch.json").read_text())["inputs"]:
            stem = Path(r["input"]).stem
            s = json.loads((out / f"{stem}.json").read_text())
            rows.append({"input": stem, "membrane": s["membrane"], "status": s["status"],
                         "triangles": s["mesh"]["triangles"], "energy": s.get("energy"),
                         "newton_its": len(s["history"]["iterations"]), "seconds": r.get("seconds")})
            print(rows[-1], flush=True)
    (HERE / "results" / "convert_membrane.json").write_text(
        json.dumps({"machine": machine_info(), "rows": rows}, indent=1))


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="10 meshes of 200-2000 triangles")
    ap.add_argument("--work", default="/tmp/shellritz-batch50", help="folder for inputs and outputs")
    ap.add_argument("--workers", type=int, default=1)
    ap.add_argument("--membrane", choices=("dkt", "regge"),
                    help="the defaults with this membrane metric (results in batch50_{metric}.json); "
                         "default: the packaged defaults as they are")
    ap.add_argument("--membranes", action="store_true",
                    help="only the defaults' membrane metric on a curling disc and a cap at 2k-32k triangles")
    args = ap.parse_args()
    work = Path(args.work)
    if args.membranes:
        return membranes(work)
    n_good, tri = ((4, (200, 2000)) if args.quick else (44, (2000, 20000)))
    expected = make_inputs(work / "in", n_good, tri)
    t = time.perf_counter()
    scene = defaults_with(args.membrane, work) if args.membrane else DEFAULTS
    code = subprocess.call([sys.executable, "-m", "shellritz.cli", "convert", str(work / "in"),
                            "-o", str(work / "out"), "--workers", str(args.workers), "--force",
                            "--scene", str(scene)])
    wall = time.perf_counter() - t
    report = json.loads((work / "out" / "batch.json").read_text())
    rows = report["inputs"]
    got = {Path(r["input"]).stem: r["status"] for r in rows}
    out = {"machine": machine_info(), "membrane": load_scene(scene).membrane, "quick": args.quick,
           "workers": args.workers, "exit_code": code, "wall_s": wall,
           "inputs": len(rows), "counts": report["counts"],
           "as_expected": all(got.get(k) == v for k, v in expected.items()),
           "unexpected": {k: got.get(k) for k, v in expected.items() if got.get(k) != v},
           "rows": [{k: r.get(k) for k in ("input", "status", "reason", "triangles", "seconds", "stable")}
                    for r in rows]}
    (HERE / "results").mkdir(exist_ok=True)
    name = f"batch50{'_quick' if args.quick else ''}{'_' + args.membrane if args.membrane else ''}.json"
    (HERE / "results" / name).write_text(json.dumps(out, indent=1))
    print(f"{len(rows)} inputs in {wall:.0f} s: {report['counts']}; exit code {code}; "
          f"statuses as expected: {out['as_expected']}")


if __name__ == "__main__":
    main()
