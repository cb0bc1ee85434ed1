"""Parallel loops of the assembly kernels, on Python threads.

A parallel kernel is a ``nogil`` Numba function ``kernel(lo, hi, *args)``
that handles the items ``lo .. hi - 1`` of a loop whose items are
independent (or, in the coloured assemblies, write to disjoint entries).
``run_chunks`` splits a range into chunks and runs them on a thread pool of
``numba.get_num_threads()`` threads (set by ``NUMBA_NUM_THREADS`` or
``numba.set_num_threads``, as before), the calling thread taking the first
chunk; it returns when all are done.

Why not Numba's ``prange``: a parallel loop costs a gufunc library that links
and re-optimizes everything the loop body calls, i.e. the whole point kernel
again; measured on the DKT assembly, ``parallel=True`` took 27-32 s to compile
against 8 s for the same function without it (and a second library per
parallel kernel).  The chunks here are a few per thread, each a plain call of
a compiled function (~10 us of dispatch), and the results do not depend on
the number of threads: each item is computed the same way whichever chunk it
falls in, and within a colour no two items touch the same entries.
"""

import itertools
from concurrent.futures import ThreadPoolExecutor, wait

import numba

CHUNKS_PER_THREAD = 4    # load balance against dispatch cost (~10 us per chunk)
_pool = None


def _executor():
    global _pool
    if _pool is None:
        _pool = ThreadPoolExecutor(max_workers=max(1, numba.config.NUMBA_NUM_THREADS - 1),
                                   thread_name_prefix="shellritz")
    return _pool


def run_chunks(kernel, lo, hi, *args, min_chunk=1):
    """kernel(a, b, *args) on chunks [a, b) covering [lo, hi), on
    numba.get_num_threads() threads (the caller's included), each taking the
    next chunk when done with one.  At most CHUNKS_PER_THREAD chunks per
    thread, none shorter than min_chunk items."""
    n = hi - lo
    if n <= 0:
        return
    threads = numba.get_num_threads()
    nchunk = max(1, min(CHUNKS_PER_THREAD * threads, n // max(1, min_chunk)))
    if threads == 1 or nchunk == 1:
        kernel(lo, hi, *args)
        return
    bounds = [lo + (k * n) // nchunk for k in range(nchunk + 1)]
    chunks = itertools.count()          # next() is atomic under the GIL

    def work():
        k = next(chunks)
        while k < nchunk:
            kernel(bounds[k], bounds[k + 1], *args)
            k = next(chunks)
    futures = [_executor().submit(work) for _ in range(min(threads, nchunk) - 1)]
    try:
        work()
    finally:
        wait(futures)
    for f in futures:
        f.result()                      # re-raise a worker's error
