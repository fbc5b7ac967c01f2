"""Shared pytest configuration: headless rendering and a non-interactive matplotlib.

Tolerance policy (tests/_tolerance.py, docs/testing.md): the same code path run twice must give the same bits
(``assert_same_path`` / ``assert_array_equal``), a batch against its rows run alone included; two implementations
of one law (a law against an independent reference, closed form vs scipy) agree to
``tol = C eps scale cond sqrt(steps)`` with C = 100 (``assert_same_law``), never to one ulp.  Tolerances on
physics and paper numbers state their own reasons where they are written.
"""

import os

os.environ.setdefault("MUJOCO_GL", "egl")
os.environ.setdefault("MPLBACKEND", "Agg")
