"""The machine a benchmark ran on, recorded in every bench/results file: CPU
model, cores (and those this process may use), Python and library versions,
how the kernels run in parallel and on how many threads, the thread variables
of the environment, the load average (a shared machine shows up there) and
how the memory behaves (``memory_info``: on a VM whose balloon reports free
pages to the host, memory freed and touched again seconds later costs about
3 s per GB of page faults, ten times a plain machine's)."""

import os
import platform
from importlib import metadata
from pathlib import Path

LIBRARIES = ("numpy", "scipy", "numba", "llvmlite", "pyamg", "pypardiso", "mkl", "intel-openmp", "tbb",
             "scikit-fem")
THREAD_VARIABLES = ("OMP_NUM_THREADS", "NUMBA_NUM_THREADS", "NUMBA_THREADING_LAYER", "MKL_NUM_THREADS",
                    "OPENBLAS_NUM_THREADS", "KMP_BLOCKTIME", "OMP_WAIT_POLICY")


def cpu_model():
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def version(dist):
    try:
        return metadata.version(dist)
    except metadata.PackageNotFoundError:
        return None


def machine_info(extra_libraries=()):
    """A dict for the 'machine' entry of a results file."""
    import numba
    return {"cpu": cpu_model(), "cores": os.cpu_count(), "cores_available": len(os.sched_getaffinity(0)),
            "python": platform.python_version(),
            "libraries": {d: version(d) for d in (*LIBRARIES, *extra_libraries)},
            # the assembly kernels are nogil Numba functions run on Python threads
            # (shellritz/kernels/parallel.py), numba.get_num_threads() of them
            "threading": "python threads (shellritz.kernels.parallel)",
            "numba_threads": numba.get_num_threads(),
            "environment": {v: os.environ.get(v) for v in THREAD_VARIABLES},
            "load_average": list(os.getloadavg()),
            "memory": memory_info()}


def _read(path):
    try:
        return Path(path).read_text().strip()
    except OSError:
        return None


def memory_info():
    """Transparent huge pages (mode, defrag) and whether a virtio balloon
    reports free pages to the host (feature bit 5, VIRTIO_BALLOON_F_REPORTING:
    freed guest memory is handed back within seconds, and its next first
    touch waits for the host; measured on the machine of bench/results:
    11.7 s to touch 4 GB, 1.4 s again at once, 6.9 s after 10 s, 10.9 s
    after 30 s)."""
    reporting = None
    for dev in Path("/sys/bus/virtio/drivers/virtio_balloon").glob("virtio*"):
        features = _read(dev / "features")
        if features:
            reporting = len(features) > 5 and features[5] == "1"
    return {"thp_enabled": _read("/sys/kernel/mm/transparent_hugepage/enabled"),
            "thp_defrag": _read("/sys/kernel/mm/transparent_hugepage/defrag"),
            "balloon_free_page_reporting": reporting,
            "numpy_madvise_hugepage": os.environ.get("NUMPY_MADVISE_HUGEPAGE")}
