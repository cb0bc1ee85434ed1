"""First run of the default scene on a fresh install: a new process, an empty
Numba cache (NUMBA_CACHE_DIR pointed at a new temporary folder), the bare
``shellritz`` command.  Records the wall time and the split the command
prints (kernels compiled, solve) in bench/results/first_run.json.

    python bench/first_run.py            # three cold runs (median), then a warm run
    python bench/first_run.py --quick    # one cold run only
"""

import argparse
import json
import os
import re
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent


def run(cache_dir, out_dir):
    env = dict(os.environ, NUMBA_CACHE_DIR=str(cache_dir))
    t = time.perf_counter()
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    p = subprocess.run([sys.executable, "-m", "shellritz.cli", "-o", str(out_dir), "-q"],
                       env=env, capture_output=True, text=True)
    wall = time.perf_counter() - t
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    # CPU time of the run: less sensitive than the wall time to other load on the machine
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    if p.returncode != 0:
        raise SystemExit(f"shellritz failed ({p.returncode}):\n{p.stdout}\n{p.stderr}")
    kernels = float(re.search(r"kernels ready in ([\d.]+) s", p.stdout).group(1))
    solve = float(re.search(r"solved in ([\d.]+) s", p.stdout).group(1))
    return {"wall_s": wall, "cpu_s": cpu, "kernels_compiled": "compiled now" in p.stdout,
            "kernels_s": kernels, "solve_s": solve,
            "other_s": wall - kernels - solve, "stdout": p.stdout.splitlines()}


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="one cold run only")
    ap.add_argument("--repeats", type=int, default=3, help="cold runs, each with a new empty cache")
    args = ap.parse_args()
    from machine import machine_info
    out = {"machine": machine_info(), "target_s": 90}
    runs = []
    with tempfile.TemporaryDirectory() as tmp:
        for k in range(1 if args.quick else args.repeats):
            cache, res = Path(tmp) / f"numba-cache-{k}", Path(tmp) / f"out-{k}"
            runs.append(run(cache, res))
        out["cold_runs"] = runs
        # the median run by wall time (its fields, so the record reads as one run)
        out["cold"] = sorted(runs, key=lambda r: r["wall_s"])[len(runs) // 2]
        if not args.quick:
            out["warm"] = run(cache, res)
    out["machine"]["load_average_at_end"] = os.getloadavg()
    (HERE / "results").mkdir(exist_ok=True)
    (HERE / "results" / "first_run.json").write_text(json.dumps(out, indent=1))
    print("cold runs (wall s): " + ", ".join(f"{r['wall_s']:.1f}" for r in runs))
    for k in ("cold", "warm"):
        if k in out:
            r = out[k]
            print(f"{k}{' (median)' if k == 'cold' else ''}: {r['wall_s']:.1f} s wall, {r['cpu_s']:.1f} s CPU "
                  f"(kernels {r['kernels_s']:.1f} s, solve {r['solve_s']:.1f} s, "
                  f"start-up and output {r['other_s']:.1f} s)")


if __name__ == "__main__":
    main()
