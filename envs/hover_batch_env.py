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

This is the env's one step law: :class:`fawtgym.envs.hover_env.HoverEnv` is this env at N = 1 with
Gymnasium's single-env API.  Per vehicle (row) the semantics are HoverEnv's (read its module docstring):
the same options and their validation (:mod:`fawtgym.envs.options`, shared), action checking and
clipping, wind at [CoM, rotor hubs 1-4] held with the aero wrench (plus a per-row external wrench)
over the control step, exact first-order motor lag (mid-substep thrust, end-of-step speed), 19-D
observation from measurements, the same dense reward, termination (ground contact, box,
divergence) and truncation.  What is batched:

* physics: one ``mujoco.rollout`` call per control step on the env's own one-vehicle model, on the
  calling thread below :data:`THREADED_ROWS` rows, else on one thread per core, each with its own ``MjData``
  (:func:`default_physics_threads`): state spec ``mjSTATE_FULLPHYSICS`` (time, qpos,
  qvel; 14 numbers, round-trips this model's state exactly: no actuator activations, contacts
  disabled so no warm start matters), control spec ``mjSTATE_CTRL | mjSTATE_QFRC_APPLIED`` with the
  whole (N, n_substeps, 10) array (rotor thrusts per substep, held world force and body torque as the
  free joint's generalized force, see :mod:`fawtgym.envs.mjcf`);
* motor lag, rollout controls, state readout, divergence and termination, sensors
  (:func:`fawtgym.envs.sensors_batch.measure_rows`), observation (:func:`fawtgym.envs.observation.observation_rows`),
  reward, aero and the info numbers: compiled row kernels (numba), the same code at N = 1 and N = 1024, composed
  into three calls per control step (:mod:`fawtgym.envs.step_kernels`: ``act_rows`` before the rollout, ``step_rows``
  after it, ``disturbance_rows`` after the wind); wind (:mod:`fawtgym.envs.wind_cohorts`): batch-first over the
  leading axis N.

Pickling and ``copy.deepcopy`` copy the whole state (models, data, generators); the rollout's thread pool is
rebuilt on load.  ``setpoint`` is a checked property ((3,) or (N, 3), above the floor); ``reset`` checks
every option before it applies any (a failed reset changes nothing).

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
  the row's own generator *is* the stream).  So with exact sensors (any wind: each row's wind comes
  from its own seed, see Wind), or at N = 1, every episode (length, rewards, observations, terminal
  observation) equals the next-step mode's; with sensor noise at N > 1 the episodes are draws of the
  same distributions from other samples of the shared noise stream.

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
is stepped once for all N rows; a row that resets restarts its own gust field.  Any other model (a fan
schedule, ``gust-1cos``, a user class) is run in cohorts: rows that reset at the same step share one
copy of the model, stepped with their episode time as each single env would; cost grows with the number
of distinct reset times alive.  Either way every row's gust field (FAWT, Dryden: initial state and noise)
comes from that row's own wind seed, so a row's wind is the one the single env gets with the row's seed,
whatever the other rows do (a user model in a cohort of several rows gets one seed pooled from theirs;
:mod:`fawtgym.envs.wind_cohorts`, ``tests/test_wind_row_independence.py``).

``info`` holds batched arrays with HoverEnv's keys: ``measurement``/``applied``/``truth`` dicts of
(N, ...) arrays, ``reward_terms`` (a dict of (N,) arrays: the reward's terms, HoverEnv's table),
``setpoint`` (N, 3), ``action_clipped`` (N,), ``failure`` (N,) str, ``time`` (N,).  A row that
autoresets in the next-step mode reports reward 0 and all terms 0 on its reset step.  The float arrays are
C-contiguous views of one float64 buffer filled by the step's kernels and allocated afresh every step
(:data:`fawtgym.envs.step_kernels.INFO_FIELDS`), so nothing handed out is written by a later step;
:class:`HoverEnv` gets the same numbers as row views and Python scalars (:func:`~fawtgym.envs.step_kernels.info_views`).

``action_type="ctbr"``: the inner rate loop (:mod:`fawtgym.envs.ctbr`) runs at the physics rate on the
true body rates, so the physics is one single-substep rollout per substep (``n_substeps`` calls per
control step), with :class:`fawtgym.envs.ctbr.RateLoop` (batch-first) in between.

