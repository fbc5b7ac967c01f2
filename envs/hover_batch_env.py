"""``HoverBatchEnv``: N independent ``fawtgym/Hover-v0`` vehicles in one batch-first vector env.

``gym.make_vec("fawtgym/Hover-v0", num_envs=N, **options)`` or ``HoverBatchEnv(num_envs=N, **options)``.
The tables of :mod:`fawtgym.envs.hover_env` (action, observation, reward terms, starting state, episode
end) hold row by row; batched, they read:

| item | batched form |
| --- | --- |
| ``action_space`` | ``Box`` (N, 4): HoverEnv's ``single_action_space`` per row |
| ``observation_space`` | ``Box`` (N, 19) float32: HoverEnv's 19 entries per row |
| ``reward``, ``terminated``, ``truncated`` | (N,) arrays |
| ``info`` | HoverEnv's keys, each an (N, ...) array; ``info["reward_terms"]`` a dict of (N,) arrays |
| ``reset(seed=s)`` | row i as ``HoverEnv.reset(seed=s + i)``; a list of N seeds also works |
| arguments | HoverEnv's (``render_mode`` None), plus ``num_envs``, ``autoreset_mode``, ``randomizer`` (below) |

Version history: v0 as HoverEnv's; ``info["reward_terms"]`` added within v0.

Per vehicle (row) the semantics are exactly :class:`fawtgym.envs.hover_env.HoverEnv`'s (read its
module docstring): the same options and their validation (a template ``HoverEnv`` is built from the
same keyword arguments and its spaces, timing and reward weights are used), action checking and
clipping, wind at [CoM, rotor hubs 1-4] held with the aero wrench (plus a per-row external wrench)
over the control step, exact first-order motor lag (mid-substep thrust, end-of-step speed), 19-D
observation from measurements, the same dense reward, termination (ground contact, box,
divergence) and truncation.  What is batched:

* physics: one ``mujoco.rollout`` call per control step on the env's own one-vehicle model with
  one ``MjData`` on the calling thread (one core): state spec ``mjSTATE_FULLPHYSICS`` (time, qpos,
  qvel; 14 numbers, round-trips this model's state exactly: no actuator activations, contacts
  disabled so no warm start matters), control spec ``mjSTATE_CTRL | mjSTATE_QFRC_APPLIED`` with the
  whole (N, n_substeps, 10) array (rotor thrusts per substep, held world force and body torque as the
  free joint's generalized force, see :mod:`fawtgym.envs.mjcf`);
* wind, aero, sensors (:mod:`fawtgym.envs.sensors_batch`), observation, reward, termination: numpy
  over the leading axis N (no Python loop over vehicles per step).

Divergence: MuJoCo resets a row whose state becomes NaN/inf/huge (its warnings).  The rollout starts
every row at MuJoCo time ``_MJ_T0`` = 1 s, so a reset row ends at a time below 1 s instead of
``1 + n_substeps dt``; that row (or any row with a non-finite state) terminates with
``failure = "diverged"`` and keeps its last finite state, the other rows are unaffected.

Autoreset (``autoreset_mode``, in ``metadata["autoreset_mode"]``):

* ``"next_step"`` (``AutoresetMode.NEXT_STEP``, gymnasium's default and this env's): after a row
  terminates or truncates, the next ``step`` ignores its action, resets it and returns its reset
  observation and info with reward 0 and both flags False.
* ``"same_step"`` (``AutoresetMode.SAME_STEP``, what Stable-Baselines3 expects; no reward-0 step): a row
  that ends is reset inside the same ``step``.  Reward, ``terminated`` and ``truncated`` are the
  terminal step's; the returned observation and info rows are the new episode's (exactly what the
  next-step mode returns one step later); the terminal ones are in gymnasium's ``SyncVectorEnv`` format:
  ``info["final_obs"]`` an object array (N,) holding the terminal observation of each ended row (None
  elsewhere), ``info["final_info"]`` the terminal step's info (the batched arrays of every row; only the
  rows of its masks are terminal, the others equal the returned info's) with a ``"_<key>"`` mask beside
  every key at every level, and ``info["_final_obs"]`` / ``info["_final_info"]`` the ended rows (N,).
  Rows restarting while others fly must not advance the others' random streams: their first wind
  sample comes from the wind model's own restart (a cohort model steps alone; a shared stationary model
  starts the rows from a k-row copy, the other rows untouched), and with noisy sensors their first
  measurement draws its noise from each row's own sensor generator (the shared per-step stream of the
  other rows is untouched).  When every row ends at once the restart is the regular reset (at N = 1
  the row's own generator *is* the stream).  So with deterministic wind and
  exact sensors, or at N = 1, every episode (length, rewards, observations, terminal observation)
  equals the next-step mode's bitwise; with random wind or sensor noise at N > 1 the episodes are
  draws of the same distributions from other samples of the streams.

Domain randomization (``randomizer``, e.g. :mod:`fawtgym.train.randomization`): a callable
``randomizer(rows, rngs) -> draws`` called at every episode start (full reset and autoreset) with the
starting rows (k,) and one generator per row (spawned from the row's episode seed, child 2 of the
seed sequence whose children 0 and 1 seed the wind and the sensors, so the other streams are
unchanged and a seed reproduces the draws).  ``draws`` maps any of :data:`RANDOMIZER_KEYS` to one value
per row, applied per row for the whole episode: ``mass_scale`` (k,) and ``inertia_scale`` (k,) scale
the MuJoCo body mass and inertia of the row's own model copy (``mujoco.rollout`` takes one model per
row); ``drag_scale`` (k,) scales the row's aerodynamic wrench, i.e. all three drag coefficients of
:mod:`.aero` (rotor drag, flapping moment, body drag: the wrench is linear in them); ``gyro_bias`` /
``accel_bias`` (k, 3) replace the rows' turn-on IMU biases (noisy sensor presets only: exact sensors
have none); ``wind`` a list of k :class:`WindModel` (e.g. a FAWT wind at a drawn duty), each run for its
row alone (a cohort of one row, see Wind).  The current values are ``mass_scale``, ``inertia_scale``,
``drag_scale`` (N,), ``sensor.gyro_bias`` / ``sensor.accel_bias`` (N, 3).  The env's own onboard parts
keep the nominal vehicle: the ``ctbr`` rate loop, the hover action, ``info["applied"]`` (rotor thrusts
through the nominal allocation).

Seeding: ``reset(seed=s)`` gives row ``i`` the generator ``HoverEnv.reset(seed=s + i)`` would use
(same initial-state draws, same wind/sensor seeds; a list of per-row seeds is also accepted), so with
calm wind and ``sensors="none"`` row ``i`` reproduces that single env; the per-step sensor noise of
N > 1 rows comes from one generator seeded by ``s`` (fixed-size draws, rows stay independent), and
with N = 1 it is the row's own generator, so N = 1 reproduces ``HoverEnv`` with any sensors.

Wind: a wind model whose output does not depend on time (``calm``, steady ``fawt-*``, ``dryden-*``)
is stepped once for all N rows; a row that resets gets a fresh draw of its gust-filter state from
the stationary distribution.  Any other model (a fan schedule, ``gust-1cos``, a user class) is run
in cohorts: rows that reset at the same step share one copy of the model, stepped with their episode
time as each single env would (a deterministic model reproduces the single envs exactly; a random one
draws one stream set per cohort); cost grows with the number of distinct reset times alive.

``info`` holds batched arrays with HoverEnv's keys: ``measurement``/``applied``/``truth`` dicts of
(N, ...) arrays, ``reward_terms`` (a dict of (N,) arrays: the reward's terms, HoverEnv's table),
``setpoint`` (N, 3), ``action_clipped`` (N,), ``failure`` (N,) str, ``time`` (N,).  A row that
autoresets in the next-step mode reports reward 0 and all terms 0 on its reset step.

``action_type="ctbr"``: the inner rate loop (:mod:`fawtgym.envs.ctbr`) runs at the physics rate on the
true body rates, so the physics is one single-substep rollout per substep (``n_substeps`` calls per
control step), with :class:`BatchRateLoop` (RateLoop's law row by row) in between.

Not implemented: rendering (render a single ``fawtgym/Hover-v0``).
"""

