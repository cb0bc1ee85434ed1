"""kernels/parallel.py: chunks of a loop on threads."""

import threading
import time

import numba
import numpy as np
import pytest
from numba import njit

from shellritz.kernels.parallel import CHUNKS_PER_THREAD, run_chunks


@njit(nogil=True)
def _mark(lo, hi, count, chunk_id):
    for i in range(lo, hi):
        count[i] += 1
        chunk_id[i] = lo


@pytest.fixture
def threads():
    before = numba.get_num_threads()
    yield
    numba.set_num_threads(before)


@pytest.mark.parametrize("n_threads", [1, 2])
@pytest.mark.parametrize("lo, hi, min_chunk", [(0, 1, 1), (3, 10, 1), (0, 1000, 1), (5, 1005, 64),
                                               (0, 100, 64), (7, 7, 1)])
def test_chunks_cover_the_range_once(threads, n_threads, lo, hi, min_chunk):
    numba.set_num_threads(min(n_threads, numba.config.NUMBA_NUM_THREADS))
    n = hi - lo
    count = np.zeros(hi + 3, np.int64)
    chunk_id = np.full(hi + 3, -1, np.int64)
    run_chunks(_mark, lo, hi, count, chunk_id, min_chunk=min_chunk)
    assert np.all(count[lo:hi] == 1) and count[:lo].sum() == 0 and count[hi:].sum() == 0
    starts = np.unique(chunk_id[chunk_id >= 0])     # each item records its chunk's start
    if n == 0:
        assert starts.size == 0
        return
    sizes = np.diff(np.r_[starts, hi])
    assert starts[0] == lo
    assert starts.size <= CHUNKS_PER_THREAD * numba.get_num_threads()
    assert starts.size == 1 or sizes.min() >= min_chunk      # short loops: one call
    assert sizes.max() - sizes.min() <= 1                      # even chunks


def test_an_error_in_a_worker_reaches_the_caller(threads):
    numba.set_num_threads(min(2, numba.config.NUMBA_NUM_THREADS))
    if numba.get_num_threads() < 2:
        pytest.skip("one thread")
    main = threading.get_ident()

    def kernel(lo, hi):
        if threading.get_ident() == main:
            time.sleep(0.05)            # the worker thread takes the other chunks
        else:
            raise RuntimeError(f"chunk {lo}-{hi} failed")
    with pytest.raises(RuntimeError, match="chunk"):
        run_chunks(kernel, 0, 100)