Not implemented: rendering (render a single ``fawtgym/Hover-v0``).
"""

from __future__ import annotations

import copy
import os
from collections.abc import Callable, Mapping, Sequence
from concurrent.futures import Future, ThreadPoolExecutor
from types import MappingProxyType
from typing import Any

import mujoco
import numpy as np
from gymnasium import spaces
from gymnasium.utils import seeding
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space
from mujoco import rollout
from numpy.typing import ArrayLike, NDArray

from fawtgym.core import measurement as M
from fawtgym.core.arrays import REAL_KINDS, ReadOnlyState, as_array, as_f64, read_only
from fawtgym.core.checks import check_flag, check_known, keyword_names, listed, shown
from fawtgym.core.frames import SIGN_MJ_NED, rot_ned_to_quat_mj
from fawtgym.core.so3 import exp_so3

from .aero import AeroModel
from .ctbr import MAX_RATES, RateLoop
from .mjcf import hull_points, vehicle_mjcf
from .motors import allocation_matrix, decay_factors, substep_times
from .mujoco_timers import timers_off, timers_on
from .observation import OBS_SIZE, hover_observation, observation_bounds
from .options import (
    INIT_SPREAD,
    check_actions,
    check_external_wrench,
    check_init_noise,
    check_max_position_error,
    check_reset_options,
    check_setpoint,
    hover_action,
    hover_action_space,
    hover_mass_scales,
    hover_options,
    raise_action_not_finite,
)
from .sensors_batch import SENSOR_NOT_FINITE, BatchSensorModel
from .step_kernels import (
    DIVERGED,
    FAILURES,
    INFO_START,
    INFO_WIDTH,
    REWARD_TERMS,
    STEP_PARAM_START,
    act_rows,
    ctbr_substep,
    disturbance_rows,
    info_views,
    observe_rows,
    states_to_ned,
    step_params,
    step_rows,
    wind_points,
)
from .wind import WindModel
from .wind_cohorts import BatchWind

_MJ_T0 = 1.0  #: MuJoCo time at the start of every rollout (a MuJoCo reset sets it to 0: divergence test)
_STATE_SPEC = int(mujoco.mjtState.mjSTATE_FULLPHYSICS)
_CONTROL_SPEC = int(mujoco.mjtState.mjSTATE_CTRL | mujoco.mjtState.mjSTATE_QFRC_APPLIED)
_SIGN = SIGN_MJ_NED
#: the error of assigning kernel state (the compiled kernels read and write it by index: a wrong shape corrupts memory)
_KERNEL_STATE = "HoverBatchEnv.{name} is kernel state (read-only): "
_USE_RANDOMIZER = ("set {name} per row with a randomizer (HoverBatchEnv(..., randomizer=...)), applied at each episode "
                   "start")
#: the autoreset modes of HoverBatchEnv (module docstring)
AUTORESET_MODES = {"next_step": AutoresetMode.NEXT_STEP, "same_step": AutoresetMode.SAME_STEP}
#: what a randomizer's draws may set, one value per starting row (module docstring)
RANDOMIZER_KEYS = ("mass_scale", "inertia_scale", "drag_scale", "gyro_bias", "accel_bias", "wind")
#: the failure names by code as Python str (the single env's ``info["failure"]``)
_FAILURE_NAMES = tuple(FAILURES.tolist())
#: below this many rows the rollout runs on the calling thread (a thread hand-off costs more than it saves)
THREADED_ROWS = 64
#: rows per task of the threaded rollout: the threads take tasks from one queue, so a thread that other load slows
#: down (a busy sibling vCPU, another process) does fewer; one task per thread waits for the slowest thread.
#: Measured at N = 1024 on a 2-vCPU VM: median step 5.6-6.0 ms in tasks of 64 rows, 5.4-8.0 ms in one per thread.
PHYSICS_CHUNK_ROWS = 64


def usable_cores() -> int:
    """The cores this process may use (its CPU affinity where the OS has one)."""
    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)


def default_physics_threads(n: int) -> int:
    """Threads of the env's ``mujoco.rollout`` for ``n`` rows, each with its own ``MjData``: one per core this
    process may use (at most one per :data:`THREADED_ROWS` rows), or 0 (the calling thread) if that is one."""
    threads = min(usable_cores(), n // THREADED_ROWS)
    return threads if threads > 1 else 0


#: the most rollout threads ``HoverBatchEnv(physics_threads=...)`` takes
MAX_PHYSICS_THREADS = 256
#: the most rows a HoverBatchEnv takes
MAX_NUM_ENVS = 10**6
#: what step() and reset() of a closed env raise
CLOSED = "the env was closed: step(), reset() and render() need a new env"


def _check_physics_threads(threads: Any) -> int | None:
    """The ``physics_threads`` option: None (:func:`default_physics_threads`: one per core) or an int in
    [0, :data:`MAX_PHYSICS_THREADS`]."""
    if threads is None or (isinstance(threads, (int, np.integer)) and not isinstance(threads, (bool, np.bool_))
                           and 0 <= threads <= MAX_PHYSICS_THREADS):
        return None if threads is None else int(threads)
    raise ValueError(f"physics_threads must be None (one per core) or an int in [0, {MAX_PHYSICS_THREADS}] "
                     f"(0: on the calling thread), got {shown(threads)}")


def _check_seeds(seed: Any, n: int) -> list[int | None]:
    """``reset``'s ``seed``: None, an int >= 0 (row i gets seed + i) or a list of n ints >= 0 / None."""
    def ok(x: Any) -> bool:
        return isinstance(x, (int, np.integer)) and not isinstance(x, (bool, np.bool_)) and bool(x >= 0)

    if seed is None:
        return [None] * n
    if ok(seed):
        return [int(seed) + i for i in range(n)]
    if isinstance(seed, Sequence) and not isinstance(seed, str) and len(seed) == n and all(
            x is None or ok(x) for x in seed):
        return [None if x is None else int(x) for x in seed]
    raise ValueError(f"seed must be None, an int >= 0 or a list of {n} ints >= 0 / None (one per row), "
                     f"got {shown(seed)}")


def _with_masks(info: Mapping[str, Any], mask: NDArray[np.bool_]) -> dict[str, Any]:
    """``info`` with a ``"_<key>"`` mask beside every key at every level (gymnasium's vector-info format)."""
    out: dict[str, Any] = {}
    for key, value in info.items():
        out[key] = _with_masks(value, mask) if isinstance(value, Mapping) else value
        out[f"_{key}"] = mask
    return out