from __future__ import annotations

import copy
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import mujoco
import numpy as np
from gymnasium.utils import seeding
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space
from mujoco import rollout
from numpy.typing import ArrayLike, NDArray

from fawtgym.core import measurement as M
from fawtgym.core.frames import SIGN2_MJ_NED, SIGN_MJ_NED, rot_ned_to_quat_mj
from fawtgym.core.so3 import exp_so3

from .ctbr import MAX_RATES, RateLoop
from .hover_env import INIT_SPREAD, HoverEnv, check_init_noise
from .mjcf import hull_points
from .motors import allocation_matrix, decay_factors, lag_thrusts, substep_times
from .observation import hover_observation
from .sensors_batch import BatchSensorModel
from .wind import WindModel
from .wind.base import CalmWind
from .wind.fawt import FawtWind
from .wind.outdoor import DrydenWind

_MJ_T0 = 1.0  #: MuJoCo time at the start of every rollout (a MuJoCo reset sets it to 0: divergence test)
_STATE_SPEC = int(mujoco.mjtState.mjSTATE_FULLPHYSICS)
_CONTROL_SPEC = int(mujoco.mjtState.mjSTATE_CTRL | mujoco.mjtState.mjSTATE_QFRC_APPLIED)
_SIGN, _SIGN2 = SIGN_MJ_NED, SIGN2_MJ_NED
#: the autoreset modes of HoverBatchEnv (module docstring)
AUTORESET_MODES = {"next_step": AutoresetMode.NEXT_STEP, "same_step": AutoresetMode.SAME_STEP}
#: what a randomizer's draws may set, one value per starting row (module docstring)
RANDOMIZER_KEYS = ("mass_scale", "inertia_scale", "drag_scale", "gyro_bias", "accel_bias", "wind")


def quat_mj_to_rot_ned_batch(q: NDArray[np.float64]) -> NDArray[np.float64]:
    """MuJoCo quaternions (N, 4) to R (N, 3, 3) FRD -> NED, with ``mju_quat2Mat``'s arithmetic."""
    w, x, y, z = q[:, 0], q[:, 1], q[:, 2], q[:, 3]
    q00, q01, q02, q03 = w * w, w * x, w * y, w * z
    q11, q12, q13, q22, q23, q33 = x * x, x * y, x * z, y * y, y * z, z * z
    r = np.empty((q.shape[0], 3, 3))
    r[:, 0, 0] = q00 + q11 - q22 - q33
    r[:, 1, 1] = q00 - q11 + q22 - q33
    r[:, 2, 2] = q00 - q11 - q22 + q33
    r[:, 0, 1] = 2 * (q12 - q03)
    r[:, 0, 2] = 2 * (q13 + q02)
    r[:, 1, 0] = 2 * (q12 + q03)
    r[:, 1, 2] = 2 * (q23 - q01)
    r[:, 2, 0] = 2 * (q13 - q02)
    r[:, 2, 1] = 2 * (q23 + q01)
    return r * _SIGN2


def _time_invariant(wind: WindModel) -> bool:
    """Whether ``wind``'s output depends on the time argument (models known to ignore it)."""
    if type(wind) is CalmWind or type(wind) is DrydenWind:
        return True
    return type(wind) is FawtWind and wind.schedule.steady


