"""shellritz command line.

    shellritz [-o DIR]                    the default scene: a growing leaf
    shellritz run SCENE.toml [-o DIR]     solve a scene file
    shellritz convert INPUT... -o DIR     grow every input mesh with scene defaults

Exit codes: 0 all done, 1 some inputs (or the scene's solve) failed, 2 usage
error (bad arguments, an invalid scene file, colliding inputs), 130 interrupted.

Default scene (``meshes/leaf.toml``): a flat disc of radius 1, thickness
0.02, compressible neo-Hookean (nu = 0.4), grows in its plane by
gamma = 1 + 0.3 rho^2, so the rim has more length than a flat disc can hold; a
small through-thickness growth gradient G1 = diag(0.5, -0.5, 0) picks the
orientation.  The disc buckles into a saddle, as growing leaves and petals do.
The locking-free membrane metric (membrane = "regge"): with the DKT metric
this mesh locks (README, Membrane locking).  ``convert``'s defaults
(``meshes/convert-defaults.toml``: free bodies, thickness 1 % of the extent)
use it too.
"""

import argparse
import sys
import time
from importlib.resources import files
from pathlib import Path

EXIT_OK, EXIT_FAILED, EXIT_USAGE, EXIT_INTERRUPTED = 0, 1, 2, 130


def _packaged(name):
    return Path(str(files("shellritz.meshes") / name))


def _kernels(say, membrane):
    from .batch import prepare_kernels
    say("preparing the Numba kernels (the first run compiles them, a few minutes on a "
        "fresh install; cached afterwards) ...")
    seconds, compiled = prepare_kernels(membrane)
    say(f"kernels ready in {seconds:.1f} s ({'compiled now and cached' if compiled else 'from the cache'})")
    return seconds


def run_scene(scene_path, out_dir, quiet=False):
    """``shellritz run``: solve one scene file, write its outputs and summary."""
    from .batch import run_one
    from .scenefile import load_scene

    def say(msg):
        print(f"shellritz: {msg}", flush=True)
    scene_path = Path(scene_path)
    scene = load_scene(scene_path)          # SceneError before any work
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    stem = scene.output["name"] or scene_path.stem
    say(f"scene {scene_path}" + (f": {scene.data['description']}" if "description" in scene.data else ""))
    t0 = time.perf_counter()
    kernels_s = _kernels(say, scene.membrane)
    say(f"solving {scene.mesh_file} ...")
    summary = run_one({"scene_text": scene_path.read_text(), "scene_dir": str(scene_path.parent),
                       "scene_name": str(scene_path), "input": None, "out_dir": str(out_dir),
                       "stem": stem, "format": None, "verbose": not quiet, "threads": None})
    tm = summary["timings"]
    for w in summary["warnings"]:
        say(f"warning: {w}")
    if summary["status"] != "ok":
        say(f"FAILED: {summary['reason']}")
        say(f"wrote {out_dir / (stem + '.json')}")
        return EXIT_FAILED
    h = summary["history"] or {}
    st = summary["stability"]
    say(f"{summary['mesh']['triangles']} triangles, {summary['free_dofs']} free DOFs, growth: "
        f"{summary['growth']}")
    say(f"solved in {tm['solve_s']:.1f} s: energy {summary['energy']:.6g}, "
        f"{h.get('n_iterations', '?')} Newton iterations, "
        + ("stable" if st["stable"] else f"NOT stable ({st['unstable_modes']} negative eigenvalues)"))
    files_ = [str(out_dir / f) for f in summary["files"].values()] + [str(out_dir / (stem + ".json"))]
    say(f"wrote {', '.join(files_)} in {tm['write_s']:.1f} s")
    say(f"total {time.perf_counter() - t0:.1f} s (kernels {kernels_s:.1f} s, solve {tm['solve_s']:.1f} s)")
    return EXIT_OK