class HoverBatchEnv(VectorEnv):
    """N hover vehicles stepped together; per-row semantics of :class:`HoverEnv` (module docstring).

    Args:
        num_envs: number of vehicles N.
        **options: the options of :class:`HoverEnv` (vehicle, wind, action_type, sensors, control_rate,
            physics_rate, episode_seconds, setpoint, init_noise, reward_weights, max_position_error,
            integrator); ``render_mode`` must be None.
        autoreset_mode: ``"next_step"`` (default) or ``"same_step"`` (or the ``AutoresetMode``); module docstring.
        randomizer: None, or a callable ``(rows, rngs) -> draws`` run at every episode start (module docstring).
        physics_threads: threads of the env's ``mujoco.rollout``, each with its own ``MjData``: None (default) for
            :func:`default_physics_threads` (one per core from :data:`THREADED_ROWS` rows on), 0 for the calling
            thread.  0 lets one thread per core each fly its own env of N / cores rows with its own agent (the
            ``sharded`` loop of ``fawtgym bench closed-loop``: the fastest closed loop on a 2-core machine).
        mujoco_timers: False (default): the env's physics runs with MuJoCo's profiler timers off (a quarter of
            ``mj_step`` on the s500; the same physics bit for bit; :mod:`fawtgym.envs.mujoco_timers`); True: with
            them, as the Python bindings set them up.  The switch is one process global: code that reads
            ``mjData.timer`` of MuJoCo it steps on other threads while envs step builds every env with True.
        max_episode_steps: None, or truncate episodes after at most this many control steps (the shorter of it and
            ``episode_seconds``): what ``gym.make_vec`` hands a vector entry point for a spec with a time limit,
            as the ``TimeLimit`` wrapper does for the single env.
    """

    metadata = {"autoreset_mode": AutoresetMode.NEXT_STEP, "render_modes": []}

    def __init__(self, num_envs: int = 1, vehicle: Any = "s500", wind: Any = "calm", action_type: str = "motors",
                 sensors: Any = "none", control_rate: float = 100.0, physics_rate: float = 1000.0,
                 episode_seconds: float = 10.0, setpoint: ArrayLike | None = None, init_noise: float = 1.0,
                 reward_weights: Mapping[str, float] | None = None, max_position_error: float = 2.0,
                 integrator: str = "Euler", render_mode: str | None = None, render_width: int = 480,
                 render_height: int = 480, autoreset_mode: str | AutoresetMode = "next_step",
                 randomizer: Callable[[NDArray[np.intp], list[np.random.Generator]], Mapping[str, Any]] | None = None,
                 physics_threads: int | None = None, mujoco_timers: bool = False,
                 max_episode_steps: int | None = None, **unknown: Any) -> None:
        if unknown:  # a one-line ValueError, as for every option (Python's TypeError is re-worded by gym.make)
            check_known(unknown, keyword_names(HoverBatchEnv), "HoverBatchEnv")
        if (isinstance(num_envs, bool) or not isinstance(num_envs, (int, np.integer))
                or not 1 <= num_envs <= MAX_NUM_ENVS):
            raise ValueError(f"num_envs must be an int in [1, {MAX_NUM_ENVS}], got {shown(num_envs)}")
        modes: dict[str | AutoresetMode, AutoresetMode] = {k: v for k, v in AUTORESET_MODES.items()}
        modes.update({m: m for m in AUTORESET_MODES.values()})
        if not isinstance(autoreset_mode, (str, AutoresetMode)) or autoreset_mode not in modes:
            raise ValueError(f"autoreset_mode must be one of {list(AUTORESET_MODES)}, got {shown(autoreset_mode)}")
        if randomizer is not None and not callable(randomizer):
            raise ValueError(f"randomizer must be None or a callable (rows, rngs) -> draws, got "
                             f"{type(randomizer).__name__}")
        threads = _check_physics_threads(physics_threads)
        self._timers = check_flag(mujoco_timers, "mujoco_timers")
        if render_mode is not None:
            raise ValueError(f"HoverBatchEnv does not render; render_mode must be None, got {shown(render_mode)} "
                             "(render a single fawtgym/Hover-v0 instead)")
        opts = hover_options(vehicle=vehicle, wind=wind, action_type=action_type, sensors=sensors,
                             control_rate=control_rate, physics_rate=physics_rate, episode_seconds=episode_seconds,
                             setpoint=setpoint, init_noise=init_noise, reward_weights=reward_weights,
                             max_position_error=max_position_error, integrator=integrator,
                             render_width=render_width, render_height=render_height)
        self.options = opts
        n = self.num_envs = int(num_envs)
        self.autoreset_mode = modes[autoreset_mode]
        self._same_step = self.autoreset_mode is AutoresetMode.SAME_STEP
        self._autoreset_on = True  # HoverEnv (a batch of one, Gymnasium's single-env API) turns it off
        self.metadata = {**type(self).metadata, "autoreset_mode": self.autoreset_mode}
        self.randomizer = randomizer
        self.preset = opts.preset
        self.action_type = opts.action_type
        self.n_substeps, self.physics_dt, self.dt = opts.n_substeps, opts.physics_dt, opts.dt
        self.episode_seconds = opts.episode_seconds
        self._init_noise = opts.init_noise
        self._reward_weights = dict(opts.reward_weights)
        w = self._reward_weights
        self._reward_w = np.array([w[key] for key in REWARD_TERMS])
        self.single_action_space = hover_action_space(opts.action_type)
        low, high = observation_bounds(opts.max_position_error, self.single_action_space.low,
                                       self.single_action_space.high)
        self.single_observation_space = spaces.Box(low, high, dtype=np.float32)
        self.action_space = batch_space(self.single_action_space, n)
        self.observation_space = batch_space(self.single_observation_space, n)
        self.render_mode = None
        self._setpoint = np.tile(opts.setpoint, (n, 1))
        self.model = mujoco.MjModel.from_xml_string(vehicle_mjcf(opts.preset, opts.physics_dt, opts.integrator,
                                                                 opts.render_width, opts.render_height))
        self._nthread = default_physics_threads(n) if threads is None else threads
        self._datas = [mujoco.MjData(self.model) for _ in range(max(self._nthread, 1))]
        self._data = self._datas[0]
        self._rollout = rollout.Rollout(nthread=self._nthread)
        self._worker: ThreadPoolExecutor | None = None  # step_async's thread (made on its first call)
        self._pending: Future[Any] | None = None  # the step started by step_async, until step_wait
        self._chunk = min(PHYSICS_CHUNK_ROWS, -(-n // self._nthread)) if self._nthread else None
        self._models = [self.model] * n  # one per row: a row with a randomized vehicle gets its own copy
        self._body = self.model.body("vehicle").id
        self._nominal_mass = float(self.model.body_mass[self._body])
        self._nominal_inertia = self.model.body_inertia[self._body].copy()
        self._mass_scale, self._inertia_scale, self._drag_scale = np.ones(n), np.ones(n), np.ones(n)
        self._qfrc_col = self.model.nu  # qfrc_applied follows ctrl in the control vector
        self.wind = BatchWind(opts.wind, n)
        self.aero = AeroModel(opts.preset)
        self.sensor = BatchSensorModel(opts.sensors, self.dt, n, self.physics_dt)

        p = self.preset
        self._hull = np.ascontiguousarray(hull_points(p))
        self._alloc_t = np.ascontiguousarray(allocation_matrix(p).T)
        self._rotor_pos = np.ascontiguousarray(p.rotor_positions)
        self._hover = hover_action(p, self.action_type)
        self._rate_loop = RateLoop(p, self.physics_dt, n) if action_type == "ctbr" else None
        self._sub_decay_up, self._sub_decay_down = decay_factors(p, substep_times(self.physics_dt, 1))
        self._max_thrust = 4.0 * p.max_thrust_per_rotor
        self._act_low = self.single_action_space.low.astype(float)
        self._act_high = self.single_action_space.high.astype(float)
        self._obs_low = self.single_observation_space.low.astype(float)
        self._obs_high = self.single_observation_space.high.astype(float)
        k = self.n_substeps
        self._decay_up, self._decay_down = decay_factors(p, substep_times(self.dt, k))  # (K + 1,): motors.lag_thrusts
        self._omega_min, self._omega_span = float(p.omega_min), float(p.omega_max - p.omega_min)
        self._k_thrust = float(p.k_thrust)
        if self._qfrc_col != 4:  # motor_controls writes [4 rotor thrusts, qfrc_applied 6]
            raise RuntimeError(f"the vehicle model must have 4 actuators, got {self._qfrc_col}")
        self._ctrl = np.zeros((n, k, mujoco.mj_stateSize(self.model, _CONTROL_SPEC)))
        self._mj_state = np.zeros((n, mujoco.mj_stateSize(self.model, _STATE_SPEC)))
        self._out = np.zeros((n, k, self._mj_state.shape[1]))
        self._out1 = np.zeros((n, 1, mujoco.mj_stateSize(self.model, _STATE_SPEC)))  # ctbr: one substep
        self._ctrl1 = np.zeros((n, 1, self._ctrl.shape[2]))
        #: per row the held disturbance: aero force NED 0-2, aero torque FRD 3-5, the CoM wind 6-8 (held over the
        #: next step), and the external force 9-11 / torque 12-14 (:meth:`set_external_wrench`); one array, the
        #: step kernels' one argument (the properties ``_force``, ``external_force``, ... are views of it)
        self._wrench = np.zeros((n, 15))
        self._row_rngs: list[np.random.Generator] | None = None
        self._autoreset = np.zeros(n, dtype=bool)
        self._n_autoreset = 0  # rows of _autoreset set
        self._no_rows, self._all_rows = np.zeros(n, dtype=bool), np.ones(n, dtype=bool)
        self._failure_code = np.zeros(n, dtype=np.int8)
        self._no_failure = np.full(n, "", dtype="<U14")
        self._t_end = _MJ_T0 + self.n_substeps * self.physics_dt  # MuJoCo time after a control step's rollout
        self._time = np.zeros(n)
        sensor, aero = self.sensor, self.aero
        self._params = step_params(  # the constants of the step kernels, one array
            t0=_MJ_T0, t_end=self._t_end if self._rate_loop is None else _MJ_T0 + self.physics_dt,  # ctbr: 1 substep
            physics_dt=self.physics_dt, dt=self.dt, max_position_error=opts.max_position_error,
            max_steps=opts.max_steps, pose_every=sensor.pose_every if sensor.noisy else 1, sigma=sensor.sigma,
            field=M.EARTH_FIELD_NED, act_low=self._act_low, act_high=self._act_high, hover=self._hover,
            omega_min=self._omega_min, omega_span=self._omega_span, k_thrust=self._k_thrust, obs_low=self._obs_low,
            obs_high=self._obs_high, reward_weights=self._reward_w, alloc_t=self._alloc_t, rotor_pos=self._rotor_pos,
            hull=self._hull, cop=aero.cop, body_drag=aero.body_drag, k_d=aero.k_d, k_r=aero.k_r)
        self._link_aero()
        if max_episode_steps is not None:  # the setter checks it
            self.max_steps = max_episode_steps
            self.max_steps = min(self.max_steps, opts.max_steps)

    def _link_aero(self) -> None:
        """Make the aero model's coefficients a view of the step parameters (cop, body_drag, k_d, k_r, in
        :class:`AeroModel`'s order), so an assignment to ``env.aero.k_d`` etc. acts from the next step on."""
        start = STEP_PARAM_START["cop"]
        assert STEP_PARAM_START["k_r"] == start + 7  # cop 3, body_drag 3, k_d, k_r: AeroModel.coefficients' layout
        self._params[start:start + 8] = self.aero.coefficients
        self.aero._share(self._params[start:start + 8])

    # ---- kernel state, read-only (the compiled kernels trust these arrays' shapes: never assigned from outside) ----
    rotor_speeds = ReadOnlyState("Rotor speeds [rad/s] at the end of the last step (N, 4): a read-only view.",
                                 _KERNEL_STATE + "they follow the actions (step) and reset")
    time = ReadOnlyState("Episode time of each row [s] (N,): a read-only view.",
                         _KERNEL_STATE + "it advances with step and restarts at reset")
    mass_scale = ReadOnlyState("Each row's body mass over the nominal one (N,) (module docstring, Domain "
                               "randomization): a read-only view.", _KERNEL_STATE + _USE_RANDOMIZER)
    inertia_scale = ReadOnlyState("Each row's body inertia over the nominal one (N,) (module docstring, Domain "
                                  "randomization): a read-only view.", _KERNEL_STATE + _USE_RANDOMIZER)
    drag_scale = ReadOnlyState("Each row's aerodynamic wrench scale (N,) (module docstring, Domain randomization): a "
                               "read-only view.", _KERNEL_STATE + _USE_RANDOMIZER)

    @property
    def _force(self) -> NDArray[np.float64]:
        """The held aero force (N, 3) world NED [N] (a view of ``_wrench``)."""
        return self._wrench[:, 0:3]

    @property
    def _torque(self) -> NDArray[np.float64]:
        """The held aero torque (N, 3) body FRD [N m] (a view of ``_wrench``)."""
        return self._wrench[:, 3:6]

    @property
    def _wind_com(self) -> NDArray[np.float64]:
        """The wind at the CoM (N, 3) NED [m/s] of the held disturbance (a view of ``_wrench``)."""
        return self._wrench[:, 6:9]

    @property
    def external_force(self) -> NDArray[np.float64]:
        """The constant external force (N, 3) world NED [N] (a read-only view; assign it or call
        :meth:`set_external_wrench`)."""
        return read_only(self._wrench[:, 9:12])

    @external_force.setter
    def external_force(self, value: ArrayLike) -> None:
        self.set_external_wrench(value, self.external_torque.copy())

    @property
    def external_torque(self) -> NDArray[np.float64]:
        """The constant external torque (N, 3) body FRD [N m] (a read-only view; assign it or call
        :meth:`set_external_wrench`)."""
        return read_only(self._wrench[:, 12:15])

    @external_torque.setter
    def external_torque(self, value: ArrayLike) -> None:
        self.set_external_wrench(self.external_force.copy(), value)

    @property
    def max_steps(self) -> int:
        """Steps per episode before truncation (``episode_seconds / dt`` at construction); assign an int >= 1 (from
        the next step; ``episode_seconds`` keeps the constructed value, as in :attr:`options`)."""
        return int(self._params[STEP_PARAM_START["max_steps"]])

    @max_steps.setter
    def max_steps(self, value: Any) -> None:
        self._check_idle("setting max_steps")
        if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)) or value < 1 \
                or value > 2**52:
            raise ValueError(f"max_steps must be an int in [1, 2**52] (exact as a float64), got {shown(value)}")
        self._params[STEP_PARAM_START["max_steps"]] = int(value)

    @property
    def reward_weights(self) -> Mapping[str, float]:
        """The reward's weights (a read-only mapping, fixed at construction: the step kernels hold a copy; pass
        ``reward_weights=`` to the constructor to change them)."""
        return MappingProxyType(self._reward_weights)

    @reward_weights.setter
    def reward_weights(self, value: object) -> None:
        raise AttributeError("reward_weights is fixed at construction (the step kernels hold a copy): pass "
                             "reward_weights={...} to the constructor instead")

    @property
    def init_noise(self) -> float:
        """Scale of the random initial perturbation (:data:`INIT_SPREAD` at 1; 0: start exactly hovering at the set
        point); assign a finite number >= 0 (checked; from the next reset on)."""
        return self._init_noise

    @init_noise.setter
    def init_noise(self, value: Any) -> None:
        self._check_idle("setting init_noise")
        self._init_noise = check_init_noise(value)

    @property
    def max_position_error(self) -> float:
        """Half-size of the termination box [m]; assign a finite positive number up to 1e9 (the box from the next
        step on; the observation bounds stay those of construction)."""
        return float(self._params[STEP_PARAM_START["max_position_error"]])

    @max_position_error.setter
    def max_position_error(self, value: Any) -> None:
        self._check_idle("setting max_position_error")
        self._params[STEP_PARAM_START["max_position_error"]] = check_max_position_error(value)

    # ---- public helpers -------------------------------------------------------------------
    def hover_action(self) -> NDArray[np.float32]:
        """(N, 4) actions holding the weight at rest."""
        return np.tile(self._hover, (self.num_envs, 1))

    @property
    def setpoint(self) -> NDArray[np.float64]:
        """Hover set points, world NED [m] (N, 3), a read-only view; assign (3,) or (N, 3) any time (validated, from
        the next step)."""
        return read_only(self._setpoint)

    @setpoint.setter
    def setpoint(self, value: ArrayLike) -> None:
        self._check_idle("setting setpoint")
        self._setpoint[...] = check_setpoint(value, self.num_envs)  # broadcast (3,) to every row

    def __getstate__(self) -> dict[str, Any]:
        """Pickle/deepcopy: MuJoCo's model and data are copied; the rollout (threads, not picklable) is rebuilt."""
        self._check_idle("pickling or copying the env")
        state = self.__dict__.copy()
        state["_rollout"] = state["_worker"] = None
        state["_closed"] = self._rollout is None  # a closed env's copy is closed too
        return state

    def __setstate__(self, state: dict[str, Any]) -> None:
        closed = state.pop("_closed", False)
        self.__dict__.update(state)
        self._rollout = None if closed else rollout.Rollout(nthread=self._nthread)
        self._link_aero()  # a copy's aero coefficients are a view of the copy's parameters again

    def set_external_wrench(self, force_ned: ArrayLike = (0.0, 0.0, 0.0),
                            torque_frd: ArrayLike = (0.0, 0.0, 0.0)) -> None:
        """Constant extra disturbance per row: force NED (3,) or (N, 3) [N], torque FRD (3,) or (N, 3) [N m] (finite
        real numbers, checked), from the next step on."""
        self._check_idle("set_external_wrench() called")
        f, t = check_external_wrench(force_ned, torque_frd, self.num_envs)
        self._wrench[:, 9:12], self._wrench[:, 12:15] = f, t

    # ---- state ------------------------------------------------------------------------------
    def _reset_rows(self, rows: NDArray[np.intp]) -> list[np.random.Generator]:
        """HoverEnv.reset for ``rows`` (each row draws from its own generator, in HoverEnv's order), then the
        randomizer's draws; returns the rows' sensor generators."""
        assert self._row_rngs is not None  # reset() made them
        return self._start_rows(rows, self._draw_rows(rows, self._row_rngs, self.init_noise))

    def _draw_rows(self, rows: NDArray[np.intp], row_rngs: list[np.random.Generator], init_noise: float
                   ) -> tuple[Any, ...]:
        """Everything a reset of ``rows`` draws, checked, with nothing of the env written (only the rows' generators
        ``row_rngs[row]`` advance): the initial perturbations, the wind and sensor seeds and the randomizer's
        checked draws (:meth:`_check_draws`); :meth:`_start_rows` applies them."""
        k = rows.size
        du = np.empty((k, 4, 3))
        ints: list[int] = []
        wind_seeds: list[np.random.SeedSequence] = []
        sensor_rngs: list[np.random.Generator] = []
        draw_rngs: list[np.random.Generator] = []
        spread = np.array([INIT_SPREAD[key] for key in ("position", "velocity", "attitude", "angular_velocity")])
        for j, row in enumerate(rows.tolist()):  # reset path only: per-row generators
            rng = row_rngs[row]
            for i in range(4):
                du[j, i] = rng.uniform(-1.0, 1.0, 3) * spread[i] * init_noise
            seed_int = int(rng.integers(2**63))
            # children 0, 1 as HoverEnv's spawn(2); child 2 (randomizer only) leaves them unchanged
            wind_seed, sensor_seed, *draw_seed = np.random.SeedSequence(seed_int).spawn(
                2 if self.randomizer is None else 3)
            ints.append(seed_int)
            wind_seeds.append(wind_seed)
            sensor_rngs.append(np.random.default_rng(sensor_seed))
            draw_rngs.extend(np.random.default_rng(d) for d in draw_seed)
        draws = None if self.randomizer is None else self._check_draws(rows, self.randomizer(rows, draw_rngs))
        return du, ints, wind_seeds, sensor_rngs, draws

    def _start_rows(self, rows: NDArray[np.intp], drawn: tuple[Any, ...]) -> list[np.random.Generator]:
        """Write the new episodes of ``rows`` from :meth:`_draw_rows`' ``drawn``; returns the rows' sensor
        generators."""
        du, ints, wind_seeds, sensor_rngs, draws = drawn
        k = rows.size
        s = np.zeros((k, self._mj_state.shape[1]))
        s[:, 0] = _MJ_T0  # MuJoCo time at the start of every rollout (module docstring: divergence test)
        s[:, 1:4] = (self._setpoint[rows] + du[:, 0]) * _SIGN
        s[:, 4:8] = rot_ned_to_quat_mj(exp_so3(du[:, 2]))
        s[:, 8:11] = du[:, 1] * _SIGN
        s[:, 11:14] = du[:, 3] * _SIGN
        self._mj_state[rows] = s
        b, v, r, w = np.empty((k, 3)), np.empty((k, 3)), np.empty((k, 3, 3)), np.empty((k, 3))
        states_to_ned(s, b, v, r, w)
        self._pos[rows], self._vel[rows], self._rot[rows], self._omega[rows] = b, v, r, w
        self._rotor_speeds[rows] = self.preset.hover_omega
        self._applied[rows] = self.preset.k_thrust * self.preset.hover_omega**2
        self._last_action[rows] = self._hover
        self._accel[rows] = 0.0
        self._steps[rows] = 0
        self._time[rows] = 0.0
        self._failure_code[rows] = 0
        self.sensor.reset_rows(rows, sensor_rngs)
        winds = None
        if draws is not None:
            values, winds = draws
            self._apply_draws(rows, values)
        self.wind.reset_rows(rows, ints, wind_seeds, winds)
        if self._rate_loop is not None:
            self._rate_loop.reset(rows)
        if self.num_envs == 1:  # N = 1: the row's own sensor stream, as HoverEnv
            self.sensor.set_noise_rng(sensor_rngs[0])
        return sensor_rngs

    def _check_draws(self, rows: NDArray[np.intp], draws: Any
                     ) -> tuple[dict[str, NDArray[np.float64]], list[WindModel] | None]:
        """A randomizer's ``draws`` for ``rows`` checked (ValueError naming the key and what is allowed), nothing
        applied: the numeric draws as float64 arrays, and the rows' wind models (or None)."""
        k = rows.size
        if not isinstance(draws, Mapping):
            raise ValueError(f"randomizer must return a mapping of {list(RANDOMIZER_KEYS)}, got {type(draws).__name__}")
        unknown = set(draws) - set(RANDOMIZER_KEYS)
        if unknown:
            raise ValueError(f"randomizer draws {listed(unknown)} are unknown; valid: {list(RANDOMIZER_KEYS)}")
        values = {}
        for key, shape, need, ok in (("mass_scale", (k,), "> 0", np.greater),
                                     ("inertia_scale", (k,), "> 0", np.greater),
                                     ("drag_scale", (k,), ">= 0", np.greater_equal),
                                     ("gyro_bias", (k, 3), "finite", None), ("accel_bias", (k, 3), "finite", None)):
            if key in draws:
                raw = draws[key]
                v = as_array(raw)
                if v.dtype.kind not in REAL_KINDS:  # bool, complex, str, objects: no silent conversion
                    raise ValueError(f"randomizer draw {shown(key)} must be {need} with shape {shape} (one per "
                                     f"starting "
                                     f"row) of real numbers, got {raw!r:.80} ({type(raw).__name__}, dtype {v.dtype})")
                v = v.astype(np.float64)
                if v.shape != shape or not np.all(np.isfinite(v)) or (ok is not None and not np.all(ok(v, 0.0))):
                    raise ValueError(f"randomizer draw {shown(key)} must be {need} with shape {shape} (one per "
                                     f"starting row), got shape {v.shape}: {v.ravel()[:6].tolist()}")
                values[key] = v
        if "mass_scale" in values:  # the row must still hover: weight between the rotors' idle and maximum thrust
            lo, hi = hover_mass_scales(self.preset)
            bad = np.flatnonzero(~((values["mass_scale"] > lo) & (values["mass_scale"] < hi)))
            if bad.size:
                raise ValueError(f"randomizer draw 'mass_scale' must be in ({lo:.4g}, {hi:.4g}) for vehicle "
                                 f"{shown(self.preset.name)} to hover (weight between the rotors' idle and maximum "
                                 f"thrust), got {shown(values['mass_scale'][bad[0]])} for starting row {int(bad[0])}")
        if ("gyro_bias" in values or "accel_bias" in values) and not self.sensor.noisy:
            raise ValueError("randomizer draws IMU biases but the sensors are exact (sensors='none' has no biases); "
                             "use a noisy preset such as 'mocap_imu'")
        winds = draws.get("wind")
        if winds is not None and (not isinstance(winds, Sequence) or isinstance(winds, str) or len(winds) != k
                                  or not all(isinstance(w, WindModel) for w in winds)):
            raise ValueError(f"randomizer draw 'wind' must be a list of {k} WindModel (one per starting row), got "
                             f"{winds!r:.80} ({type(winds).__name__})")
        return values, None if winds is None else list(winds)

    def _apply_draws(self, rows: NDArray[np.intp], values: Mapping[str, NDArray[np.float64]]) -> None:
        """Apply a randomizer's checked numeric draws (:meth:`_check_draws`) to ``rows`` (module docstring)."""
        if "mass_scale" in values or "inertia_scale" in values:
            mass = values.get("mass_scale", self._mass_scale[rows])
            inertia = values.get("inertia_scale", self._inertia_scale[rows])
            self._mass_scale[rows], self._inertia_scale[rows] = mass, inertia
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
            self._drag_scale[rows] = values["drag_scale"]
        self.sensor.set_bias_rows(rows, values.get("gyro_bias"), values.get("accel_bias"))

    # ---- gym API -------------------------------------------------------------------------
    def reset(self, *, seed: int | Sequence[int | None] | None = None,
              options: dict[str, Any] | None = None) -> tuple[NDArray[np.float32], dict[str, Any]]:
        self._check_idle("reset() called")
        return self._reset(seed, options)

    def _reset(self, seed: int | Sequence[int | None] | None = None, options: dict[str, Any] | None = None,
               single: bool = False) -> tuple[NDArray[np.float32], dict[str, Any]]:
        """:meth:`reset`; ``single``: the info in the single env's form (:func:`info_views`)."""
        if self._rollout is None:
            raise RuntimeError(CLOSED)
        n = self.num_envs
        seeds = _check_seeds(seed, n)
        sp, noise = check_reset_options(options, n)  # checked before anything changes
        # a failed reset changes nothing: everything is drawn and checked (the randomizer's draws included) before
        # the env is written; the only thing drawing advances, the kept row generators, is restored on failure
        old = self._row_rngs
        if old is None or seed is not None:
            row_rngs = [seeding.np_random(s)[0] if (s is not None or old is None) else old[i]
                        for i, s in enumerate(seeds)]
        else:
            row_rngs = old
        old_ids = {id(g) for g in old or []}
        kept = [(g, g.bit_generator.state) for g in row_rngs if id(g) in old_ids]  # generators this reset keeps
        try:
            drawn = self._draw_rows(np.arange(n), row_rngs, self._init_noise if noise is None else noise)
        except BaseException:
            for g, state in kept:
                g.bit_generator.state = state
            raise
        self._row_rngs = row_rngs
        if seed is not None or not hasattr(self, "_noise_seeded"):
            ints = [int(x) for x in seeds if isinstance(x, (int, np.integer)) and not isinstance(x, bool)]
            entropy = None if len(ints) < n else [*ints, n, 0x5E45]  # reproducible iff every row has a seed
            self.sensor.set_noise_rng(np.random.default_rng(entropy))
            self._noise_seeded = True
        if sp is not None:
            self.setpoint = sp
        if noise is not None:
            self._init_noise = noise
        self._pos, self._vel = np.zeros((n, 3)), np.zeros((n, 3))
        self._rot, self._omega = np.zeros((n, 3, 3)), np.zeros((n, 3))
        self._rotor_speeds, self._applied = np.zeros((n, 4)), np.zeros((n, 4))
        self._last_action, self._accel = np.zeros((n, 4)), np.zeros((n, 3))
        self._steps = np.zeros(n, dtype=np.int64)
        self._wrench[:, :9] = 0.0  # the held aero wrench and wind (the external wrench is kept)
        self._autoreset = np.zeros(n, dtype=bool)
        self._n_autoreset = 0  # rows of _autoreset set
        self._start_rows(np.arange(n), drawn)
        buf = np.empty(n * INFO_WIDTH)
        self._update_disturbance(self._all_rows, buf)
        obs, _ = self._observe(buf, self.sensor.noise(), True, self._last_action, self._last_action)
        return obs, self._info(buf, np.zeros(n, dtype=bool), single)

    def step(self, actions: ArrayLike) -> tuple[NDArray[np.float32], NDArray[np.float64], NDArray[np.bool_],
                                                 NDArray[np.bool_], dict[str, Any]]:
        return self._step(self._checked_actions(actions, "step"))

    @property
    def mujoco_timers(self) -> bool:
        """Whether the env's physics runs with MuJoCo's profiler timers (the ``mujoco_timers`` option)."""
        return self._timers

    @property
    def physics_threads(self) -> int:
        """Threads of the env's ``mujoco.rollout`` (0: the calling thread); the ``physics_threads`` option, or
        :func:`default_physics_threads` of N."""
        return self._nthread

    def step_async(self, actions: ArrayLike) -> None:
        """:meth:`step` started on a worker thread; returns at once, :meth:`step_wait` returns the step's result.

        MuJoCo's rollout, most of a step at large N, runs without Python's GIL: meanwhile the calling thread can run
        an agent or step another env: two envs of N / 2 rows stepped in turn, each half's agent acting while the
        other half's physics runs (the pipelined loop of ``fawtgym bench closed-loop``; on a 2-core VM it measured
        only ~2 % faster than the plain loop at N = 1024, within the run-to-run noise: docs/performance.md).
        The actions' type and shape are checked here, and a
        non-finite entry by the step itself, raised by :meth:`step_wait` (the errors of :meth:`step`, before anything
        changes); until :meth:`step_wait`, ``step``, ``step_async``, ``reset``, copying and pickling raise
        RuntimeError (nothing else may touch the env meanwhile).  The results are :meth:`step`'s, bit for bit."""
        a = self._checked_actions(actions, "step_async")
        if self._worker is None:
            self._worker = ThreadPoolExecutor(1, thread_name_prefix="HoverBatchEnv.step_async")
        self._pending = self._worker.submit(self._step, a)

    def step_wait(self) -> tuple[NDArray[np.float32], NDArray[np.float64], NDArray[np.bool_], NDArray[np.bool_],
                                 dict[str, Any]]:
        """The result of the step :meth:`step_async` started (waits for it; its error, if it raised one)."""
        if self._pending is None:
            raise RuntimeError("HoverBatchEnv.step_wait() called with no step started: call step_async(actions) first")
        pending, self._pending = self._pending, None
        return pending.result()

    def _check_idle(self, what: str) -> None:
        if self._pending is not None:
            raise RuntimeError(f"HoverBatchEnv: {what} while a step_async() step is running: call step_wait() first")

    def _checked_actions(self, actions: ArrayLike, caller: str) -> NDArray[np.float64]:
        self._check_idle(f"{caller}() called")
        if self._row_rngs is None:
            raise RuntimeError(f"HoverBatchEnv.{caller}() called before reset(): call reset() first")
        return check_actions(actions, (self.num_envs, 4), self._act_low, self._act_high, "actions", finite=False)

    def _step(self, a: NDArray[np.float64], name: str = "actions", single: bool = False) -> tuple[
            NDArray[np.float32], NDArray[np.float64], NDArray[np.bool_], NDArray[np.bool_], dict[str, Any]]:
        """One control step of every row with actions ``a`` (N, 4) C-contiguous float64 of checked shape and type
        (:func:`check_actions` with ``finite=False``: a non-finite entry of a stepping row raises here, before
        anything changes, naming ``name[row, entry]``, or ``name[entry]`` if ``name`` is HoverEnv's ``"action"``);
        ``single``: the info in the single env's form (:func:`info_views`)."""
        if self._rollout is None:
            raise RuntimeError(CLOSED)
        n = self.num_envs
        resetting = self._autoreset
        any_reset = self._n_autoreset > 0
        stepping = ~resetting if any_reset else self._all_rows
        clipped, action_clipped = np.empty((n, 4)), np.empty(n, dtype=bool)
        motors = self._rate_loop is None
        bad = act_rows(a, self._params, stepping, motors, self._decay_up, self._decay_down, self._rotor_speeds,
                       self._wrench, clipped, action_clipped, self._ctrl, self._applied)
        if bad >= 0:
            row, entry = divmod(bad, 4)
            idx = (entry,) if name == "action" else (row, entry)
            raise_action_not_finite(a[0] if name == "action" else a, idx, name, self._act_low, self._act_high)
        if motors:
            states, diverged = self._rollout_rows(self._mj_state, self._ctrl, self._out), self._no_rows
        else:
            states, diverged = self._run_ctbr(clipped)
        flags = np.empty((2, n), dtype=bool)
        terminated, truncated = flags[0], flags[1]  # two (N,) views of one fresh array
        points = np.empty((n, 5, 3))
        buf = np.empty(n * INFO_WIDTH)  # the step's info numbers (fresh: handed out as views)
        obs, reward = np.empty((n, OBS_SIZE), dtype=np.float32), np.empty(n)
        prev = self._last_action
        s = self.sensor
        z = s.noise() if not any_reset else s._no_noise  # drawn after the restarts below if any row restarts
        n_ended, status = step_rows(self._params, states, stepping, diverged, self._mj_state, self._pos, self._vel,
                                    self._rot, self._omega, self._accel, self._setpoint, self._failure_code,
                                    self._time, self._steps, flags, points, not any_reset, z, s._count, s._state,
                                    clipped, prev, self._applied, self._rotor_speeds, buf, obs, reward)
        codes = self._failure_code
        self._last_action = clipped
        if any_reset:
            self._reset_rows(np.flatnonzero(resetting))
            obs, reward = self._observe(buf, s.noise(), True, clipped, prev)
        elif status >= 0:
            self._raise_observe(status, buf, clipped)
        # the wind sample points of step_rows, unless reset rows moved (then sampled anew)
        self._update_disturbance(codes != DIVERGED if n_ended else self._all_rows, buf, None if any_reset else points)
        if any_reset:  # a restarting row's step: reward 0, every term 0
            reward[resetting] = 0.0
            start = INFO_START["reward_terms", "pos"]
            buf[start * n:(start + 6) * n].reshape(6, n)[:, resetting] = 0.0
        info = self._info(buf, action_clipped, single, n_ended)
        if not self._autoreset_on:
            pass
        elif not self._same_step:
            self._autoreset, self._n_autoreset = terminated | truncated, n_ended
        elif n_ended:
            obs, info = self._restart(terminated | truncated, obs, info)
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
        buf = np.empty(n * INFO_WIDTH)
        if rows.size == n:  # every row restarts: the regular path (N = 1: exactly the next-step reset)
            self._update_disturbance(self._all_rows, buf)
            measure, z = True, self.sensor.noise()
        else:
            self._start_disturbance(rows, buf)
            measure, z = self._measure_restarted(rows, sensor_rngs, info["measurement"], buf)
        new_obs, _ = self._observe(buf, z, measure, self._last_action, self._last_action)
        new_info = self._info(buf, info["action_clipped"] & ~ended)
        new_info["final_obs"], new_info["_final_obs"] = final_obs, mask
        new_info["final_info"], new_info["_final_info"] = final_info, mask
        return new_obs, new_info

    def _start_disturbance(self, rows: NDArray[np.intp], buf: NDArray[np.float64]) -> None:
        """The held disturbance of restarted ``rows`` (their first wind sample), the other rows untouched; the aero
        wrench over all N rows (the arithmetic of a full step), kept for ``rows``; the truth's part into ``buf``."""
        points = self._wind_points()
        wind = np.zeros(points.shape)
        wind[rows] = self.wind.first_step(self.dt, points[rows], self._vel[rows])
        keep = np.zeros(self.num_envs, dtype=bool)
        keep[rows] = True
        self._disturbance(wind, keep, buf)

    def _measure_restarted(self, rows: NDArray[np.intp], rngs: list[np.random.Generator],
                           measurement: Mapping[str, NDArray[np.float64]], buf: NDArray[np.float64]
                           ) -> tuple[bool, NDArray[np.float64]]:
        """The restarted ``rows``' first measurement (module docstring: their own noise), the other rows' from
        ``measurement``: written into ``buf`` for noisy sensors (returns False and unused normals), else (exact
        sensors have no state) every row is measured as in a full step (returns True and the zero normals)."""
        s = self.sensor
        if not s.noisy:
            return True, s.noise()
        state = (self._time, self._pos, self._vel, self._rot, self._omega, self._accel)
        fresh = s.measure_rows(rows, rngs, *(x[rows] for x in state))
        for key, view in info_views(buf, self.num_envs, False)["measurement"].items():
            view[...] = measurement[key]
            view[rows] = fresh[key]
        return False, s._no_noise

    def _rollout_rows(self, state: NDArray[np.float64], ctrl: NDArray[np.float64], out: NDArray[np.float64]
                      ) -> NDArray[np.float64]:
        """One rollout from ``state`` (N, 14) at MuJoCo time ``_MJ_T0`` (the step kernels and the resets keep the
        env's state there) with controls ``ctrl`` (N, nstep, 10) into ``out`` (N, nstep, 14) (all C-contiguous float64:
        the checks are skipped); returns ``out``: the final states ``out[:, -1]`` are at MuJoCo time
        ``_MJ_T0 + nstep physics_dt`` unless MuJoCo reset a diverging row."""
        off = not self._timers  # MuJoCo's profiler timers off during the rollout (:mod:`.mujoco_timers`; the calls
        if off:                 # themselves, not its ``suspended`` context manager: ~1 us less per step)
            timers_off()
        try:
            self._rollout.rollout(self._models, self._datas, state, ctrl, control_spec=_CONTROL_SPEC,
                                  skip_checks=True, nstep=ctrl.shape[1], state=out, chunk_size=self._chunk)
        finally:
            if off:
                timers_on()
        return out

    def _run_ctbr(self, a: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
        """The rate loop (:mod:`.ctbr`) on the true rates at each physics substep, then the rotor lag and a
        one-substep rollout; returns the last rollout's states (N, 1, 14) and the rows that diverged before the last
        substep."""
        collective = a[:, 0] * self._max_thrust
        rate_sp = a[:, 1:] * MAX_RATES
        force, torque = self._force + self.external_force, self._torque + self.external_torque
        state = self._mj_state.copy()
        total = np.zeros((self.num_envs, 4))
        diverged = np.zeros(self.num_envs, dtype=bool)
        t_end = _MJ_T0 + self.physics_dt
        final = state
        loop = self._rate_loop
        assert loop is not None  # action_type "ctbr"
        gains = (loop.kp, loop.ki, loop.kd, loop.j, loop.b_inv, loop.t_min, loop.t_max, loop.i_lim, loop.dt)
        for k in range(self.n_substeps):  # substeps (the rate loop closes the loop at the physics rate)
            ctbr_substep(collective, rate_sp, state, final, k == 0, t_end, self.physics_dt, gains,
                         (loop.integral, loop.prev_rate, loop.has_prev), self._rotor_speeds, self._k_thrust,
                         self._sub_decay_up, self._sub_decay_down, force, torque, self._ctrl1, self._applied, total,
                         diverged)
            state[:, 0] = _MJ_T0  # ctbr_substep carried the last substep's final state (and its time) over
            final = self._rollout_rows(state, self._ctrl1, self._out1)[:, 0]
        self._applied = total / self.n_substeps
        return self._out1, diverged

    def _wind_points(self) -> NDArray[np.float64]:
        """The wind sample points (N, 5, 3) NED: CoM and rotor hubs."""
        points = np.empty((self.num_envs, 5, 3))
        wind_points(self._pos, self._rot, self._rotor_pos, points)
        return points

    def _disturbance(self, wind: NDArray[np.float64], keep: NDArray[np.bool_], buf: NDArray[np.float64]) -> None:
        """The aero wrench of every row in ``wind`` (N, 5, 3) held for the next step by the rows of ``keep``, and the
        truth's wind, force and torque into ``buf`` (:func:`disturbance_rows`)."""
        wind = as_f64(wind, "wind")
        if disturbance_rows(self._params, self._rot, self._vel, self._omega, self._rotor_speeds, wind, self._drag_scale,
                            keep, self._wrench, buf) >= 0:
            self.aero.wrench(self._rot, self._vel, self._omega, self._rotor_speeds, wind)  # raises, naming the inputs

    def _update_disturbance(self, rows: NDArray[np.bool_], buf: NDArray[np.float64],
                            points: NDArray[np.float64] | None = None) -> None:
        """Wind at [CoM, hubs] (``points`` (N, 5, 3), if the caller has them) and the aero wrench for the next step
        (rows not diverged); the external wrench is added where the wrench is applied and reported, so a new one
        acts from the next step on."""
        if points is None:
            points = self._wind_points()
        self._disturbance(self.wind.step(self._time, self.dt, points, self._vel), rows, buf)

    def _observe(self, buf: NDArray[np.float64], z: NDArray[np.float64], measure: bool, action: NDArray[np.float64],
                 prev_action: NDArray[np.float64]) -> tuple[NDArray[np.float32], NDArray[np.float64]]:
        """Observations (N, 19) and rewards (N,), the info numbers but the disturbance into ``buf``
        (:func:`observe_rows`; ``measure``: the sensors with normals ``z``, else ``buf`` holds the measurement)."""
        n = self.num_envs
        s = self.sensor
        obs, reward = np.empty((n, OBS_SIZE), dtype=np.float32), np.empty(n)
        status = observe_rows(self._params, z, measure, self._pos, self._vel, self._rot, self._omega, self._accel,
                              self._time, self._setpoint, self._failure_code, s._count, s._state, action, prev_action,
                              self._applied, self._rotor_speeds, buf, obs, reward)
        if status >= 0:
            self._raise_observe(status, buf, action)
        return obs, reward

    def _raise_observe(self, status: int, buf: NDArray[np.float64], action: NDArray[np.float64]) -> None:
        """Raise the error of :func:`observe_rows`' ``status`` (a measurement or an observation entry not finite)."""
        n = self.num_envs
        if status >= OBS_SIZE * n:
            raise ValueError(SENSOR_NOT_FINITE)
        meas = info_views(buf, n, False)["measurement"]
        hover_observation(meas, self._setpoint, action, self._obs_low, self._obs_high)  # raises, naming the entry
        raise AssertionError(f"observe_rows flagged observation entry {status}, hover_observation found it finite")

    def _info(self, buf: NDArray[np.float64], action_clipped: NDArray[np.bool_], single: bool = False,
              n_ended: int | None = None) -> dict[str, Any]:
        """The step's ``info`` (module docstring): views of the step's fresh buffer ``buf`` (:func:`info_views`) and
        the rows' ``failure`` names (a fresh array; all "" if ``n_ended`` is 0: no row ended in the step);
        ``single``: the single env's form."""
        info = info_views(buf, self.num_envs, single)
        codes = self._failure_code
        if single:
            info["action_clipped"], info["failure"] = bool(action_clipped[0]), _FAILURE_NAMES[codes[0]]
        else:
            info["action_clipped"] = action_clipped
            info["failure"] = self._no_failure.copy() if n_ended == 0 else FAILURES[codes]
        return info

    def close_extras(self, **kwargs: Any) -> None:
        pending, worker = getattr(self, "_pending", None), getattr(self, "_worker", None)
        self._pending = self._worker = None
        if pending is not None:  # a started step finishes first (its result, or error, is dropped)
            pending.exception()
        if worker is not None:
            worker.shutdown()
        if getattr(self, "_rollout", None) is not None:
            self._rollout.close()
            self._rollout = None
