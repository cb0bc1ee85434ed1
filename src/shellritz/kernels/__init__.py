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
"""

KERNEL = {"cache": True, "_nrt": False}
