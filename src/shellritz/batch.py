"""Solving scenes on meshes: one input (:func:`run_one`), or a batch run
serially, by local worker processes or on a Dask cluster (:func:`run_batch`).

Every input is solved by the same function, :func:`run_one`, wherever it runs,
with BLAS (OpenBLAS, and MKL with its PARDISO) limited to one thread
(threadpoolctl): the DKT assembly is bitwise the same on any number of Numba
threads, so the results do not depend on how the batch was run.  ``run_one`` never raises for
a bad input: it returns a summary with ``status = "failed"`` and the reason,
and the batch goes on.  Outputs are written to temporary files and renamed
(``meshdata.atomic_path``); the per-input summary ``STEM.json`` is written
last and records the SHA-256 of the input, of the scene and of every output,
so an input counts as done (and a re-run skips it) only when all its outputs
are there and unchanged.
"""

import dataclasses
import hashlib
import json
import math
import os
import time
import traceback
import warnings
from pathlib import Path

import numpy as np

from .meshdata import FORMATS_WITH_DATA, file_format, sha256, write_mesh, write_text

__all__ = ["run_one", "run_batch", "prepare_kernels", "expand_inputs", "BatchError"]

REPORT = "batch.json"
SOLID_FORMAT = "vtu"        # wedge cells: written as VTU whatever the surface format


class BatchError(ValueError):
    """The batch cannot start (usage error): colliding stems, no inputs, ..."""


