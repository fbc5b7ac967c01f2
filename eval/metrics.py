"""Per-episode metrics of a batch of hover episodes, computed from the env's ``info["truth"]``.

:class:`EpisodeRecorder` is fed once per control step with the truth, the agent's action, its attitude
set point and its disturbance estimates, for N rows (one episode each) that may end at different times.
:meth:`EpisodeRecorder.finish` returns, per row, over the steps flown until the episode ended:

==========================  ======  =============================================================================
metric                      unit    definition
==========================  ======  =============================================================================
``pos_err_mean``            m       time average of ``|b - b_d|`` (Wang et al. 2024, Table 4's metric)
``pos_err_rms``, ``_max``   m       RMS and maximum of ``|b - b_d|``
``att_err_mean/_rms/_max``  rad     principal angle ``Phi = arccos((tr(R_d^T R) - 1) / 2)`` against the agent's
                                    commanded attitude ``R_d`` (Wang et al. 2024, eq. 88); NaN if the agent has none
``tilt_mean/_rms/_max``     rad     principal angle against level flight (the angle between body z and world z)
``wind_excursion_max``      m       peak of ``(b - b_d) . w`` along the unit mean wind ``w`` at the CoM over the
                                    episode (downstream positive; +north in still air)
``failure``                 --      the env's rule that ended the episode (``ground_contact``, ``out_of_bounds``,
                                    ``diverged``) or ``agent_error``; empty if it flew to the end
``failure_time``            s       episode time of the failure (NaN if none); ``time_flown`` the time flown
``control_effort``          --      RMS over time and action entries of ``a - a_hover`` (normalized env action)
``control_slew``            1/s     RMS of the action's rate of change ``(a_k - a_{k-1}) / dt``
``saturation``              --      fraction of steps with an action entry at (within 1e-6) or beyond its bound
``force_rmse``              N       RMS over time of ``|phi_hat - phi_D|`` (world NED) where the agent runs an
                                    observer estimating force; NaN otherwise
``torque_rmse``             N m     RMS of ``|tau_hat - tau_D|`` (body FRD), same rule
==========================  ======  =============================================================================

The estimation errors compare the estimate an agent formed at step k with the disturbance that acted
over the step before it (``info["truth"]`` of step k - 1): that is what a measurement at step k can
reveal.  For scheduled FAWT scenarios (fan on and off) ``pos_err_paper_schedule`` and
``att_err_paper_schedule`` are the Table 4 averages re-weighted to the paper's 210 s schedule
(:func:`fawtgym.eval.reproduce.table4.schedule_averages`).
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Mapping
from typing import Any

import numpy as np
from numpy.typing import NDArray

#: metrics that are averaged over seeds in the leaderboard (everything but the failure fields)
NUMERIC_METRICS = ("pos_err_mean", "pos_err_rms", "pos_err_max", "att_err_mean", "att_err_rms", "att_err_max",
                   "tilt_mean", "tilt_rms", "tilt_max", "wind_excursion_max", "control_effort", "control_slew",
                   "saturation", "force_rmse", "torque_rmse", "pos_err_paper_schedule", "att_err_paper_schedule",
                   "time_flown", "failure_time")
#: (label, unit) for tables and figures
METRIC_LABELS: dict[str, tuple[str, str]] = {
    "pos_err_mean": ("mean position error", "m"), "pos_err_rms": ("RMS position error", "m"),
    "pos_err_max": ("max position error", "m"), "att_err_mean": ("mean attitude error (vs command)", "rad"),
    "att_err_rms": ("RMS attitude error (vs command)", "rad"), "att_err_max": ("max attitude error", "rad"),
    "tilt_mean": ("mean tilt", "rad"), "tilt_rms": ("RMS tilt", "rad"), "tilt_max": ("max tilt", "rad"),
    "wind_excursion_max": ("peak downstream excursion", "m"), "control_effort": ("control effort", "-"),
    "control_slew": ("control slew", "1/s"), "saturation": ("saturated steps", "-"),
    "force_rmse": ("force estimation RMSE", "N"), "torque_rmse": ("torque estimation RMSE", "N m"),
    "pos_err_paper_schedule": ("mean position error, paper's 210 s schedule", "m"),
    "att_err_paper_schedule": ("mean attitude error, paper's 210 s schedule", "rad"),
    "time_flown": ("time flown", "s"), "failure_time": ("time to failure", "s"),
}
_SAT_TOL = 1e-6


def principal_angle(r: NDArray[np.float64], r_d: NDArray[np.float64]) -> NDArray[np.float64]:
    """``arccos((tr(R_d^T R) - 1) / 2)`` for batches (N, 3, 3) (Wang et al. 2024, eq. 88) [rad]."""
    tr = np.einsum("...ji,...ji->...", r_d, r)
    return np.arccos(np.clip((tr - 1.0) / 2.0, -1.0, 1.0))


def tilt_angle(r: NDArray[np.float64]) -> NDArray[np.float64]:
    """Angle between body z and world z (N, 3, 3) -> (N,) [rad]: the principal angle to the nearest level attitude."""
    return np.arccos(np.clip(r[..., 2, 2], -1.0, 1.0))


class EpisodeRecorder:
    """Records N episodes step by step (module docstring) and computes their metrics.

    Args:
        n: rows (episodes).
        dt: control step [s].
        max_steps: steps of a full episode.
        setpoint: (N, 3) NED set points [m].
        action_low, action_high, hover_action: the env's single action bounds and hover action (A,).
        record_hz: rate of the decimated traces kept for figures.
    """

    def __init__(self, n: int, dt: float, max_steps: int, setpoint: NDArray[np.float64],
                 action_low: NDArray[np.float64], action_high: NDArray[np.float64],
                 hover_action: NDArray[np.float64], record_hz: float = 20.0) -> None:
        self.n, self.dt, self.max_steps = n, float(dt), int(max_steps)
        self.setpoint = np.broadcast_to(np.asarray(setpoint, dtype=float), (n, 3)).copy()
        self.low, self.high = np.asarray(action_low, float), np.asarray(action_high, float)
        self.hover = np.asarray(hover_action, float)
        k = self.max_steps
        self.pos_err = np.zeros((k, n, 3))
        self.att_err = np.full((k, n), np.nan)
        self.tilt = np.zeros((k, n))
        self.wind = np.zeros((k, n, 3))
        self.action = np.zeros((k, n, self.hover.size))
        self.saturated = np.zeros((k, n), dtype=bool)
        self.force_err = np.full((k, n), np.nan)
        self.torque_err = np.full((k, n), np.nan)
        self.steps = 0
        self.alive = np.ones(n, dtype=bool)
        self.end_step = np.full(n, k, dtype=np.int64)  # steps flown per row
        self.failure = np.full(n, "", dtype=object)
        self.failure_message = np.full(n, "", dtype=object)
        self.record_every = max(1, int(round(1.0 / (record_hz * self.dt))))
        self._prev_truth: tuple[NDArray[np.float64], NDArray[np.float64]] | None = None

    def step(self, truth: Mapping[str, Any], action: NDArray[np.float64], attitude_sp: NDArray[np.float64] | None,
             estimate: tuple[NDArray[np.float64] | None, NDArray[np.float64] | None],
             estimate_truth: tuple[NDArray[np.float64], NDArray[np.float64]] | None,
             action_clipped: NDArray[np.bool_] | None = None) -> None:
        """Record one control step: ``truth`` after it, the ``action`` taken, the attitude set point and the
        estimates the agent formed before acting, and the disturbance (force, torque) that acted over the step
        before (what those estimates estimate).  Rows no longer alive are recorded but ignored."""
        k = self.steps
        if k >= self.max_steps:
            raise RuntimeError(f"EpisodeRecorder got more than max_steps={self.max_steps} steps")
        r = np.asarray(truth["attitude"], dtype=float)
        self.pos_err[k] = np.asarray(truth["position"], dtype=float) - self.setpoint
        self.tilt[k] = tilt_angle(r)
        if attitude_sp is not None:
            self.att_err[k] = principal_angle(r, np.asarray(attitude_sp, dtype=float))
        self.wind[k] = np.asarray(truth["wind"], dtype=float)
        a = np.asarray(action, dtype=float).reshape(self.n, -1)
        self.action[k] = a
        sat = ((a <= self.low + _SAT_TOL) | (a >= self.high - _SAT_TOL)).any(axis=1)
        self.saturated[k] = sat if action_clipped is None else sat | np.asarray(action_clipped, dtype=bool)
        f_hat, t_hat = estimate
        if estimate_truth is not None:
            if f_hat is not None:
                self.force_err[k] = np.linalg.norm(np.asarray(f_hat, float) - estimate_truth[0], axis=1)
            if t_hat is not None:
                self.torque_err[k] = np.linalg.norm(np.asarray(t_hat, float) - estimate_truth[1], axis=1)
        self.steps = k + 1

    def end(self, rows: NDArray[np.bool_], failure: NDArray[Any] | str, message: str = "") -> None:
        """End the episodes of ``rows`` at the current step (``failure`` per row or one rule for all)."""
        rows = rows & self.alive
        if not rows.any():
            return
        self.end_step[rows] = self.steps
        self.failure[rows] = np.broadcast_to(np.asarray(failure, dtype=object), (self.n,))[rows]
        if message:
            self.failure_message[rows] = message
        self.alive &= ~rows

    def finish(self, schedule: tuple[float, float, float] | None = None) -> tuple[list[dict[str, Any]],
                                                                                dict[str, NDArray[np.float64]]]:
        """(per-row metric dicts, decimated traces) over each row's flown steps.

        ``schedule`` = (hover, fan on, fan off) [s] adds the paper-schedule averages (module docstring).
        """
        self.end_step[self.alive] = self.steps
        k = np.arange(self.max_steps)[:, None]
        valid = k < self.end_step[None, :]  # (K, N)
        counts = np.maximum(valid.sum(axis=0), 1)

        def mean(x: NDArray[np.float64]) -> NDArray[np.float64]:
            return np.where(valid, x, 0.0).sum(axis=0) / counts

        def rms(x: NDArray[np.float64]) -> NDArray[np.float64]:
            return np.sqrt(mean(x * x))

        def peak(x: NDArray[np.float64]) -> NDArray[np.float64]:
            return np.where(valid, x, -np.inf).max(axis=0)

        pos = np.linalg.norm(self.pos_err, axis=2)
        wind_mean = np.where(valid[:, :, None], self.wind, 0.0).sum(axis=0) / counts[:, None]
        wind_norm = np.linalg.norm(wind_mean, axis=1)
        axis = np.where(wind_norm[:, None] > 1e-9, wind_mean / np.maximum(wind_norm, 1e-300)[:, None],
                        np.array([1.0, 0.0, 0.0]))
        along = np.einsum("kni,ni->kn", self.pos_err, axis)
        dev = self.action - self.hover
        slew = np.zeros_like(self.action)
        slew[1:] = (self.action[1:] - self.action[:-1]) / self.dt
        valid_slew = valid.copy()
        valid_slew[0] = False
        slew_counts = np.maximum(valid_slew.sum(axis=0), 1)
        att_known = np.asarray(np.isfinite(np.where(valid, self.att_err, 0.0)).all(axis=0))

        def est_rmse(err: NDArray[np.float64]) -> NDArray[np.float64]:
            ok = valid & np.isfinite(err)
            cnt = ok.sum(axis=0)
            out = np.sqrt(np.where(ok, err * err, 0.0).sum(axis=0) / np.maximum(cnt, 1))
            return np.where(cnt > 0, out, np.nan)

        att = np.where(np.isfinite(self.att_err), self.att_err, 0.0)
        m: dict[str, NDArray[np.floating[Any]]] = {
            "pos_err_mean": mean(pos), "pos_err_rms": rms(pos), "pos_err_max": peak(pos),
            "att_err_mean": np.where(att_known, mean(att), np.nan),
            "att_err_rms": np.where(att_known, rms(att), np.nan),
            "att_err_max": np.where(att_known, peak(att), np.nan),
            "tilt_mean": mean(self.tilt), "tilt_rms": rms(self.tilt), "tilt_max": peak(self.tilt),
            "wind_excursion_max": peak(along),
            "control_effort": np.sqrt(mean((dev * dev).mean(axis=2))),
            "control_slew": np.sqrt(np.where(valid_slew, (slew * slew).mean(axis=2), 0.0).sum(axis=0) / slew_counts),
            "saturation": mean(self.saturated.astype(float)),
            "force_rmse": est_rmse(self.force_err), "torque_rmse": est_rmse(self.torque_err),
            "time_flown": self.end_step * self.dt,
            "failure_time": np.where(self.failure != "", self.end_step * self.dt, np.nan),
        }
        if schedule is not None:
            from fawtgym.eval.reproduce.table4 import schedule_averages

            hover, on, off = schedule
            flown = self.steps
            pos_t = np.where(valid, pos, np.nan)[:flown]
            att_t = np.where(valid & att_known[None, :], self.att_err, np.nan)[:flown]
            with warnings.catch_warnings():  # all-NaN columns of failed rows (masked below)
                warnings.simplefilter("ignore", RuntimeWarning)
                pa = schedule_averages(pos_t, self.dt, hover, on, off).get("paper")
                aa = schedule_averages(att_t, self.dt, hover, on, off).get("paper")
            complete = self.end_step >= self.max_steps
            m["pos_err_paper_schedule"] = np.where(complete, pa, np.nan) if pa is not None else np.full(self.n, np.nan)
            m["att_err_paper_schedule"] = np.where(complete, aa, np.nan) if aa is not None else np.full(self.n, np.nan)
        rows = []
        for i in range(self.n):
            row: dict[str, float | str | None] = {key: _clean(float(v[i])) for key, v in m.items()}
            row["failure"] = str(self.failure[i])
            if self.failure_message[i]:
                row["failure_message"] = str(self.failure_message[i])
            rows.append(row)
        every = self.record_every
        idx = np.arange(every - 1, self.steps, every)
        keep = valid[idx]
        traces = {"time": (idx + 1) * self.dt,
                  "pos_err": np.where(keep, pos[idx], np.nan),
                  "att_err": np.where(keep, self.att_err[idx], np.nan),
                  "tilt": np.where(keep, self.tilt[idx], np.nan),
                  "along_wind": np.where(keep, along[idx], np.nan),
                  "force_err": np.where(keep, self.force_err[idx], np.nan),
                  "torque_err": np.where(keep, self.torque_err[idx], np.nan),
                  "wind_speed": np.where(keep, np.linalg.norm(self.wind[idx], axis=2), np.nan),
                  # the full-rate wind at the CoM of the first row, for its spectrum
                  "wind_row0": self.wind[: int(self.end_step[0]), 0, :].copy()}
        return rows, traces


def _clean(v: float) -> float | None:
    """JSON-safe float: None for NaN/inf."""
    return v if math.isfinite(v) else None
