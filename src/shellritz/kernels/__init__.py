"""Numba kernels of the engines.

``KERNEL`` holds the options of every kernel that allocates nothing (all but
the scratch allocators and the parallel drivers).  ``_nrt=False`` compiles it
without Numba's reference counting: such a function only borrows views of
arrays its caller owns, so the counts are not needed, and the atomic
increment/decrement pairs Numba otherwise emits for every view taken from the
tuples of work arrays cost about a quarter of the point kernel (Hessian
12.2 -> 8.9 us per point on one thread).  ``_nrt`` is Numba's own switch for
this (underscored, but part of its target options since the runtime was
introduced); a kernel compiled with it cannot create arrays, which Numba
rejects at compile time.

``fastmath`` lets LLVM fuse multiply-adds (``contract``), reassociate sums
(``reassoc``: reductions vectorize), ignore the sign of zero (``nsz``) and
use reciprocals (``arcp``); not ``nnan``/``ninf``, so the kernels' checks of
non-finite values (``not x > 0.0``, ``np.isfinite``) stay.  Measured
(2026-12-06, 2 threads): point-kernel Hessian 7.26 -> 6.59 us per point on
one thread, Hessian assembly 39.3 -> 34.1 ms on the 1,280-triangle Sze
cantilever and 153.5 -> 136.8 ms on 5,120.  It changes round-off (sums in
another order): results agree to round-off, not to the bit, with builds of
another arithmetic; bench/disc_robustness.py, where round-off decides which
load paths pass nearly singular equilibria, counts 50 of 60 either way.
"""

KERNEL = {"cache": True, "_nrt": False, "fastmath": {"contract", "reassoc", "nsz", "arcp"}}