def jsonable(obj):
    """Plain JSON values of results (dataclasses, numpy values, tuples);
    non-finite floats become None."""
    if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        return {f.name: jsonable(getattr(obj, f.name)) for f in dataclasses.fields(obj)}
    if isinstance(obj, dict):
        return {str(k): jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [jsonable(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return jsonable(obj.tolist())
    if isinstance(obj, (np.bool_, bool)):
        return bool(obj)
    if isinstance(obj, (np.integer, int)):
        return int(obj)
    if isinstance(obj, (np.floating, float)):
        return float(obj) if math.isfinite(obj) else None
    if obj is None or isinstance(obj, str):
        return obj
    return repr(obj)


def prepare_kernels(membrane="dkt"):
    """Compile (first run) or load (cached) every Numba kernel a solve of the
    triangle engine with that membrane metric ("dkt" | "regge", Shell) and
    its output use, on a 4-triangle problem.  Returns (seconds, compiled)."""
    from . import NeoHookean, Shell, shapes
    from .kernels.assembly import assemble_elements, assemble_elements_regge
    from .post import _fields, fields
    t0 = time.perf_counter()
    mesh = shapes.rectangle(2, 1)
    shell = Shell(mesh, 0.05, NeoHookean(1.0, nu=0.3), membrane=membrane)
    shell.set_growth(G0=np.diag([1.01, 1.0, 1.0]), G1=np.diag([0.1, 0.0, 0.0]))
    shell.clamp(mesh.nodes_on_plane("x", 0.0))
    fields(shell.solve(steps=1, verbose=False))
    assembly = assemble_elements_regge if membrane == "regge" else assemble_elements
    compiled = bool(sum(assembly.stats.cache_misses.values())
                    + sum(_fields.stats.cache_misses.values()))
    return time.perf_counter() - t0, compiled


def _threads_for_this_process():
    """Numba threads for a task on a Dask worker of a remote cluster: the
    machine's cores shared by the worker's threads (None outside Dask)."""
    try:
        from distributed import get_worker
        return max(1, (os.cpu_count() or 1) // get_worker().state.nthreads)
    except (ImportError, ValueError):
        return None


def output_names(stem, fmt, opts):
    names = {"mesh": f"{stem}.{fmt}"}
    if opts["faces"]:
        names["bottom"], names["top"] = f"{stem}_bottom.{fmt}", f"{stem}_top.{fmt}"
    if opts["solid"]:
        names["solid"] = f"{stem}_solid.{SOLID_FORMAT}"
    if opts["picture"]:
        names["picture"] = f"{stem}.png"
    return names


def _write_outputs(result, out_dir, names, title):
    from . import post
    fmt = file_format(names["mesh"])
    write_mesh(out_dir / names["mesh"], post.result_mesh(result, with_data=fmt in FORMATS_WITH_DATA))
    if "top" in names:
        bottom, top = post.face_meshes(result)
        write_mesh(out_dir / names["bottom"], bottom)
        write_mesh(out_dir / names["top"], top)
    if "solid" in names:
        write_mesh(out_dir / names["solid"], post.solid_mesh(result))
    if "picture" in names:
        post.picture(result, out_dir / names["picture"], title=title)
    return {k: sha256(out_dir / v) for k, v in names.items()}


def _history(result):
    h = result.history
    out = jsonable(h) if h is not None else None
    if isinstance(out, dict) and "iterations" in out:
        out["n_iterations"] = len(out["iterations"])
    return out


def run_one(spec):
    """Solve one input; returns its summary (also written as STEM.json).

    ``spec``: dict with ``scene_text`` (the TOML), ``scene_dir`` (for relative
    paths), ``input`` (a mesh file, or None: the scene's [mesh] file),
    ``out_dir``, ``stem``, ``format`` (None: the scene's), ``verbose``,
    ``threads`` (Numba threads, None: decide here).
    """
    import numba
    from threadpoolctl import threadpool_limits

    from .scenefile import SceneError, loads_scene
    from .solve import SolveError

    t_start = time.perf_counter()
    out_dir = Path(spec["out_dir"])
    stem = spec["stem"]
    timings = {}
    summary = {"status": "failed", "stem": stem, "reason": None,
               "input": {"path": spec.get("input")},
               "scene": {"sha256": hashlib.sha256(spec["scene_text"].encode()).hexdigest()}}
    threads = spec.get("threads") or _threads_for_this_process()
    if threads:
        numba.set_num_threads(min(threads, numba.config.NUMBA_NUM_THREADS))
    summary["threads"] = {"numba": numba.get_num_threads(), "blas": 1}
    # load MKL (PARDISO) now, so that the BLAS limit below covers it too
    from .linalg import pardiso_available
    pardiso_available()
    caught = []
    try:
        with warnings.catch_warnings(record=True) as caught, threadpool_limits(1, user_api="blas"):
            warnings.simplefilter("always")
            scene = loads_scene(spec["scene_text"], spec["scene_dir"],
                                source=spec.get("scene_name", "scene"))
            opts = scene.output
            fmt = (spec.get("format") or opts["format"]).lstrip(".")
            summary["format"] = fmt
            path = Path(spec["input"]) if spec.get("input") else scene.mesh_file
            summary["input"]["path"] = str(path)
            t = time.perf_counter()
            try:
                summary["input"]["sha256"] = sha256(path)
                surf = scene.read(path)
            except Exception as exc:
                raise _Failed(str(exc) if str(path) in str(exc) else f"{path}: {exc}") from None
            mesh = surf.mesh
            summary["mesh"] = {"nodes": mesh.n_nodes, "triangles": mesh.n_triangles,
                               "boundary_loops": len(mesh.boundary_loops()),
                               "point_data": sorted(surf.point_data), "cell_data": sorted(surf.cell_data)}
            timings["read_s"] = time.perf_counter() - t
            t = time.perf_counter()
            shell, growth = scene.build(surf)
            summary["growth"] = growth
            summary["thickness"] = shell.h
            summary["level"], summary["membrane"] = shell.level, shell.membrane
            timings["setup_s"] = time.perf_counter() - t
            names = output_names(stem, fmt, opts)
            t = time.perf_counter()
            try:
                result = scene.solve(surf, shell, verbose=spec.get("verbose", False))
            except SolveError as exc:
                timings["solve_s"] = time.perf_counter() - t
                summary["history"] = jsonable(exc.history)
                partial = getattr(exc, "result", None)
                msg = f"solver failed: {exc}"
                if partial is not None and exc.last_t is not None and exc.last_t > 0:
                    pnames = {"mesh": f"{stem}.partial.{fmt}"}
                    summary["partial"] = {"t": exc.last_t, "outputs": _write_outputs(
                        partial, out_dir, pnames, None), "files": pnames}
                    msg += f" (last converged state at t = {exc.last_t:.4g} written to {pnames['mesh']})"
                raise _Failed(msg) from None
            timings["solve_s"] = time.perf_counter() - t
            summary["free_dofs"] = int(len(shell.free))
            summary["energy"] = result.energy
            summary["t"] = result.t
            summary["history"] = _history(result)
            h = result.history
            summary["stability"] = {"stable": getattr(h, "stable", None),
                                    "unstable_modes": getattr(h, "unstable_modes", None)}
            r = result.r
            summary["extent"] = {"min": r.min(axis=0), "max": r.max(axis=0)}
            t = time.perf_counter()
            summary["outputs"] = _write_outputs(result, out_dir, names, scene.data.get("description"))
            summary["files"] = names
            timings["write_s"] = time.perf_counter() - t
            if fmt not in FORMATS_WITH_DATA:
                warnings.warn(f"format {fmt!r} keeps no data arrays: {names['mesh']} has the "
                              f"deformed geometry only (vtu, xdmf, msh keep the fields)")
            summary["status"] = "ok"
    except (_Failed, SceneError) as exc:
        summary["reason"] = str(exc)
    except Exception as exc:       # anything else is recorded too: the batch goes on
        summary["reason"] = f"{type(exc).__name__}: {exc}"
        summary["traceback"] = traceback.format_exc()
    summary["warnings"] = sorted({str(w.message) for w in caught})
    timings["total_s"] = time.perf_counter() - t_start
    summary["timings"] = timings
    summary = jsonable(summary)
    try:
        write_text(out_dir / f"{stem}.json", json.dumps(summary, indent=1))
    except OSError as exc:
        summary["status"] = "failed"
        summary["reason"] = f"cannot write {out_dir / (stem + '.json')}: {exc}"
    return summary


class _Failed(Exception):
    """An input failed for a stated reason."""


# ---------------------------------------------------------------------------
# batches
# ---------------------------------------------------------------------------

def mesh_extensions():
    import meshio
    return set(meshio.extension_to_filetypes) | {".glb", ".gltf", ".3mf"}


def expand_inputs(paths):
    """Files as given; folders replaced by their mesh files (sorted)."""
    exts = mesh_extensions()
    out = []
    for p in map(Path, paths):
        if p.is_dir():
            out += sorted(q for q in p.iterdir()
                          if q.is_file() and q.suffix.lower() in exts and not q.name.startswith("."))
        else:
            out.append(p)
    return out


def is_complete(out_dir, stem, input_path, scene_sha, fmt):
    """An input's outputs are complete: its summary says ok for this input,
    scene and format, and every output it lists is there, unchanged."""
    try:
        s = json.loads((out_dir / f"{stem}.json").read_text())
        if (s.get("status") != "ok" or s.get("format") != fmt
                or s["scene"]["sha256"] != scene_sha or s["input"]["sha256"] != sha256(input_path)):
            return False
        return all(sha256(out_dir / s["files"][k]) == h for k, h in s["outputs"].items())
    except (OSError, ValueError, KeyError, TypeError):
        return False


def _report_row(summary, wall=None):
    row = {"input": summary["input"]["path"], "stem": summary["stem"], "status": summary["status"],
           "reason": summary.get("reason")}
    if summary["status"] == "ok":
        row.update(energy=summary.get("energy"), triangles=summary.get("mesh", {}).get("triangles"),
                   stable=summary.get("stability", {}).get("stable"), files=summary.get("files"))
    row["seconds"] = summary.get("timings", {}).get("total_s") if wall is None else wall
    return row


def run_batch(inputs, out_dir, scene_text, scene_dir=".", scene_name="scene", fmt=None,
              workers=1, scheduler=None, force=False, progress=True, log=print):
    """Solve every input with the scene; write outputs, per-input summaries
    and ``batch.json`` to out_dir.  Returns the report (dict)."""
    from tqdm import tqdm

    t0 = time.perf_counter()
    out_dir = Path(out_dir)
    if out_dir.exists() and not out_dir.is_dir():
        raise BatchError(f"the output folder {out_dir} is an existing file")
    out_dir.mkdir(parents=True, exist_ok=True)
    for stale in out_dir.glob(".*.part"):           # temporary files of an interrupted run
        stale.unlink(missing_ok=True)
    paths = expand_inputs(inputs)
    if not paths:
        raise BatchError("no input meshes (folders are searched for files with a mesh extension)")
    stems = {}
    for p in paths:
        stems.setdefault(p.stem, []).append(str(p))
    clash = {s: ps for s, ps in stems.items() if len(ps) > 1}
    if clash:
        s, ps = next(iter(clash.items()))
        raise BatchError(f"inputs with the same stem would write the same outputs: {', '.join(ps)} "
                         f"(stem {s!r}); rename them or convert them into different folders")
    from .scenefile import loads_scene
    fmt = (fmt or loads_scene(scene_text, scene_dir, scene_name).output["format"]).lstrip(".")
    scene_sha = hashlib.sha256(scene_text.encode()).hexdigest()
    rows = {}
    todo = []
    for p in paths:
        spec = {"scene_text": scene_text, "scene_dir": str(scene_dir), "scene_name": scene_name,
                "input": str(p), "out_dir": str(out_dir), "stem": p.stem, "format": fmt,
                "verbose": False, "threads": None}
        if not force and p.is_file() and is_complete(out_dir, p.stem, p, scene_sha, fmt):
            done = json.loads((out_dir / f"{p.stem}.json").read_text())
            rows[p.stem] = dict(_report_row(done), status="skipped",
                                reason="outputs complete from an earlier run (--force redoes it)")
        else:
            todo.append(spec)
            rows[p.stem] = {"input": str(p), "stem": p.stem, "status": "not run", "reason": None}
    report = {"scene": scene_name, "scene_sha256": scene_sha, "format": fmt,
              "workers": workers, "scheduler": scheduler, "inputs": list(rows.values())}

    def save():
        report["inputs"] = list(rows.values())
        counts = {}
        for r in rows.values():
            counts[r["status"]] = counts.get(r["status"], 0) + 1
        report["counts"] = counts
        report["wall_s"] = time.perf_counter() - t0
        write_text(out_dir / REPORT, json.dumps(jsonable(report), indent=1))

    save()
    skipped = len(paths) - len(todo)
    if skipped:
        log(f"{skipped} of {len(paths)} inputs already done (outputs complete); --force redoes them")
    bar = tqdm(total=len(todo), unit="mesh", desc="convert", disable=not progress or not todo,
               dynamic_ncols=True)
    failed = 0

    def finished(summary):
        nonlocal failed
        rows[summary["stem"]] = _report_row(summary)
        if summary["status"] != "ok":
            failed += 1
            bar.write(f"FAILED {summary['input']['path']}: {summary['reason']}")
        bar.update(1)
        bar.set_postfix(failed=failed)
        save()

    try:
        if workers <= 1 and scheduler is None:
            for spec in todo:
                finished(run_one(spec))
        else:
            _run_dask(todo, workers, scheduler, finished)
    finally:
        bar.close()
        save()
    return report


def _run_dask(todo, workers, scheduler, finished):
    """Run the specs on a Dask cluster (a LocalCluster of ``workers``
    single-threaded processes, or the scheduler at ``scheduler``)."""
    import logging

    from dask.distributed import Client, LocalCluster, as_completed
    from distributed.scheduler import KilledWorker

    if scheduler is None:
        # the Numba threads of a task: this machine's cores shared by the workers
        threads = max(1, (os.cpu_count() or 1) // workers)
        todo = [dict(spec, threads=threads) for spec in todo]
        cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                               dashboard_address=None, silence_logs=logging.ERROR)
        client = Client(cluster)
    else:
        cluster = None
        client = Client(scheduler, timeout="30s")
    try:
        futures = {client.submit(run_one, spec, key=f"shellritz-{spec['stem']}", pure=False): spec
                   for spec in todo}
        for fut in as_completed(futures):
            spec = futures[fut]
            try:
                summary = fut.result()
            except KilledWorker as exc:
                summary = {"status": "failed", "stem": spec["stem"], "input": {"path": spec["input"]},
                           "reason": f"the worker running it died repeatedly ({exc}); "
                                     "out of memory?"}
            except Exception as exc:
                summary = {"status": "failed", "stem": spec["stem"], "input": {"path": spec["input"]},
                           "reason": f"{type(exc).__name__}: {exc}"}
            finished(summary)
    finally:
        client.close()
        if cluster is not None:
            cluster.close()