def convert(args):
    """``shellritz convert``: the batch."""
    from .batch import run_batch
    from .scenefile import load_scene
    scene_path = Path(args.scene) if args.scene else _packaged("convert-defaults.toml")
    scene = load_scene(scene_path)          # SceneError before any work
    if args.format:
        from .meshdata import file_format
        file_format("x." + args.format.lstrip("."))
    if args.workers < 1:
        raise ValueError(f"--workers must be >= 1, got {args.workers}")
    fmt = args.format.lstrip(".") if args.format else None
    if args.scheduler is None:
        _kernels(lambda m: print(f"shellritz: {m}", file=sys.stderr, flush=True),
                 scene.membrane)
    report = run_batch(args.inputs, args.out, scene_path.read_text(), scene_dir=scene_path.parent,
                       scene_name=str(scene_path), fmt=fmt, workers=args.workers,
                       scheduler=args.scheduler, force=args.force, progress=not args.no_progress,
                       log=lambda m: print(f"shellritz: {m}", file=sys.stderr, flush=True))
    c = report["counts"]
    print(f"shellritz: {c.get('ok', 0)} converted, {c.get('skipped', 0)} already done, "
          f"{c.get('failed', 0)} failed, in {report['wall_s']:.1f} s; report {Path(args.out) / 'batch.json'}",
          file=sys.stderr)
    return EXIT_FAILED if c.get("failed") else EXIT_OK


def parser():
    ap = argparse.ArgumentParser(
        prog="shellritz", formatter_class=argparse.RawDescriptionHelpFormatter,
        description="Equilibrium shapes of thin growing shells.  Without a command: solve the "
                    "default scene (a growing leaf) into ./shellritz-output.",
        epilog="exit codes: 0 all done, 1 some inputs failed, 2 usage error, 130 interrupted")
    ap.add_argument("-o", "--out", default="shellritz-output",
                    help="output directory of the default scene (default: ./shellritz-output)")
    ap.add_argument("-q", "--quiet", action="store_true", help="no per-iteration report")
    sub = ap.add_subparsers(dest="command", metavar="COMMAND")
    run = sub.add_parser("run", help="solve a scene file",
                         description="Solve a scene file (TOML, see the README's 'Scene files'); "
                                     "writes the deformed mesh with fields, STEM.json (energy, "
                                     "solver history, timings, warnings) and what [output] asks for.",
                         epilog="exit codes: 0 solved, 1 the solve failed, 2 invalid scene file")
    run.add_argument("scene", help="scene file (.toml)")
    run.add_argument("-o", "--out", default="shellritz-output", help="output directory (default: ./shellritz-output)")
    run.add_argument("-q", "--quiet", action="store_true", help="no per-iteration report")
    cv = sub.add_parser(
        "convert", help="grow every input mesh with scene defaults",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        description="Solve each input surface mesh (any format meshio or trimesh reads, with its "
                    "point/cell data) with the scene defaults and write DIR/STEM.FORMAT, "
                    "DIR/STEM.json and DIR/batch.json.  Inputs whose outputs are complete are "
                    "skipped; a failed input is reported and the batch goes on.",
        epilog="default scene: meshes/convert-defaults.toml (growth from the mesh's G0/G1 or "
               "abar/bbar arrays when present, thickness 1 % of the extent, the locking-free "
               "regge membrane metric, rigid motions removed).\n"
               "exit codes: 0 all done, 1 some inputs failed, 2 usage error, 130 interrupted")
    cv.add_argument("inputs", nargs="+", metavar="INPUT", help="mesh files or folders of them")
    cv.add_argument("-o", "--out", required=True, metavar="DIR", help="output directory")
    cv.add_argument("--scene", metavar="DEFAULTS.toml", help="scene defaults (its [mesh] file is ignored)")
    cv.add_argument("--format", help="output mesh format: vtu (default), xdmf, vtk, msh, ply, obj, stl, "
                                     "off, ... (the last four without data arrays)")
    cv.add_argument("--workers", type=int, default=1, metavar="N",
                    help="worker processes on this machine (Dask LocalCluster; default 1: in this process)")
    cv.add_argument("--scheduler", metavar="ADDRESS",
                    help="run on the Dask cluster of this scheduler (e.g. tcp://host:8786); inputs "
                         "and DIR must be on a file system the workers share")
    cv.add_argument("--force", action="store_true", help="redo inputs whose outputs are complete")
    cv.add_argument("--no-progress", action="store_true", help="no progress bar")
    return ap


def main(argv=None):
    from .batch import BatchError
    from .scenefile import SceneError
    ap = parser()
    args = ap.parse_args(argv)
    try:
        if args.command == "convert":
            return convert(args)
        if args.command == "run":
            return run_scene(args.scene, args.out, args.quiet)
        return run_scene(_packaged("leaf.toml"), args.out, args.quiet)
    except (SceneError, BatchError, ValueError) as exc:
        print(f"shellritz: error: {exc}", file=sys.stderr)
        return EXIT_USAGE
    except KeyboardInterrupt:
        print("shellritz: interrupted; completed outputs are kept, a re-run goes on from there",
              file=sys.stderr)
        return EXIT_INTERRUPTED


if __name__ == "__main__":
    sys.exit(main())