class BatchWind:
    """Runs one :class:`WindModel` for N rows whose episodes start at different times (module docstring).

    ``shared``: one model steps every row (time-invariant models); else cohorts: one model copy per set of
    rows that started together (or per row, for rows given their own model by a randomizer).
    """

    def __init__(self, template: WindModel, n: int) -> None:
        self.template = copy.deepcopy(template)  # pristine copy: cohorts are copied from it
        self.n = n
        self.shared = _time_invariant(template)
        self.model: WindModel | None = None
        self.cohorts: list[list[Any]] = []  # [model, rows (k,), alive (k,) bool]
        self._started: list[list[Any]] = []  # the cohorts of the last reset_rows (cohort mode)
        self._scratch: WindModel | None = None  # shared mode: restarts rows while the others go on
        self._last: tuple[NDArray[np.intp], Sequence[int], Sequence[np.random.SeedSequence]] = (
            np.zeros(0, dtype=np.intp), [], [])  # (rows, seed ints, seeds) of the last reset_rows

    @staticmethod
    def _seed(ints: Sequence[int], seeds: Sequence[np.random.SeedSequence]) -> np.random.SeedSequence:
        # one row: exactly the single env's wind seed; several: all rows' seed integers pooled
        return seeds[0] if len(seeds) == 1 else np.random.SeedSequence([int(i) for i in ints])

    def reset_rows(self, rows: NDArray[np.intp], ints: Sequence[int], seeds: Sequence[np.random.SeedSequence],
                   models: Sequence[WindModel] | None = None) -> None:
        """New episodes (time 0) for ``rows``; ``ints``/``seeds`` are the rows' wind seeds; ``models``: one own
        model per row (each then runs as a cohort of one row; a shared model becomes a cohort of its rows)."""
        self._last = (rows, ints, seeds)
        if models is not None:
            if self.shared:
                if self.model is not None:  # the rows still flying keep the shared model, as a cohort
                    self.cohorts = [[self.model, np.arange(self.n), np.ones(self.n, dtype=bool)]]
                self.shared, self.model = False, None
            for c in self.cohorts:
                c[2] &= ~np.isin(c[1], rows)
            self.cohorts = [c for c in self.cohorts if c[2].any()]
            self._started = []
            for row, model, seed in zip(rows.tolist(), models, seeds, strict=True):
                model.reset(1, seed=seed)
                self._started.append([model, np.array([row]), np.ones(1, dtype=bool)])
            self.cohorts.extend(self._started)
            return
        if self.shared:
            if self.model is None or rows.size == self.n:
                self.model = copy.deepcopy(self.template)
                self.model.reset(self.n, seed=self._seed(ints, seeds))
                return
            process = getattr(self.model, "process", None)
            if process is not None:  # fresh stationary gust-filter state for the reset rows
                p = process.p_stat
                w, v = np.linalg.eigh(p)
                root = v * np.sqrt(np.clip(w, 0.0, None))
                x = process.x.copy()
                for k, row in enumerate(rows.tolist()):  # reset path only
                    x[row] = root @ np.random.default_rng(seeds[k]).standard_normal(process.n_states)
                process.x = x
            return
        for c in self.cohorts:
            c[2] &= ~np.isin(c[1], rows)
        self.cohorts = [c for c in self.cohorts if c[2].any()]
        model = copy.deepcopy(self.template)
        model.reset(rows.size, seed=self._seed(ints, seeds))
        self._started = [[model, rows.copy(), np.ones(rows.size, dtype=bool)]]
        self.cohorts.append(self._started[0])

    def first_step(self, dt: float, points: NDArray[np.float64], velocity: NDArray[np.float64]) -> NDArray[np.float64]:
        """The first wind sample (k, K, 3) of the rows of the last :meth:`reset_rows` (at their ``points``
        (k, K, 3)), without stepping the other rows (same-step autoreset, module docstring)."""
        rows, ints, seeds = self._last
        if not self.shared:  # the cohorts just started step alone, at episode time 0, as in step()
            out = np.empty(points.shape)
            pos = {row: j for j, row in enumerate(rows.tolist())}
            for model, crows, _ in self._started:
                idx = np.array([pos[r] for r in crows.tolist()])
                out[idx] = model.step(0.0, dt, points[idx], velocity[idx])
            return out
        if rows.size == self.n:  # a full restart: the fresh shared model steps every row
            return self.model.step(0.0, dt, points, velocity)
        # the shared model goes on for the other rows: a k-row copy takes the restarted rows' fresh filter state
        # (reset_rows drew it) one step forward, with noise from the rows' pooled wind seed, and hands it back
        if self._scratch is None:
            self._scratch = copy.deepcopy(self.template)
        scratch = self._scratch
        scratch.reset(rows.size, seed=self._seed(ints, seeds))
        process = getattr(self.model, "process", None)
        if process is not None:
            scratch.process.x = process.x[rows].copy()
        out = scratch.step(0.0, dt, points, velocity)
        if process is not None:
            x = process.x.copy()
            x[rows] = scratch.process.x
            process.x = x
        return out

    def step(self, times: NDArray[np.float64], dt: float, points: NDArray[np.float64],
             velocity: NDArray[np.float64]) -> NDArray[np.float64]:
        """Wind (N, K, 3) at ``points`` (N, K, 3); ``times`` (N,) are the rows' episode times."""
        if self.shared:
            return self.model.step(float(times[0]), dt, points, velocity)
        out = np.empty(points.shape)
        for model, rows, alive in self.cohorts:  # one call per cohort (rows that reset together)
            live = rows[alive]
            got = model.step(float(times[live[0]]), dt, points[rows], velocity[rows])
            out[live] = got[alive]
        return out


def _with_masks(info: Mapping[str, Any], mask: NDArray[np.bool_]) -> dict[str, Any]:
    """``info`` with a ``"_<key>"`` mask beside every key at every level (gymnasium's vector-info format)."""
    out: dict[str, Any] = {}
    for key, value in info.items():
        out[key] = _with_masks(value, mask) if isinstance(value, Mapping) else value
        out[f"_{key}"] = mask
    return out


class BatchRateLoop:
    """:class:`fawtgym.envs.ctbr.RateLoop` for N vehicles: the same gains and law, row by row (batch-first)."""

    def __init__(self, loop: RateLoop, n: int) -> None:
        self.dt = loop.dt
        self.kp, self.ki, self.kd = loop.kp, loop.ki, loop.kd
        self.i_lim = loop.i_lim
        self.j_t = loop.j.T
        self.b_thrust = loop.b_inv[:, 0]
        self.b_torque_t = loop.b_inv[:, 1:].T
        self.t_min, self.t_max = loop.t_min, loop.t_max
        self.integral = np.zeros((n, 3))
        self.prev_rate = np.zeros((n, 3))
        self.has_prev = np.zeros(n, dtype=bool)

    def reset_rows(self, rows: NDArray[np.intp]) -> None:
        self.integral[rows] = 0.0
        self.prev_rate[rows] = 0.0
        self.has_prev[rows] = False

    def rotor_thrusts(self, collective: NDArray[np.float64], rate_sp: NDArray[np.float64],
                      rate: NDArray[np.float64]) -> NDArray[np.float64]:
        """Rotor thrusts (N, 4) [N] for collective thrusts (N,) [N] and body-rate setpoints (N, 3) [rad/s]."""
        err = rate_sp - rate
        rate_dot = np.where(self.has_prev[:, None], (rate - self.prev_rate) / self.dt, 0.0)
        self.prev_rate = rate.copy()
        self.has_prev[:] = True
        ang_acc = self.kp * err + self.integral - self.kd * rate_dot
        torque = ang_acc @ self.j_t + np.cross(rate, rate @ self.j_t)
        thrust_part = self.b_thrust * collective[:, None]
        torque_part = torque @ self.b_torque_t
        lo, hi = self.t_min - thrust_part, self.t_max - thrust_part
        with np.errstate(divide="ignore", invalid="ignore"):
            room = np.where(torque_part > 0, hi / torque_part, np.where(torque_part < 0, lo / torque_part, np.inf))
        scale = np.clip(room.min(axis=1), 0.0, 1.0)
        free = scale >= 1.0  # PX4: freeze the integrator while the actuators saturate
        self.integral = np.where(free[:, None], np.clip(self.integral + self.ki * err * self.dt, -self.i_lim,
                                                        self.i_lim), self.integral)
        return np.clip(thrust_part + scale[:, None] * torque_part, self.t_min, self.t_max)


