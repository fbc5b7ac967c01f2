"""The FAWT flight study of Wang et al. (2024), Sec. 7 (Table 4), flown batched, with its assumptions explicit.

One :class:`~fawtgym.envs.hover_batch_env.HoverBatchEnv` per controller holds every (duty, seed) of the
study as a row (each row its own FAWT wind model, seeded by the row's seed, so a (duty, seed) sees the
same wind whatever else is flown and whichever controller flies it: comparisons are paired).  The
controllers are the PX4 cascade and PX4 + observer feedforward (:mod:`fawtgym.agents.px4_agent`).

Every aerodynamic and timing number the result depends on is a field of :class:`Assumptions`; its
value, source and range are in ``docs/fidelity.md``.  None was chosen by looking at Table 4.

Failure as the paper means it (a vehicle that could not keep hovering): a *physical* limit, not a box.
The fan array is a wall ``ARRAY_DISTANCE`` = 1.5 m upstream of the hover point (Sec. 7.3): a row crashes
when its centre comes within the vehicle radius (arm + rotor radius) of the array plane; the ground
(the env's ground contact) and divergence end a row too.  Downstream the room is open.  The +-2 m box
of the env (``box=True``) remains an option.  Per row the study records the peak upstream and downstream
excursions (along the stream, from the set point).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from fawtgym.core.frames import FAWT_HOVER_POINT_NED, FAWT_ORIGIN_NED, R_FAWT_TO_NED
from fawtgym.eval.reproduce.progress import Progress, tick

#: distance of the hover point from the fan-array plane [m] (Wang et al. 2024, Sec. 7.3)
ARRAY_DISTANCE = 1.5
#: the stream direction in NED (FAWT x)
STREAM_NED = R_FAWT_TO_NED[:, 0].copy()
#: the paper's hover: 210 s, fan on for 150 s (Sec. 7.3); (hover, on, off) [s]
PAPER_SCHEDULE = (210.0, 20.0, 170.0)
#: the env's termination box when ``box=False`` (large enough never to act before the physical limits)
_OPEN_BOX = 50.0
#: Table 4 duties that have a named wind preset
_PRESET_DUTIES = (30, 40, 50, 60, 70)
BASELINE = "px4"


@dataclasses.dataclass(frozen=True)
class Assumptions:
    """The study's aerodynamic and timing numbers (docs/fidelity.md gives each one's source and range).

    ``linear_drag_per_kg`` [N s/m per kg]: the rotors' linear drag at hover (``aero.calibrated_rotor_drag``);
    ``body_drag`` [N s^2/m^2]: horizontal quadratic body drag ``0.5 rho C_D A``; ``spin_tau`` /
    ``spin_down_tau`` [s]: fan spin-up / spin-down time constants; ``pose_latency`` [s]: motion-capture
    latency to the controller; ``observer_inputs``: what the observer knows of the thrust ("commanded"
    through a thrust model, or the exact "applied" one); ``thrust_model_error``: that model's relative error.
    """

    linear_drag_per_kg: float = 0.34
    body_drag: float = 0.017
    spin_tau: float = 1.0
    spin_down_tau: float = 2.0
    pose_latency: float = 0.02
    observer_inputs: str = "commanded"
    thrust_model_error: float = -0.05

    def replace(self, **changes: Any) -> Assumptions:
        return dataclasses.replace(self, **changes)


#: sensitivity: each assumption over its documented range (docs/fidelity.md), the others at their defaults
SENSITIVITY_RANGES: dict[str, tuple[Any, ...]] = {
    "linear_drag_per_kg": (0.26, 0.40),
    "body_drag": (0.009, 0.022),
    "spin_tau": (0.3, 3.0),
    "spin_down_tau": (1.0, 4.0),
    "pose_latency": (0.0, 0.05),
    "thrust_model_error": (-0.10, 0.05),
    "observer_inputs": ("applied",),
}


def vehicle_for(assumptions: Assumptions) -> dict[str, Any]:
    """The s500 with the study's drag numbers (a vehicle mapping for the env)."""
    from fawtgym.envs.aero import calibrated_rotor_drag
    from fawtgym.envs.vehicles import make_vehicle

    base = make_vehicle("s500")
    k_d = calibrated_rotor_drag(base, assumptions.linear_drag_per_kg)
    bz = base.body_drag[2]
    return {"base": "s500", "rotor_drag": k_d, "body_drag": (assumptions.body_drag, assumptions.body_drag, bz)}


