"""MuJoCo's profiler timers, off while an env's own physics runs.

MuJoCo times the stages of ``mj_step`` into ``mjData.timer`` only while the global callback ``mjcb_time`` is set;
the C library leaves it unset.  The Python bindings set one (a steady clock) when ``mujoco`` is imported (and
``mujoco.set_mjcb_time(None)`` sets it back; ``mujoco.get_mjcb_time()`` shows only callbacks set from Python, so it
reports None), and every ``mj_step`` then reads that clock about a dozen times: on the 2-vCPU VM of
docs/performance.md a quarter of the s500's ``mj_step`` (2.08 -> 1.55 us per step, bit-for-bit the same physics).
An env's ``MjData`` are its own and nobody reads their timers, so by default (``HoverBatchEnv(mujoco_timers=False)``)
its rollouts run with ``mjcb_time`` unset, and it is set back afterwards (the bindings' clock, or whatever callback
was set before).

``mjcb_time`` is one global of the process.  Stepping in one thread at a time (an env, then other MuJoCo code), every
timer is as before.  But while an env's rollout runs, MuJoCo stepped on other threads -- other code, or an env built
with ``mujoco_timers=True`` -- gets meaningless timer statistics: a stage timed from before the switch to after it
adds minus a clock reading (negative durations).  Code that reads ``mjData.timer`` while envs step on other threads
builds every env with ``mujoco_timers=True``.  Envs stepping at once on several threads
(:class:`fawtgym.eval.sharded.ShardedLoop`) share one count: the first unsets the callback, the last sets it back; a
callback set meanwhile (by other code) is kept.

The callback is reached through ``ctypes`` in the ``libmujoco`` the bindings have loaded (only a library already
loaded is taken, never a second copy); where it cannot be found (:data:`AVAILABLE` False) the switch does nothing and
MuJoCo keeps its timers.
"""

from __future__ import annotations

import ctypes
import glob
import os
import threading
from collections.abc import Iterator
from contextlib import contextmanager

import mujoco

__all__ = ["AVAILABLE", "suspended", "timer_callback", "timers_off", "timers_on"]


def _loaded(path: str) -> ctypes.CDLL | None:
    """The library at ``path`` if this process has it loaded already (never loads a second copy), else None."""
    if os.name == "nt":  # LoadLibrary has no "only if loaded": ask for the module's handle first
        if not ctypes.WinDLL("kernel32").GetModuleHandleW(path):  # type: ignore[attr-defined, unused-ignore]
            return None
        return ctypes.CDLL(path)
    return ctypes.CDLL(path, mode=os.RTLD_NOLOAD | os.RTLD_LAZY)  # OSError if not loaded


def _callback_slot() -> ctypes.c_void_p | None:
    """``mjcb_time`` of the ``libmujoco`` next to the bindings that the bindings have loaded, or None."""
    folder = os.path.dirname(mujoco.__file__)
    for pattern in ("libmujoco.so*", "libmujoco*.dylib", "mujoco.dll"):
        for path in sorted(glob.glob(os.path.join(folder, pattern))):
            try:
                lib = _loaded(path)
                if lib is not None:
                    return ctypes.c_void_p.in_dll(lib, "mjcb_time")
            except (OSError, ValueError, AttributeError):  # not loaded, or no such symbol
                continue
    return None


_SLOT = _callback_slot()
#: whether the switch works here (``libmujoco``'s ``mjcb_time`` found)
AVAILABLE = _SLOT is not None
_LOCK = threading.Lock()
_depth = 0  # rollouts running with the timers off
_saved: int | None = None  # the callback they unset


def timer_callback() -> int | None:
    """The address of MuJoCo's timer callback now (None: unset, or the switch is not :data:`AVAILABLE`)."""
    return None if _SLOT is None else _SLOT.value


def timers_off() -> None:
    """Unset MuJoCo's timer callback (the first of nested or concurrent calls saves it); pair with :func:`timers_on`."""
    global _depth, _saved
    if _SLOT is None:
        return
    with _LOCK:
        if _depth == 0:
            _saved = _SLOT.value
            _SLOT.value = None
        _depth += 1


def timers_on() -> None:
    """Undo one :func:`timers_off`; the last one sets the saved callback back, unless one was set meanwhile."""
    global _depth, _saved
    if _SLOT is None:
        return
    with _LOCK:
        if _depth == 0:
            raise RuntimeError("mujoco_timers.timers_on() without a timers_off() before it")
        _depth -= 1
        if _depth == 0:
            if _SLOT.value is None:
                _SLOT.value = _saved
            _saved = None


@contextmanager
def suspended(active: bool = True) -> Iterator[None]:
    """MuJoCo's timers off inside the ``with`` block (``active`` False: left as they are), as an env with
    ``mujoco_timers=False`` runs its physics (benchmarks time their bare-MuJoCo baselines under the env's setting)."""
    if not active:
        yield
        return
    timers_off()
    try:
        yield
    finally:
        timers_on()
