"""The leaf growth scene on a 1M-triangle disc: what each phase of a solve
costs in time and memory (issue 10, item 5), measured phase by phase in one
process on 2 threads: the mesh, the engine's set-up, one Hessian assembly
at the flat state grown to t = 1, the AMG hierarchy of that Hessian (the
method for meshes whose factors do not fit in memory) and one W-cycle and
one Hessian-vector product.  The whole solve is not run here
(bench/scaling.py, method amg-nested, does that up to 100k triangles).

Writes bench/results/large_mesh.json: per phase the seconds and the
resident memory after it (GB) and the peak so far, with the machine.

Run:  python bench/large_mesh.py [--rings 408]     (408 rings: 998,784 triangles)
"""

import os

THREADS = 2
for _var in ("OMP_NUM_THREADS", "NUMBA_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS"):
    os.environ[_var] = str(THREADS)

import argparse  # noqa: E402
import json  # noqa: E402
import resource  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
RESULTS = HERE / "results"


def resident_gb():
    with open("/proc/self/statm") as fh:
        return int(fh.read().split()[1]) * os.sysconf("SC_PAGE_SIZE") / 2**30


def peak_gb():
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 2**20


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--rings", type=int, default=408)
    ap.add_argument("--out", default=str(RESULTS / "large_mesh.json"))
    args = ap.parse_args()
    from machine import machine_info
    from shellritz.batch import prepare_kernels
    from shellritz.linalg import AMGSolver, lower_matvec
    from shellritz.scenes import leaf
    kernels_s, _ = prepare_kernels()
    leaf(4, membrane="dkt").solve(verbose=False)    # compiled code warm
    out = dict(benchmark="leaf growth scene, one large mesh, phase by phase", rings=args.rings,
               threads=THREADS, kernels_s=kernels_s, machine=machine_info(), phases=[])

    def phase(name, fn):
        t = time.perf_counter()
        value = fn()
        out["phases"].append(dict(phase=name, seconds=time.perf_counter() - t,
                                  resident_gb=resident_gb(), peak_gb=peak_gb()))
        print(out["phases"][-1], flush=True)
        Path(args.out).write_text(json.dumps(out, indent=1))
        return value

    # the DKT membrane metric, as the results were measured (the scene file's is regge since 2026-12-07)
    shell = phase("mesh and scene", lambda: leaf(args.rings, membrane="dkt"))
    out["n_triangles"] = int(len(shell.mesh.triangles))

    def setup():
        shell._setup()
        shell.set_parameter(1.0)
        return shell.free_state()
    x = phase("engine set-up (pattern, colouring, maps)", setup)
    out["dofs"] = int(len(x))
    _, g, K = phase("one Hessian assembly", lambda: shell.evaluate(x, 2))
    out["hessian_nnz_lower"] = int(K.nnz)
    amg = AMGSolver(len(x), shell.block_layout())

    def build():
        amg.factorize(K)
        return amg.preconditioner()
    precond = phase("AMG hierarchy", build)
    out["amg_levels"] = [dict(unknowns=int(lv.A.shape[0]), nonzeros=int(lv.A.nnz)) for lv in amg._ml.levels]
    phase("one W-cycle", lambda: precond(g))
    matvec = lower_matvec(K)
    phase("one Hessian-vector product", lambda: matvec(g))
    print(f"{out['n_triangles']} triangles, {out['dofs']} DOFs: peak {peak_gb():.2f} GB")


if __name__ == "__main__":
    main()
