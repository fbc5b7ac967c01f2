"""The test suite's tolerance policy: when two results must agree, and how closely (docs/testing.md).

1. **Same code path, run twice** (determinism, seeding, resume, pickling, a reset that must reproduce a
   run), and **one code path on a batch and on one of its rows**: bitwise equality,
   :func:`assert_same_path` (or ``np.testing.assert_array_equal``).  The same operations on the same inputs
   in the same process give the same bits; any difference is a bug.  Every law is one compiled row kernel
   and N = 1 is a batch of one (HoverEnv is HoverBatchEnv(1), an observer of one row is the same kernel),
   rows never interact, so row i of an N-row env, observer, wind or aero call is bitwise the one-row run with
   that row's inputs and seeds: a batch-vs-N = 1 comparison belongs to this case, not to case 2 (a tolerance
   there would hide a rounding-level coupling of the rows, the defect such a test is for).

2. **Two implementations of one law** (a compiled kernel and an independent numpy reference written in the
   test, e.g. a per-rotor loop with ``numpy.cross`` and BLAS products; a closed-form exponential and
   ``scipy.linalg.expm``; a quaternion and a matrix form of one rotation): :func:`assert_same_law`.  They
   round differently (the order of a sum, a fused multiply-add, BLAS picking another kernel for another shape
   or CPU: ``OPENBLAS_CORETYPE``), so they agree to a tolerance scaled by the magnitudes involved and by the
   number of steps, never to one ulp::

       tol  = C * eps * scale * cond * sqrt(steps)     absolute
       rtol = C * eps * cond * sqrt(steps)             relative, on top: |actual - desired| <= tol + rtol |desired|

   - ``eps = np.finfo(float).eps`` (2.2e-16), ``C = SAFETY = 100``: a stated safety factor for the
     handful of roundings per operation and the kernels we have not measured;
   - ``scale``: the largest magnitude among the quantities that make the compared value (default:
     ``max |desired|``, the reference; never the actual result).  Pass it when intermediate values are
     larger than the result (cancellation: the sum of the terms' magnitudes) or when a per-step value
     crosses zero (the quantity's scale over the run); ``scale=0`` compares relatively only, for values
     computed without cancellation (products and sums of positive terms);
   - ``steps``: the number of steps (updates, integration steps) that accumulated rounding; independent
     roundings grow like sqrt(steps), and C = 100 also covers the linear worst case (every rounding of
     the same sign in a non-expanding law) up to 1e4 steps;
   - ``cond``: how much the law amplifies a relative perturbation of its inputs, stated in the test
     with its reason: 1 for a well-conditioned map, a condition number for a linear solve or an
     eigenvector, ``floor ** (p - 1)`` for a Hölder term ``|x| ** p`` (p < 1) floored at ``|x| >= floor``,
     the gain-times-step product of a high-gain loop.

   The tolerance must stay orders of magnitude below any real discrepancy (a missing or wrong term, a
   step of another length, a wrong gain: 1e-4 and up, relative), so the test can still fail (the former
   N = 1 fast-path comparisons caught a 1e-5 relative change of one HC-ESO gain, 1e-7 of an FFTS-ESO gain,
   1e-9 of the GESO bandwidth); and it must stay >= 30x above the measured difference on every OpenBLAS kernel
   (``OPENBLAS_CORETYPE=SkylakeX``, ``Haswell``, ``Prescott``).  ``cond`` is never fitted to one machine:
   it is a bound or a named constant below, with its reason.

Tolerances that test physics or a paper's numbers (a convergence bound, an integrator error, a table
value) are not this policy's business: they state their own reason where they are written.
"""

from __future__ import annotations

import math

import numpy as np

#: machine epsilon of float64
EPS = float(np.finfo(float).eps)
#: safety factor C of the policy
SAFETY = 100.0
#: ``cond`` of the finite-time (Hölder-continuous) observers (FFTS-ESO, FxTSDO, STO, PDT-STA): terms like
#: |e|^p e with p < 1 have an unbounded slope at e = 0, so a rounding delta of an input comes out amplified by
#: ~|e|^(p - 1) where the error e is small; measured <= 6e2 on the suite's runs (SkylakeX, Haswell, Prescott).
HOLDER = 1e4
#: ``cond`` of the HC-ESO (eq. 30 of Wang 2022), which adds to its Hölder terms (floor |Psi| >= 1e-12:
#: |Psi|^(2 alpha - 2) <= 4e3) the matrix H(s) = I - c s s^T / max(|s|^2, 1e-24) of eq. 28: it depends on the
#: direction of s, which is pure rounding right after a reset at zero attitude error (up to 1 / sqrt(floor) =
#: 1e12 in theory); measured <= 3.1e5 relative to the compared quantity's scale (the first update of
#: ``vectors="attitude"`` on the env run, SkylakeX kernel; 6.4e4 for the IMU vectors).
HC_ESO_COND = 1e6


def same_law_tol(scale: float, steps: int = 1, cond: float = 1.0) -> float:
    """Absolute tolerance C eps scale cond sqrt(steps) of the policy (module docstring)."""
    if not (np.isfinite(scale) and scale >= 0 and steps >= 1 and cond >= 1):
        raise ValueError(f"need finite scale >= 0, steps >= 1, cond >= 1; got {scale!r}, {steps!r}, {cond!r}")
    return SAFETY * EPS * float(scale) * float(cond) * math.sqrt(steps)


def assert_same_law(actual, desired, *, scale: float | None = None, steps: int = 1, cond: float = 1.0,
                    what: str = "") -> float:
    """Assert that two implementations of one law agree: ``|actual - desired| <= tol + rtol |desired|`` with
    ``tol = C eps scale cond sqrt(steps)`` and ``rtol = C eps cond sqrt(steps)`` (module docstring); shapes must
    be equal and non-finite values must sit at the same places.  ``desired`` is the reference implementation.
    Returns the absolute tolerance; the failure message states it and how it was made."""
    actual, desired = np.asarray(actual, dtype=float), np.asarray(desired, dtype=float)
    assert actual.shape == desired.shape, f"{what}: shapes differ, {actual.shape} != {desired.shape}"
    if scale is None:
        finite = desired[np.isfinite(desired)]
        scale = float(np.abs(finite).max()) if finite.size else 0.0
    tol = same_law_tol(scale, steps, cond)
    rtol = same_law_tol(1.0, steps, cond)
    np.testing.assert_allclose(
        actual, desired, rtol=rtol, atol=tol, equal_nan=True,
        err_msg=(f"{what}: two implementations of one law must agree to tol = C eps scale cond sqrt(steps) = "
                 f"{SAFETY:g} * {EPS:.3g} * {scale:.3g} * {cond:.3g} * sqrt({steps}) = {tol:.3g} "
                 f"(+ rtol {rtol:.3g}); see tests/_tolerance.py"))
    return tol


def assert_same_path(actual, desired, *, what: str = "") -> None:
    """Assert bitwise equality: the SAME code path run twice (determinism, seeding, resume) must give the same
    bits (shapes, values, NaN places)."""
    assert np.shape(actual) == np.shape(desired), f"{what}: shapes differ, {np.shape(actual)} != {np.shape(desired)}"
    np.testing.assert_array_equal(actual, desired,
                                  err_msg=f"{what}: the same code path run twice must give the same bits")
