"""Argument types of the kernels compiled with an explicit signature, and whether such signatures are enforced.

A kernel compiled for one explicit signature (:func:`compile_only`, from the on-disk cache) then refuses,
with a TypeError raised before it runs, arguments of any other type, dtype, ndim or layout (a list, a float32 or
read-only array, a strided view, None).  A caller on a hot path can therefore skip those checks in Python: it
calls the kernel and, on TypeError, takes its general path (conversion, the Python checks and their one-line
errors).  Under ``NUMBA_DISABLE_JIT=1`` kernels are plain Python functions that accept anything, so
:data:`TYPED_DISPATCH` is False and the caller must check the types itself.
"""

from __future__ import annotations

import threading
from typing import Any

from numba import config, float64

#: True when kernels are compiled (explicit signatures enforced by numba's dispatch)
TYPED_DISPATCH: bool = not getattr(config, "DISABLE_JIT", False)
#: C-contiguous float64 arrays: (N,), (N, k), (N, 3, 3) (or any 3-d buffer)
VALUES, ROWS, ROTATIONS = float64[::1], float64[:, ::1], float64[:, :, ::1]


#: ``njit`` options of a kernel that allocates nothing (its scratch is an argument): compiled without numba's
#: reference counting (``_nrt=False``, an option numba uses for its own allocation-free helpers).  Every row view a
#: kernel's loop makes, and every array argument of a law inlined into it, otherwise costs an atomic increment and
#: decrement per row (found with ``perf`` and ``gdb``: ~15 % of the PX4 cascade kernel, most of the GESO, HC-ESO,
#: pdt_sta and QB updates at N = 1024).  Without NRT a kernel cannot allocate (numba refuses to compile it), nor
#: assign one array to another (``a[:] = b`` may go through a temporary: copy entry by entry).
NO_REFCOUNT: dict[str, Any] = {"_nrt": False}
#: ``njit`` options of a kernel that allocates and is also called from a :data:`NO_REFCOUNT` one (on a rare path):
#: a callee inherits its caller's setting unless it states its own, so it states reference counting on.
REFCOUNTED: dict[str, Any] = {"_nrt": True}


_LOCK = threading.Lock()
_COMPILED: set[int] = set()  # id() of the dispatchers compile_only has compiled (dispatchers live as long as modules)


def compile_only(kernel: Any, signature: Any) -> None:
    """Compile the numba dispatcher ``kernel`` for ``signature`` (loaded from numba's disk cache when it is there) and
    refuse any other argument types from then on (TypeError).  Called on the kernel's first use rather than at import
    (an explicit signature in the decorator would load it whenever its module is imported); only when
    :data:`TYPED_DISPATCH` (plain Python functions have nothing to compile).  Idempotent and thread-safe: agents
    stepping on several threads (:class:`fawtgym.eval.sharded.ShardedLoop`) may make their first calls at once."""
    with _LOCK:
        if id(kernel) in _COMPILED:
            return
        kernel.compile(signature)
        kernel.disable_compile()
        _COMPILED.add(id(kernel))