def wind_for(duty: float, hover: float, on: float, off: float, assumptions: Assumptions) -> dict[str, Any]:
    """The FAWT wind of a duty [%] with the study's fan schedule."""
    name = {"name": f"fawt-{int(duty)}"} if duty in _PRESET_DUTIES else {"name": "fawt", "duty": duty / 100.0}
    return {**name, "on_time": on, "off_time": off, "spin_tau": assumptions.spin_tau,
            "spin_down_tau": assumptions.spin_down_tau}


def agent_for(column: str, env: Any, assumptions: Assumptions, observer_kwargs: Mapping[str, Any] | None = None
              ) -> Any:
    """The agent of a column (``px4`` or ``px4+<observer>``) with the study's sensing assumptions."""
    from fawtgym.agents.px4_agent import PX4Agent, PX4ObserverAgent

    opts = {"pose_latency": assumptions.pose_latency, "observer_inputs": assumptions.observer_inputs,
            "thrust_model_error": assumptions.thrust_model_error}
    if column == BASELINE:
        return PX4Agent.for_env(env, **opts)
    return PX4ObserverAgent.for_env(env, observer=column.split("+", 1)[1], observer_kwargs=observer_kwargs, **opts)


def flight_steps(hover: float, control_rate: float) -> int:
    """Control steps of one :func:`fly` over ``hover`` seconds at ``control_rate`` (the env's ``max_steps``)."""
    return int(math.ceil(hover * control_rate - 1e-9))


def vehicle_radius(preset: Any) -> float:
    """Arm length + rotor radius [m]: how close the centre can come to a wall before a rotor touches it."""
    return float(preset.arm_length + preset.rotor_radius)


