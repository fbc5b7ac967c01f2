"""fawtgym.core.kernel_types.compile_only: one signature, then refusal of others; idempotent and thread-safe."""

from __future__ import annotations

import threading

import numpy as np
import pytest
from numba import njit

from fawtgym.core.kernel_types import TYPED_DISPATCH, VALUES, compile_only


def _fresh_kernel():
    @njit(cache=False)
    def double(a):
        return a * 2.0

    return double


@pytest.mark.skipif(not TYPED_DISPATCH, reason="NUMBA_DISABLE_JIT=1: kernels are plain Python functions")
def test_compile_only_twice_and_from_many_threads_at_once():
    """A second call (another agent's first update) must not fail with numba's 'compilation disabled'."""
    kernel = _fresh_kernel()
    compile_only(kernel, (VALUES,))
    compile_only(kernel, (VALUES,))
    np.testing.assert_array_equal(kernel(np.ones(2)), [2.0, 2.0])
    with pytest.raises(TypeError):
        kernel(np.ones(2, dtype=np.float32))  # another signature: refused

    kernel = _fresh_kernel()
    barrier, errors = threading.Barrier(4), []

    def first_use():
        barrier.wait()
        try:
            compile_only(kernel, (VALUES,))
        except Exception as exc:  # collected for the assertion
            errors.append(exc)

    threads = [threading.Thread(target=first_use) for _ in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert errors == []
    np.testing.assert_array_equal(kernel(np.ones(3)), [2.0, 2.0, 2.0])


def test_a_kernel_without_refcounts_calls_a_refcounted_one_that_allocates():
    """QUEST's last resort (the eigenvector of K, eq. 64: it allocates K and calls eigh) states REFCOUNTED, so a
    NO_REFCOUNT caller (quest_row inside pdt_sta's kernel) still runs it: compiled, and the same numbers as the
    function called alone."""
    from fawtgym.core.kernel_types import NO_REFCOUNT
    from fawtgym.observers import quest as Q

    @njit(cache=False, **NO_REFCOUNT)
    def last_resort(b, r, a, out):
        w, x, y, z, lam = Q._eigh_quaternion(b, r, a)
        out[0], out[1], out[2], out[3], out[4] = w, x, y, z, lam

    rng = np.random.default_rng(4)
    b = rng.normal(size=(3, 3))
    b /= np.linalg.norm(b, axis=1, keepdims=True)
    r = rng.normal(size=(3, 3))
    r /= np.linalg.norm(r, axis=1, keepdims=True)
    a = np.array([0.5, 0.3, 0.2])
    out = np.empty(5)
    for _ in range(3):  # allocations freed each call
        last_resort(b, r, a, out)
    np.testing.assert_array_equal(out, np.array(Q._eigh_quaternion(b, r, a)))
