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

No ``fastmath``: with it (even ``contract`` alone) a first run, which
compiles the kernels, and later runs, which load them from Numba's cache,
differed in the last bits (97 of 3,520 gradient entries of a small disc, by
2e-19), enough to change which load paths pass a nearly singular
equilibrium and to break the batch's bit-for-bit promise.  Likely cause:
a callee is optimized again in each caller it is linked into, LLVM's fusing
depends on the surrounding code, and the copy that runs is not the same in
the two cases.  The hot products are fused explicitly instead
(``small.fma``), which rounds the same way in every compilation.
"""

KERNEL = {"cache": True, "_nrt": False}