def fly(column: str, rows: Sequence[tuple[float, int]], hover: float, on: float, off: float,
        assumptions: Assumptions = Assumptions(), sensors: str = "mocap_imu", control_rate: float = 200.0,
        box: bool = False, record_hz: float = 20.0, observer_kwargs: Mapping[str, Any] | None = None,
        progress: Progress | None = None) -> dict[str, Any]:
    """Fly ``rows`` = [(duty %, seed), ...] with one controller; per-row traces and failure data.

    ``progress``, if given, is called with the number of control steps done, :func:`flight_steps` in all
    (the steps a flight skips once every row has failed are counted at its end).

    Returns arrays over rows: ``pos`` / ``att`` error traces (K, R) at every control step (NaN after a
    row failed), ``failure`` (R,) ("" if it held; else ``upstream_wall``, ``ground_contact``, ``out_of_bounds``
    (box), ``diverged``, ...), ``fail_time`` [s], ``upstream`` / ``downstream`` (R,) peak excursions [m]
    along the stream, and decimated traces for figures.
    """
    from fawtgym.envs.hover_batch_env import HoverBatchEnv
    from fawtgym.envs.wind import make_wind

    winds = [make_wind(wind_for(d, hover, on, off, assumptions)) for d, _ in rows]

    def per_row_wind(started: np.ndarray, rngs: list) -> dict[str, Any]:
        return {"wind": [winds[int(i)] for i in started]}

    env = HoverBatchEnv(num_envs=len(rows), vehicle=vehicle_for(assumptions),
                        wind=wind_for(rows[0][0], hover, on, off, assumptions), sensors=sensors,
                        control_rate=control_rate, episode_seconds=hover, init_noise=0.0,
                        max_position_error=2.0 if box else _OPEN_BOX, randomizer=per_row_wind)
    try:
        agent = agent_for(column, env, assumptions, observer_kwargs)
        obs, info = env.reset(seed=[int(s) for _, s in rows])
        agent.reset(info)
        n, steps, dt = len(rows), env.max_steps, env.dt
        setpoint = np.broadcast_to(np.asarray(env.setpoint, dtype=float), (n, 3))
        wall = float(np.dot(setpoint[0] - FAWT_ORIGIN_NED, STREAM_NED))
        if not math.isclose(wall, ARRAY_DISTANCE, abs_tol=1e-9) or not np.allclose(setpoint, FAWT_HOVER_POINT_NED):
            raise ValueError(f"the study flies at the FAWT hover point {FAWT_HOVER_POINT_NED.tolist()}")
        crash_upstream = ARRAY_DISTANCE - vehicle_radius(agent.preset)
        alive = np.ones(n, dtype=bool)
        failure = np.array([""] * n, dtype=object)
        fail_time = np.full(n, np.nan)
        up, down = np.zeros(n), np.zeros(n)
        pos_tr, att_tr = np.full((steps, n), np.nan), np.full((steps, n), np.nan)
        restarted = np.zeros(n, dtype=bool)  # rows the env ended last step (it restarts them: so does the agent)
        done = 0
        for k in range(steps):
            if restarted.any():
                agent.reset(info, rows=restarted)
            action = agent.act(obs, info)
            r_d = agent.attitude_setpoint
            obs, _, terminated, _, info = env.step(action)
            truth = info["truth"]
            err = np.asarray(truth["position"]) - setpoint
            along = err @ STREAM_NED
            up = np.where(alive, np.maximum(up, -along), up)
            down = np.where(alive, np.maximum(down, along), down)
            tr = np.einsum("nji,nji->n", r_d, np.asarray(truth["attitude"]))
            pos_tr[k] = np.where(alive, np.linalg.norm(err, axis=1), np.nan)
            att_tr[k] = np.where(alive, np.arccos(np.clip((tr - 1.0) / 2.0, -1.0, 1.0)), np.nan)
            wall_hit = alive & (-along >= crash_upstream)
            restarted = np.asarray(terminated, dtype=bool).copy()
            ended = alive & restarted
            new_fail = wall_hit | ended
            if new_fail.any():
                reasons = np.where(wall_hit, "upstream_wall", np.asarray(info["failure"], dtype=object))
                failure[new_fail] = [r or "terminated" for r in reasons[new_fail]]
                fail_time[new_fail] = (k + 1) * dt
                alive &= ~new_fail
            done = k + 1
            tick(progress)
            if not alive.any():
                break
        if done < steps:
            tick(progress, steps - done)
    finally:
        env.close()
    every = max(1, int(round(1.0 / (record_hz * dt))))
    return {"column": column, "rows": [(float(d), int(s)) for d, s in rows], "dt": dt, "pos": pos_tr, "att": att_tr,
            "failure": failure.tolist(), "fail_time": fail_time, "upstream": up, "downstream": down,
            "crash_upstream": crash_upstream, "trace_time": np.arange(0, steps, every) * dt + dt,
            "trace_pos": pos_tr[::every], "trace_att": att_tr[::every]}


def failure_fraction(failures: Sequence[str]) -> tuple[int, int, float, float, float]:
    """(failed, n, fraction, Wilson 95 % low, high) of a cell's seeds."""
    from fawtgym.eval.stats import failure_rate

    k, n = sum(1 for f in failures if f), len(failures)
    est = failure_rate(k, n)
    if est.value is None or est.low is None or est.high is None:
        raise ValueError("a failure fraction needs at least one seed, got none")
    return k, n, float(est.value), float(est.low), float(est.high)
