"""The AMG preconditioner's quality apart from the Newton forcing terms
(which set a different CG tolerance per step), shared by bench/scaling.py
(amg_cg_1e8_*), bench/amg_growth.py and bench/amg_thickness_ratio.py: CG
to a relative residual of 1e-8 for a fixed random right side (free rigid
motions projected out), one W-cycle of shellritz's AMG hierarchy per
iteration; and the fresh 2-thread process each case of the last two runs
in (run_cases)."""

import json
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

THREADS = 2


def leaf_reference(rings, h_over_l, nested=False, coarsest=11, supports="clamp"):
    """The default leaf (meshes/leaf.toml) on shapes.disc(rings) with
    h = h_over_l / rings, the DKT membrane metric (as the AMG studies were
    measured; the scene file's is regge since 2026-12-07), set up at its
    reference state t = 0: (shell, K the Hessian there, prolongators).
    ``nested``: the prolongators of the discs of rings / 2, rings / 4, ...
    (at least ``coarsest`` rings, the same thickness) below it, the
    interpolation of nested iteration linearized at their reference states
    (transfer.interpolation_jacobian), for multigrid over nested meshes;
    else None (smoothed aggregation).  ``supports``: "clamp", the scene's
    (its centre node clamped), or "rigid", a free body whose rigid motions
    the 3-2-1 supports of Shell.remove_rigid_motions take away (the scene
    file's ``[boundary] supports = "rigid"``)."""
    import tomllib
    from importlib.resources import files
    from shellritz import shapes
    from shellritz.meshdata import Surface
    from shellritz.scenefile import parse_scene
    from shellritz.transfer import interpolation_jacobian
    path = files("shellritz.meshes") / "leaf.toml"
    data = tomllib.loads(path.read_text())
    if supports == "rigid":
        data["boundary"] = dict(supports="rigid")
    elif supports != "clamp":
        raise ValueError(f"supports={supports!r}: 'clamp' or 'rigid'")
    scene = parse_scene(data, path.parent, source=str(path))

    def reference(r):
        shell = scene.build(Surface(shapes.disc(r)), thickness=h_over_l / rings, membrane="dkt")[0]
        shell._setup()           # the engine's set-up (solve does it), then the reference state
        shell.set_parameter(0.0)
        return shell
    shells = [reference(rings)]
    while nested and rings // 2 ** len(shells) >= coarsest:
        shells.append(reference(rings // 2 ** len(shells)))
    K = shells[0].evaluate(shells[0].free_state(), 2)[2]
    prolongators = [interpolation_jacobian(c, c.U, f) for f, c in zip(shells, shells[1:])] if nested else None
    return shells[0], K, prolongators


def amg_cg_iterations(K, layout, finest=None, options=None, prolongators=None, inspect=None):
    """CG on ``finest`` (default K; lower CSR) preconditioned by the solver's
    hierarchy built on K (``options`` over the solver's: theta, omega, max_levels,
    max_coarse, smoothed_levels, cycle; AMGSolver._build; ``prolongators``: the
    geometric hierarchy over nested meshes instead of smoothed aggregation); with
    ``finest`` the hierarchy's finest level (residuals and smoother) is that
    matrix.  Returns dict(its, reason, setup_s, cg_s, levels, coarsest_blocks,
    complexity) (pyamg's count of the coarsest level: nodal blocks or
    aggregates; the operator complexity: the values of all levels' operators
    over the finest one's); ``inspect(amg)``, if given, looks at the solver
    before its hierarchy is released and returns more entries of that dict."""
    from shellritz.linalg import (_smooth, free_rigid_modes, lower_matvec,
                                  make_linear_solver, projector, steihaug_cg)
    finest = K if finest is None else finest
    project = projector(free_rigid_modes(layout))
    if prolongators is not None:
        layout = layout._replace(prolongators=prolongators)
    amg = make_linear_solver("amg", K.shape[0], K.indptr, K.indices, layout)
    amg.options = dict(options or {})
    t = time.perf_counter()
    amg.factorize(K)
    if finest is not K:
        _smooth(amg._ml.levels[0], amg._embed(finest), single=True)
    setup = time.perf_counter() - t
    b = np.random.default_rng(0).standard_normal(K.shape[0])
    b = project(b) if project is not None else b
    t = time.perf_counter()
    _, info = steihaug_cg(lower_matvec(finest), -b, amg.preconditioner(), rtol=1e-8, maxiter=1000,
                          project=project)
    coarse = amg._ml.levels[-1].A
    blocks = coarse.shape[0] // (coarse.blocksize[0] if hasattr(coarse, "blocksize") else 1)
    out = dict(its=info["iterations"], reason=info["reason"], setup_s=setup,
               cg_s=time.perf_counter() - t, levels=len(amg._ml.levels), coarsest_blocks=int(blocks),
               complexity=sum(lv.A.data.size for lv in amg._ml.levels) / amg._ml.levels[0].A.data.size)
    if inspect is not None:
        out.update(inspect(amg))
    amg.release()
    return out


def study(doc, name, benchmark, code, axes, extra=None):
    """The command line of an AMG study (bench/amg_*.py): per axis (flag,
    key, type, defaults, choices or None) an option --flag taking one or
    more values; every combination of them is a case (a dict key: value
    in the axes' order, the child's arguments), run by run_cases into
    bench/results/``name``."""
    import argparse
    import itertools
    ap = argparse.ArgumentParser(description=doc.split("\n\n")[0])
    for flag, _, kind, defaults, choices in axes:
        ap.add_argument(f"--{flag}", type=kind, nargs="+", default=list(defaults), choices=choices)
    args = vars(ap.parse_args())
    values = [args[flag.replace("-", "_")] for flag, *_ in axes]
    cases = [dict(zip([key for _, key, *_ in axes], combo)) for combo in itertools.product(*values)]
    run_cases(Path(__file__).resolve().parent / "results" / name, benchmark, code, cases, extra)


def run_cases(path, benchmark, code, cases, extra=None):
    """Each case (a dict of the child's arguments, in order) in a fresh
    process on THREADS threads (bench/ on its path) running the Python
    source ``code``, which prints its rows as ``ROW {json}`` lines (none: a
    row of the case with the last line of its error output); they replace
    the rows of ``path`` (JSON) that have the case's values, and the file
    is written after every case (a long run stopped early keeps what it
    measured), with the machine and ``extra``."""
    from machine import machine_info
    env = dict(os.environ, NUMBA_NUM_THREADS=str(THREADS), OMP_NUM_THREADS=str(THREADS),
               MKL_NUM_THREADS=str(THREADS), PYTHONPATH=str(Path(__file__).resolve().parent))
    path.parent.mkdir(exist_ok=True)
    rows = json.loads(path.read_text())["rows"] if path.exists() else []
    for case in cases:
        out = subprocess.run([sys.executable, "-c", code, *map(str, case.values())], env=env,
                             capture_output=True, text=True)
        got = ([json.loads(line[4:]) for line in out.stdout.splitlines() if line.startswith("ROW ")]
               or [dict(case, error=out.stderr.strip().splitlines()[-1:])])
        for r in got:
            print(json.dumps(r), flush=True)
        rows = [r for r in rows if any(r.get(k) != v for k, v in case.items())] + got
        path.write_text(json.dumps({"benchmark": benchmark, "threads": THREADS, "machine": machine_info(),
                                    "rows": rows, **(extra or {})}, indent=2))