class HoverBatchEnv(VectorEnv):
    """N hover vehicles stepped together; per-row semantics of :class:`HoverEnv` (module docstring).

    Args:
        num_envs: number of vehicles N.
        **options: the options of :class:`HoverEnv` (vehicle, wind, action_type, sensors, control_rate,
            physics_rate, episode_seconds, setpoint, init_noise, reward_weights, max_position_error,
            integrator); ``render_mode`` must be None.
        autoreset_mode: ``"next_step"`` (default) or ``"same_step"`` (or the ``AutoresetMode``); module docstring.
        randomizer: None, or a callable ``(rows, rngs) -> draws`` run at every episode start (module docstring).
    """

    metadata = {"autoreset_mode": AutoresetMode.NEXT_STEP, "render_modes": []}

    def __init__(self, num_envs: int = 1, vehicle: Any = "s500", wind: Any = "calm", action_type: str = "motors",
                 sensors: Any = "none", control_rate: float = 100.0, physics_rate: float = 1000.0,
                 episode_seconds: float = 10.0, setpoint: ArrayLike | None = None, init_noise: float = 1.0,
                 reward_weights: Mapping[str, float] | None = None, max_position_error: float = 2.0,
                 integrator: str = "Euler", render_mode: str | None = None, render_width: int = 480,
                 render_height: int = 480, autoreset_mode: str | AutoresetMode = "next_step",
                 randomizer: Callable[[NDArray[np.intp], list[np.random.Generator]], Mapping[str, Any]] | None = None
                 ) -> None:
        if isinstance(num_envs, bool) or not isinstance(num_envs, (int, np.integer)) or num_envs < 1:
            raise ValueError(f"num_envs must be a positive int, got {num_envs!r}")
        modes = {**AUTORESET_MODES, **{m: m for m in AUTORESET_MODES.values()}}
        if not isinstance(autoreset_mode, (str, AutoresetMode)) or autoreset_mode not in modes:
            raise ValueError(f"autoreset_mode must be one of {list(AUTORESET_MODES)}, got {autoreset_mode!r}")
        if randomizer is not None and not callable(randomizer):
            raise ValueError(f"randomizer must be None or a callable (rows, rngs) -> draws, got "
                             f"{type(randomizer).__name__}")
        if render_mode is not None:
            raise ValueError(f"HoverBatchEnv does not render; render_mode must be None, got {render_mode!r} "
                             "(render a single fawtgym/Hover-v0 instead)")
        single = HoverEnv(vehicle=vehicle, wind=wind, action_type=action_type, sensors=sensors,
                          control_rate=control_rate, physics_rate=physics_rate, episode_seconds=episode_seconds,
                          setpoint=setpoint, init_noise=init_noise, reward_weights=reward_weights,
                          max_position_error=max_position_error, integrator=integrator,
                          render_width=render_width, render_height=render_height)
        n = self.num_envs = int(num_envs)
        self.autoreset_mode = modes[autoreset_mode]
        self._same_step = self.autoreset_mode is AutoresetMode.SAME_STEP
        self.metadata = {**type(self).metadata, "autoreset_mode": self.autoreset_mode}
        self.randomizer = randomizer
        self.preset = single.preset
        self.action_type = action_type
        self.n_substeps, self.physics_dt, self.dt = single.n_substeps, single.physics_dt, single.dt
        self.episode_seconds, self.max_steps = single.episode_seconds, single.max_steps
        self.max_position_error = single.max_position_error
        self.init_noise = single.init_noise
        self.reward_weights = dict(single.reward_weights)
        w = self.reward_weights
        self._reward_w = np.repeat([w["pos"], w["vel"], 0.0, w["rate"], w["action"]], [3, 3, 6, 3, 4])
        self.single_action_space = single.action_space
        self.single_observation_space = single.observation_space
        self.action_space = batch_space(self.single_action_space, n)
        self.observation_space = batch_space(self.single_observation_space, n)
        self.render_mode = None
        self.setpoint = np.tile(single.setpoint, (n, 1))
        self.model = single.model
        self._data = mujoco.MjData(self.model)
        self._rollout = rollout.Rollout(nthread=0)  # rollouts on the calling thread: one core
        self._models = [self.model] * n  # one per row: a row with a randomized vehicle gets its own copy
        self._body = self.model.body("vehicle").id
        self._nominal_mass = float(self.model.body_mass[self._body])
        self._nominal_inertia = self.model.body_inertia[self._body].copy()
        self.mass_scale, self.inertia_scale, self.drag_scale = np.ones(n), np.ones(n), np.ones(n)
        self._drag_scaled = False
        self._qfrc_col = self.model.nu  # qfrc_applied follows ctrl in the control vector
        self.wind = BatchWind(single.wind, n)
        self.aero = single.aero
        self.sensor = BatchSensorModel(single.sensor.spec, self.dt, n)
        single.close()

        p = self.preset
        self._hull_t = hull_points(p).T
        self._alloc_t = allocation_matrix(p).T
        self._rotor_pos_t = np.ascontiguousarray(p.rotor_positions.T)
        self._hover = single.hover_action().astype(np.float32)
        self._rate_loop = BatchRateLoop(RateLoop(p, self.physics_dt), n) if action_type == "ctbr" else None
        self._sub_decay_up, self._sub_decay_down = decay_factors(p, substep_times(self.physics_dt, 1))
        self._max_thrust = 4.0 * p.max_thrust_per_rotor
        self._act_low = self.single_action_space.low.astype(float)
        self._act_high = self.single_action_space.high.astype(float)
        self._obs_low = self.single_observation_space.low.astype(float)
        self._obs_high = self.single_observation_space.high.astype(float)
        k = self.n_substeps
        self._decay_up, self._decay_down = decay_factors(p, substep_times(self.dt, k))  # (K + 1,), as HoverEnv
        self._omega_min, self._omega_span = p.omega_min, p.omega_max - p.omega_min
        self._ctrl = np.zeros((n, k, mujoco.mj_stateSize(self.model, _CONTROL_SPEC)))
        self._mj_state = np.zeros((n, mujoco.mj_stateSize(self.model, _STATE_SPEC)))
        self._out = np.zeros((n, k, self._mj_state.shape[1]))
        self._out1 = np.zeros((n, 1, mujoco.mj_stateSize(self.model, _STATE_SPEC)))  # ctbr: one substep
        self._ctrl1 = np.zeros((n, 1, self._ctrl.shape[2]))
        self.external_force = np.zeros((n, 3))
        self.external_torque = np.zeros((n, 3))
        self._row_rngs: list[np.random.Generator] | None = None
        self._autoreset = np.zeros(n, dtype=bool)
        self.time = np.zeros(n)

    # ---- public helpers -------------------------------------------------------------------
    def hover_action(self) -> NDArray[np.float32]:
        """(N, 4) actions holding the weight at rest."""
        return np.tile(self._hover, (self.num_envs, 1))

    def set_external_wrench(self, force_ned: ArrayLike = (0.0, 0.0, 0.0),
                            torque_frd: ArrayLike = (0.0, 0.0, 0.0)) -> None:
        """Constant extra disturbance per row: force NED (3,) or (N, 3) [N], torque FRD (3,) or (N, 3) [N m]."""
        n = self.num_envs
        try:
            f = np.broadcast_to(np.asarray(force_ned, dtype=float), (n, 3)).copy()
            t = np.broadcast_to(np.asarray(torque_frd, dtype=float), (n, 3)).copy()
        except ValueError as exc:
            raise ValueError(f"external wrench must be (3,) or ({n}, 3) arrays, got shapes "
                             f"{np.shape(force_ned)}, {np.shape(torque_frd)}") from exc
        if not (np.all(np.isfinite(f)) and np.all(np.isfinite(t))):
            raise ValueError(f"external wrench must be finite, got {force_ned!r}, {torque_frd!r}")
        self.external_force, self.external_torque = f, t

    # ---- state ------------------------------------------------------------------------------
    def _readout(self, s: NDArray[np.float64]) -> tuple[NDArray, NDArray, NDArray, NDArray]:
        """NED/FRD (position, velocity, R, Omega) from FULLPHYSICS states (k, 14) = [time, qpos 7, qvel 6]."""
        return s[:, 1:4] * _SIGN, s[:, 8:11] * _SIGN, quat_mj_to_rot_ned_batch(s[:, 4:8]), s[:, 11:14] * _SIGN

    def _reset_rows(self, rows: NDArray[np.intp]) -> list[np.random.Generator]:
        """HoverEnv.reset for ``rows`` (each row draws from its own generator, in HoverEnv's order), then the
        randomizer's draws; returns the rows' sensor generators."""
        k = rows.size
        du = np.empty((k, 4, 3))
        ints, wind_seeds, sensor_rngs, draw_rngs = [], [], [], []
        spread = np.array([INIT_SPREAD[key] for key in ("position", "velocity", "attitude", "angular_velocity")])
        for j, row in enumerate(rows.tolist()):  # reset path only: per-row generators
            rng = self._row_rngs[row]
            for i in range(4):
                du[j, i] = rng.uniform(-1.0, 1.0, 3) * spread[i] * self.init_noise
            seed_int = int(rng.integers(2**63))
            # children 0, 1 as HoverEnv's spawn(2); child 2 (randomizer only) leaves them unchanged
            wind_seed, sensor_seed, *draw_seed = np.random.SeedSequence(seed_int).spawn(
                2 if self.randomizer is None else 3)
            ints.append(seed_int)
            wind_seeds.append(wind_seed)
            sensor_rngs.append(np.random.default_rng(sensor_seed))
            draw_rngs.extend(np.random.default_rng(d) for d in draw_seed)
        s = np.zeros((k, self._mj_state.shape[1]))
        s[:, 1:4] = (self.setpoint[rows] + du[:, 0]) * _SIGN
        s[:, 4:8] = rot_ned_to_quat_mj(exp_so3(du[:, 2]))
        s[:, 8:11] = du[:, 1] * _SIGN
        s[:, 11:14] = du[:, 3] * _SIGN
        self._mj_state[rows] = s
        b, v, r, w = self._readout(s)
        self._pos[rows], self._vel[rows], self._rot[rows], self._omega[rows] = b, v, r, w
        self.rotor_speeds[rows] = self.preset.hover_omega
        self._applied[rows] = self.preset.k_thrust * self.preset.hover_omega**2
        self._last_action[rows] = self._hover
        self._accel[rows] = 0.0
        self._steps[rows] = 0
        self.time[rows] = 0.0
        self._failure[rows] = ""
        self.sensor.reset_rows(rows, sensor_rngs)
        winds = None if self.randomizer is None else self._apply_draws(rows, self.randomizer(rows, draw_rngs))
        self.wind.reset_rows(rows, ints, wind_seeds, winds)
        if self._rate_loop is not None:
            self._rate_loop.reset_rows(rows)
        if self.num_envs == 1:  # N = 1: the row's own sensor stream, as HoverEnv
            self.sensor.set_noise_rng(sensor_rngs[0])
        return sensor_rngs

    def _apply_draws(self, rows: NDArray[np.intp], draws: Mapping[str, Any]) -> list[WindModel] | None:
        """Apply a randomizer's draws to ``rows`` (module docstring); returns the rows' wind models (or None).

        The whole draw is checked before anything is applied (ValueError naming the key and what is allowed).
        """
        k = rows.size
        if not isinstance(draws, Mapping):
            raise ValueError(f"randomizer must return a mapping of {list(RANDOMIZER_KEYS)}, got {type(draws).__name__}")
        unknown = sorted(set(draws) - set(RANDOMIZER_KEYS))
        if unknown:
            raise ValueError(f"randomizer draws {unknown} are unknown; valid: {list(RANDOMIZER_KEYS)}")
        values = {}
        for key, shape, need, ok in (("mass_scale", (k,), "> 0", np.greater),
                                     ("inertia_scale", (k,), "> 0", np.greater),
                                     ("drag_scale", (k,), ">= 0", np.greater_equal),
                                     ("gyro_bias", (k, 3), "finite", None), ("accel_bias", (k, 3), "finite", None)):
            if key in draws:
                v = np.asarray(draws[key], dtype=float)
                if v.shape != shape or not np.all(np.isfinite(v)) or (ok is not None and not np.all(ok(v, 0.0))):
                    raise ValueError(f"randomizer draw {key!r} must be {need} with shape {shape} (one per starting "
                                     f"row), got shape {v.shape}: {v.ravel()[:6].tolist()}")
                values[key] = v
        if ("gyro_bias" in values or "accel_bias" in values) and not self.sensor.noisy:
            raise ValueError("randomizer draws IMU biases but the sensors are exact (sensors='none' has no biases); "
                             "use a noisy preset such as 'mocap_imu'")
        winds = draws.get("wind")
        if winds is not None and (len(winds) != k or not all(isinstance(w, WindModel) for w in winds)):
            raise ValueError(f"randomizer draw 'wind' must be a list of {k} WindModel (one per starting row)")
        if "mass_scale" in values or "inertia_scale" in values:
            mass = values.get("mass_scale", self.mass_scale[rows])
            inertia = values.get("inertia_scale", self.inertia_scale[rows])
            self.mass_scale[rows], self.inertia_scale[rows] = mass, inertia
            for row, sm, sj in zip(rows.tolist(), mass.tolist(), inertia.tolist(), strict=True):  # reset path only
                model = self._models[row]
                if model is self.model:
                    if sm == 1.0 and sj == 1.0:
                        continue
                    model = self._models[row] = copy.deepcopy(self.model)  # the row's own copy, once
                model.body_mass[self._body] = self._nominal_mass * sm
                model.body_inertia[self._body] = self._nominal_inertia * sj
                mujoco.mj_setConst(model, self._data)  # derived constants (subtree masses, ...) of the new body
        if "drag_scale" in values:
            self.drag_scale[rows] = values["drag_scale"]
            self._drag_scaled = bool(np.any(self.drag_scale != 1.0))
        if "gyro_bias" in values:
            self.sensor.gyro_bias[rows] = values["gyro_bias"]
        if "accel_bias" in values:
            self.sensor.accel_bias[rows] = values["accel_bias"]
        return None if winds is None else list(winds)

    # ---- gym API -------------------------------------------------------------------------
    def reset(self, *, seed: int | Sequence[int | None] | None = None,
              options: dict[str, Any] | None = None) -> tuple[NDArray[np.float32], dict[str, Any]]:
        n = self.num_envs
        if seed is None:
            seeds: list[int | None] = [None] * n
        elif isinstance(seed, (int, np.integer)) and not isinstance(seed, bool):
            seeds = [int(seed) + i for i in range(n)]
        else:
            seeds = list(seed)
            if len(seeds) != n:
                raise ValueError(f"seed must be an int, None or a list of {n} ints/None, got {len(seeds)} entries")
        if self._row_rngs is None or seed is not None:
            old = self._row_rngs
            self._row_rngs = [seeding.np_random(s)[0] if (s is not None or old is None) else old[i]
                              for i, s in enumerate(seeds)]
        if seed is not None or not hasattr(self, "_noise_seeded"):
            ints = [int(x) for x in seeds if isinstance(x, (int, np.integer)) and not isinstance(x, bool)]
            entropy = None if len(ints) < n else [*ints, n, 0x5E45]  # reproducible iff every row has a seed
            self.sensor.set_noise_rng(np.random.default_rng(entropy))
            self._noise_seeded = True
        if options:
            unknown = set(options) - {"setpoint", "init_noise"}
            if unknown:
                raise ValueError(f"unknown reset option(s) {sorted(unknown)}; valid: ['init_noise', 'setpoint']")
            if "setpoint" in options:
                sp = np.asarray(options["setpoint"], dtype=float)
                if sp.shape not in ((3,), (n, 3)) or not np.all(np.isfinite(sp)):
                    raise ValueError(f"setpoint must be 3 finite NED coordinates or ({n}, 3), "
                                     f"got {options['setpoint']!r}")
                self.setpoint = np.broadcast_to(sp, (n, 3)).copy()
            if "init_noise" in options:
                self.init_noise = check_init_noise(options["init_noise"])
        self._pos, self._vel = np.zeros((n, 3)), np.zeros((n, 3))
        self._rot, self._omega = np.zeros((n, 3, 3)), np.zeros((n, 3))
        self.rotor_speeds, self._applied = np.zeros((n, 4)), np.zeros((n, 4))
        self._last_action, self._accel = np.zeros((n, 4)), np.zeros((n, 3))
        self._steps = np.zeros(n, dtype=np.int64)
        self._failure = np.full(n, "", dtype="<U14")
        self._force, self._torque, self._wind_com = np.zeros((n, 3)), np.zeros((n, 3)), np.zeros((n, 3))
        self._autoreset = np.zeros(n, dtype=bool)
        self._reset_rows(np.arange(n))
        self._update_disturbance(np.ones(n, dtype=bool))
        info = self._info(np.zeros(n, dtype=bool))
        obs, _, info["reward_terms"] = self._observation_and_reward(info["measurement"], self._last_action)
        return obs, info

    def _check_actions(self, actions: ArrayLike, stepping: NDArray[np.bool_]) -> NDArray[np.float64]:
        n = self.num_envs
        a = np.asarray(actions, dtype=float)
        if a.shape != (n, 4):
            raise ValueError(f"actions must have shape ({n}, 4), got {np.shape(actions)}")
        bad = ~np.isfinite(a)
        bad &= stepping[:, None]
        if bad.any():
            row, i = (int(x) for x in np.argwhere(bad)[0])
            raise ValueError(f"actions[{row}, {i}] is {a[row, i]}; every action entry must be finite "
                             f"(bounds {self._act_low.tolist()} .. {self._act_high.tolist()})")
        return a

    def step(self, actions: ArrayLike) -> tuple[NDArray[np.float32], NDArray[np.float64], NDArray[np.bool_],
                                                 NDArray[np.bool_], dict[str, Any]]:
        if self._row_rngs is None:
            raise RuntimeError("call reset() before step()")
        resetting = self._autoreset
        stepping = ~resetting
        a = self._check_actions(actions, stepping)
        clipped = np.minimum(np.maximum(a, self._act_low), self._act_high)
        any_reset = bool(resetting.any())
        if any_reset:
            clipped[resetting] = self._hover
        action_clipped = (clipped != a).any(axis=1) & stepping

        state = self._mj_state
        if self._rate_loop is None:
            final, diverged = self._run_motors(clipped)
        else:
            final, diverged = self._run_ctbr(clipped)
        diverged &= stepping
        ok = stepping & ~diverged
        self.time = self.time + np.where(stepping, self.dt, 0.0)
        self._steps = self._steps + stepping

        v_before = self._vel
        b, v, r, w = self._readout(final)
        if ok.all():
            self._mj_state = final.copy()
            self._pos, self._vel, self._rot, self._omega = b, v, r, w
            self._accel = (v - v_before) / self.dt
        else:
            self._mj_state = np.where(ok[:, None], final, state)
            self._pos = np.where(ok[:, None], b, self._pos)
            self._vel = np.where(ok[:, None], v, self._vel)
            self._rot = np.where(ok[:, None, None], r, self._rot)
            self._omega = np.where(ok[:, None], w, self._omega)
            self._accel = np.where(ok[:, None], (self._vel - v_before) / self.dt, self._accel)
        self._failure = np.where(diverged, "diverged", "").astype("<U14")
        self._last_action_prev = self._last_action
        if any_reset:
            self._reset_rows(np.flatnonzero(resetting))
        self._update_disturbance(~diverged)
        pos, rot = self._pos, self._rot
        ground = pos[:, 2] + (rot[:, 2, :] @ self._hull_t).max(axis=1) >= 0.0
        out = np.abs(pos - self.setpoint).max(axis=1) > self.max_position_error
        self._failure[ok & ground] = "ground_contact"
        self._failure[ok & ~ground & out] = "out_of_bounds"
        info = self._info(action_clipped)
        obs, reward, terms = self._observation_and_reward(info["measurement"], clipped, self._last_action_prev)
        self._last_action = clipped
        terminated = self._failure != ""
        truncated = ~terminated & (self._steps >= self.max_steps)
        if any_reset:
            reward[resetting] = 0.0
            for v in terms.values():
                v[resetting] = 0.0
        info["reward_terms"] = terms
        ended = terminated | truncated
        if not self._same_step:
            self._autoreset = ended
        elif ended.any():
            obs, info = self._restart(ended, obs, info)
        return obs, reward, terminated, truncated, info

    def _restart(self, ended: NDArray[np.bool_], obs: NDArray[np.float32], info: dict[str, Any]
                 ) -> tuple[NDArray[np.float32], dict[str, Any]]:
        """Same-step autoreset: reset the ``ended`` rows now; the new episodes' observation and info, with the
        terminal ones under ``final_obs`` / ``final_info`` (module docstring)."""
        n = self.num_envs
        rows = np.flatnonzero(ended)
        mask = ended.copy()
        mask.flags.writeable = False  # one read-only mask shared by every "_<key>" entry
        final_obs = np.full(n, None, dtype=object)
        for i in rows.tolist():  # ended rows only
            final_obs[i] = obs[i]
        final_info = _with_masks(info, mask)
        sensor_rngs = self._reset_rows(rows)
        if rows.size == n:  # every row restarts: the regular path (N = 1: exactly the next-step reset)
            self._update_disturbance(np.ones(n, dtype=bool))
            meas = None
        else:
            self._start_disturbance(rows)
            meas = self._measure_restarted(rows, sensor_rngs, info["measurement"])
        new_info = self._info(info["action_clipped"] & ~ended, meas)
        new_obs, _, new_info["reward_terms"] = self._observation_and_reward(new_info["measurement"], self._last_action)
        new_info["final_obs"], new_info["_final_obs"] = final_obs, mask
        new_info["final_info"], new_info["_final_info"] = final_info, mask
        return new_obs, new_info

    def _start_disturbance(self, rows: NDArray[np.intp]) -> None:
        """The held disturbance of restarted ``rows`` (their first wind sample), the other rows untouched; the aero
        wrench over all N rows (the arithmetic of a full step), kept for ``rows``."""
        points = self._wind_points()
        wind = np.zeros(points.shape)
        wind[rows] = self.wind.first_step(self.dt, points[rows], self._vel[rows])
        force, torque = self._aero_wrench(wind)
        keep = np.zeros(self.num_envs, dtype=bool)
        keep[rows] = True
        self._force = np.where(keep[:, None], force, self._force)
        self._torque = np.where(keep[:, None], torque, self._torque)
        self._wind_com = np.where(keep[:, None], wind[:, 0], self._wind_com)

    def _measure_restarted(self, rows: NDArray[np.intp], rngs: list[np.random.Generator],
                           measurement: Mapping[str, NDArray[np.float64]]) -> dict[str, NDArray[np.float64]]:
        """``measurement`` with the first samples of the restarted ``rows`` (module docstring: their own noise)."""
        state = (self.time, self._pos, self._vel, self._rot, self._omega, self._accel)
        if not self.sensor.noisy:  # exact sensors have no state: every row measured as in a full step
            return self.sensor.measure(*state)
        fresh = self.sensor.measure_rows(rows, rngs, *(x[rows] for x in state))
        out = {}
        for key, value in measurement.items():
            out[key] = value.copy()
            out[key][rows] = fresh[key]
        return out

    def _rollout_rows(self, state: NDArray[np.float64], ctrl: NDArray[np.float64], out: NDArray[np.float64]
                      ) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
        """One rollout from ``state`` (N, 14) with controls ``ctrl`` (N, nstep, 10) into ``out`` (N, nstep, 14)
        (all C-contiguous float64: the checks are skipped); returns (final states, diverged rows)."""
        nstep = ctrl.shape[1]
        state[:, 0] = _MJ_T0
        self._rollout.rollout(self._models, [self._data], state, ctrl, control_spec=_CONTROL_SPEC,
                              skip_checks=True, nstep=nstep, state=out)
        final = out[:, -1]
        t_end = _MJ_T0 + nstep * self.physics_dt
        diverged = (np.abs(final[:, 0] - t_end) > 0.5 * self.physics_dt) | ~np.isfinite(final).all(axis=1)
        return final, diverged

    def _held_wrench(self, ctrl: NDArray[np.float64]) -> None:
        """The disturbance force (world) and torque (body), held: the free joint's qfrc_applied (envs/mjcf.py)."""
        c = self._qfrc_col
        ctrl[:, :, c:c + 3] = ((self._force + self.external_force) * _SIGN)[:, None, :]
        ctrl[:, :, c + 3:c + 6] = ((self._torque + self.external_torque) * _SIGN)[:, None, :]

    def _run_motors(self, u: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
        """HoverEnv._run_motors for every row: exact lag, mid-substep thrusts, one rollout of the control step."""
        ref = u * self._omega_span + self._omega_min
        speeds, self._applied = np.empty(ref.shape), np.empty(ref.shape)
        lag_thrusts(ref, self.rotor_speeds, self._decay_up, self._decay_down, self.preset.k_thrust, self._ctrl,
                    speeds, self._applied)
        self._held_wrench(self._ctrl)
        final, diverged = self._rollout_rows(self._mj_state, self._ctrl, self._out)
        self.rotor_speeds = speeds
        return final, diverged

    def _run_ctbr(self, a: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
        """HoverEnv._run_ctbr for every row: the rate loop on the true rates at each substep, one rollout each."""
        k_t = self.preset.k_thrust
        collective = a[:, 0] * self._max_thrust
        rate_sp = a[:, 1:] * MAX_RATES
        self._held_wrench(self._ctrl1)
        state = self._mj_state.copy()
        total = np.zeros((self.num_envs, 4))
        diverged = np.zeros(self.num_envs, dtype=bool)
        speeds = self.rotor_speeds
        for _ in range(self.n_substeps):  # substeps (the rate loop closes the loop at the physics rate)
            t_cmd = self._rate_loop.rotor_thrusts(collective, rate_sp, state[:, 11:14] * _SIGN)
            ref = np.sqrt(t_cmd / k_t)
            end, thrust = np.empty(ref.shape), np.empty(ref.shape)
            lag_thrusts(ref, speeds, self._sub_decay_up, self._sub_decay_down, k_t, self._ctrl1, end, thrust)
            final, bad = self._rollout_rows(state, self._ctrl1, self._out1)
            diverged |= bad
            state = final.copy()
            speeds = end
            total += thrust
        self.rotor_speeds = speeds.copy()
        self._applied = total / self.n_substeps
        return state, diverged

    def _wind_points(self) -> NDArray[np.float64]:
        """The wind sample points (N, 5, 3) NED: CoM and rotor hubs."""
        b, r = self._pos, self._rot
        points = np.empty((self.num_envs, 5, 3))
        points[:, 0] = b
        points[:, 1:] = b[:, None, :] + np.matmul(self._rotor_pos_t.T, r.transpose(0, 2, 1))
        return points

    def _aero_wrench(self, wind: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """The aero wrench of every row in ``wind`` (N, 5, 3), scaled by the rows' drag draws (if any)."""
        force, torque = self.aero.wrench(self._rot, self._vel, self._omega, self.rotor_speeds, wind)
        if self._drag_scaled:  # the wrench is linear in the three drag coefficients (module docstring)
            force, torque = force * self.drag_scale[:, None], torque * self.drag_scale[:, None]
        return force, torque

    def _update_disturbance(self, rows: NDArray[np.bool_]) -> None:
        """Wind at [CoM, hubs] and the aero wrench for the next step (rows not diverged); the external wrench is
        added where the wrench is applied and reported, so a new one acts from the next step on."""
        points = self._wind_points()
        wind = self.wind.step(self.time, self.dt, points, self._vel)
        force, torque = self._aero_wrench(wind)
        if rows.all():
            self._force, self._torque, self._wind_com = force, torque, wind[:, 0].copy()
        else:
            self._force = np.where(rows[:, None], force, self._force)
            self._torque = np.where(rows[:, None], torque, self._torque)
            self._wind_com = np.where(rows[:, None], wind[:, 0], self._wind_com)

    def _info(self, action_clipped: NDArray[np.bool_],
              meas: dict[str, NDArray[np.float64]] | None = None) -> dict[str, Any]:
        if meas is None:
            meas = self.sensor.measure(self.time, self._pos, self._vel, self._rot, self._omega, self._accel)
        f_torque = self._applied @ self._alloc_t
        return {
            "measurement": meas,
            "applied": {"thrust": f_torque[:, 0].copy(), "torque": f_torque[:, 1:].copy(),
                        "rotor_thrusts": self._applied.copy(), "motor_speeds": self.rotor_speeds.copy()},
            "truth": {M.POSITION: self._pos.copy(), M.VELOCITY: self._vel.copy(), M.ATTITUDE: self._rot.copy(),
                      M.ANGULAR_VELOCITY: self._omega.copy(), "wind": self._wind_com.copy(),
                      "force": self._force + self.external_force, "torque": self._torque + self.external_torque},
            "setpoint": self.setpoint.copy(),
            "action_clipped": action_clipped,
            "failure": self._failure.copy(),
            "time": self.time.copy(),
        }

    def _observation_and_reward(self, meas: Mapping[str, NDArray[np.float64]], action: NDArray[np.float64],
                                prev_action: NDArray[np.float64] | None = None
                                ) -> tuple[NDArray[np.float32], NDArray[np.float64]]:
        """Observations (N, 19), rewards (N,) and the reward's terms (dict of (N,)) (HoverEnv's layout and formula,
        row by row; the terms are its module docstring's table)."""
        r = meas[M.ATTITUDE]
        obs = hover_observation(meas, self.setpoint, action, self._obs_low, self._obs_high)
        x = np.concatenate([meas[M.POSITION] - self.setpoint, meas[M.VELOCITY], r[:, :, 0], r[:, :, 1],
                            meas[M.ANGULAR_VELOCITY], action], axis=1)
        cos = np.clip(0.5 * (r[:, 0, 0] + r[:, 1, 1] + r[:, 2, 2] - 1.0), -1.0, 1.0)
        phi = np.arccos(cos)
        x[:, 15:] -= self._last_action if prev_action is None else prev_action
        sq = x * x * self._reward_w
        w = self.reward_weights
        failed = self._failure != ""
        terms = {"pos": sq[:, 0:3].sum(axis=1), "vel": sq[:, 3:6].sum(axis=1), "att": w["att"] * phi * phi,
                 "rate": sq[:, 12:15].sum(axis=1), "action": sq[:, 15:19].sum(axis=1),
                 "failure": np.where(failed, w["failure"], 0.0)}
        reward = np.exp(-(terms["pos"] + terms["vel"] + terms["rate"] + terms["action"] + terms["att"]))
        if failed.any():
            reward[failed] = -w["failure"]
        return obs, reward, terms

    def close_extras(self, **kwargs: Any) -> None:
        if getattr(self, "_rollout", None) is not None:
            self._rollout.close()
            self._rollout = None
