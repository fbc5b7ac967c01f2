"""Per-row reset of every registered observer: ``observer.reset(measurement, rows=mask)``.

Rows of a batched env end at different times, so an observer re-initializes chosen rows only: the masked
rows get the state of a freshly built observer reset on their measurement, the other rows keep theirs
bitwise (observers/base.py, ``Observer.reset``).  Parametrized over ``observer_names()``, so a newly
registered observer is covered without editing this file.

Measurements: a 3-row ``HoverBatchEnv`` (FAWT wind at 50 % duty, mocap + IMU sensors, so every key any
observer reads is there) flown by ``PX4Agent``; the observers get ``info["measurement"]`` and the applied
thrust/torque of ``info["applied"]`` at each step.

Tolerance policy: the same code path on the same data is compared bitwise (the untouched row against an
observer that never had a partial reset; an all-False mask against no call; an all-True mask against a full
reset); a reset row against a freshly built observer is compared to 1e-9 relative to max(1, |x|)
(a batch of another size may round a product differently).
"""

from __future__ import annotations

import re
import warnings

import numpy as np
import pytest

import fawtgym.observers  # noqa: F401  (registers every observer)
from fawtgym.agents import PX4Agent
from fawtgym.envs.hover_batch_env import HoverBatchEnv
from fawtgym.observers import make_observer, observer_names

NAMES = observer_names()
RATE = 200.0
DT = 1.0 / RATE
RESET_STEP = 40     # the rows are reset after this step's update ...
RESET_FROM = 5      # ... from this step's measurement (a jump, as an autoreset row's new episode)
STEPS = 100         # steps flown (0.5 s)
MASK = np.array([True, False, True])
FORCE_GUESS = np.array([[0.3, -0.2, 0.1], [5.0, 5.0, 5.0], [-0.1, 0.2, 0.4]])  # (N, 3): one guess per row
TORQUE_GUESS = np.array([0.01, -0.02, 0.005])                                   # (3,): every row


@pytest.fixture(scope="module")
def flight() -> tuple[list[dict[str, np.ndarray]], list[tuple[np.ndarray, np.ndarray]]]:
    """Measurements and applied (thrust (3,), torque (3, 3)) of STEPS + 1 steps of a 3-row batch."""
    env = HoverBatchEnv(num_envs=3, wind="fawt-50", sensors="mocap_imu", control_rate=RATE)
    agent = PX4Agent.for_env(env)
    obs, info = env.reset(seed=3)
    agent.reset(info)
    meas, applied = [], []
    for k in range(STEPS + 1):
        meas.append({key: np.array(v) for key, v in info["measurement"].items()})
        applied.append((np.array(info["applied"]["thrust"]), np.array(info["applied"]["torque"])))
        if k < STEPS:
            obs, _, terminated, truncated, info = env.step(agent.act(obs, info))
            assert not (np.any(terminated) or np.any(truncated)), "the reference flight must not end a row"
    env.close()
    return meas, applied


def _build(name: str):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the QB observer warns that its gain was designed for another mass
        return make_observer(name, mass=1.0, inertia=[0.03, 0.03, 0.06])


def _rows(m: dict[str, np.ndarray], idx) -> dict[str, np.ndarray]:
    return {k: v[idx] for k, v in m.items()}


def _step(obs, meas, applied, k: int, idx=slice(None)):
    thrust, torque = applied[k]
    return obs.update(_rows(meas[k], idx), thrust[idx], torque[idx], DT)


def _fields(est) -> dict[str, np.ndarray]:
    out = {"force": np.asarray(est.force), "torque": np.asarray(est.torque)}
    out.update({f"states[{k!r}]": np.asarray(v) for k, v in est.states.items()})
    return out


def _close(got: np.ndarray, want: np.ndarray, what: str) -> None:
    assert got.shape == want.shape, what
    if got.dtype == np.bool_:
        np.testing.assert_array_equal(got, want, err_msg=what)
        return
    err = np.abs(got - want)
    tol = 1e-9 * np.maximum(1.0, np.abs(want))
    assert np.all(err <= tol), f"{what}: max error {err.max():.3g} (scaled tolerance 1e-9 max(1, |x|))"


@pytest.mark.parametrize("name", NAMES)
def test_reset_rows_equal_a_fresh_observer_and_other_rows_are_untouched(name, flight):
    meas, applied = flight
    obs, ref = _build(name), _build(name)  # ref: the same batch, never reset partially
    obs.reset(meas[0])
    ref.reset(meas[0])
    for k in range(1, RESET_STEP + 1):
        _step(obs, meas, applied, k)
        _step(ref, meas, applied, k)
    # only the masked rows' measurement is read: the unmasked row may be anything (here, a crashed row's NaN)
    poisoned = {key: np.array(v) for key, v in meas[RESET_FROM].items()}
    for key in poisoned:
        poisoned[key][~MASK] = np.nan
    obs.reset(poisoned, force=FORCE_GUESS, torque=TORQUE_GUESS, rows=MASK)
    fresh3, fresh2 = _build(name), _build(name)  # fresh: 3 rows reset at the same step / the masked rows alone
    fresh3.reset(meas[RESET_FROM], force=FORCE_GUESS, torque=TORQUE_GUESS)
    fresh2.reset(_rows(meas[RESET_FROM], MASK), force=FORCE_GUESS[MASK], torque=TORQUE_GUESS)
    changed = False
    for k in range(RESET_STEP + 1, STEPS + 1):
        got, want = _fields(_step(obs, meas, applied, k)), _fields(_step(ref, meas, applied, k))
        full, sub = _fields(_step(fresh3, meas, applied, k)), _fields(_step(fresh2, meas, applied, k, MASK))
        assert got.keys() == want.keys() == full.keys() == sub.keys()
        for key, x in got.items():
            what = f"{name} step {k} {key}"
            np.testing.assert_array_equal(x[~MASK], want[key][~MASK], err_msg=f"{what}: the untouched row")
            _close(x[MASK], full[key][MASK], f"{what}: reset rows vs a fresh 3-row observer")
            _close(x[MASK], sub[key], f"{what}: reset rows vs a fresh observer of those rows")
            changed |= not np.array_equal(x[MASK], want[key][MASK])
    assert changed, "the row reset had no effect: the test would not see a missing reset"


def _error(call) -> str:
    with pytest.raises(ValueError) as info:
        call()
    msg = str(info.value)
    assert "\n" not in msg, msg
    return msg


def _mistakes(name: str, n: int, meas, applied) -> list[str]:
    """The messages of each malformed per-row reset of an n-row observer (digits replaced by #); checks that a
    rejected request leaves the state as it was."""
    idx = slice(0, n)
    seq = [_rows(m, idx) for m in meas[:3]]
    obs, twin = _build(name), _build(name)
    every = np.ones(n, dtype=bool)
    got = [_error(lambda: obs.reset(seq[0], rows=every))]                            # before any full reset
    obs.reset(seq[0])
    twin.reset(seq[0])
    _step(obs, meas, applied, 1, idx)
    _step(twin, meas, applied, 1, idx)
    got += [
        _error(lambda: obs.reset(seq[1], rows=np.ones(n, dtype=int))),                # not bool
        _error(lambda: obs.reset(seq[1], rows=np.ones(n + 1, dtype=bool))),           # wrong length
        _error(lambda: obs.reset(seq[1], rows=[[True] * n])),                         # 2-D
        _error(lambda: obs.reset(seq[1], rows=True)),                                 # a scalar
        _error(lambda: obs.reset(_rows(meas[1], slice(0, 2)), rows=every)),           # 2 rows, not n
        _error(lambda: obs.reset(seq[1], force=np.zeros((2, 3)), rows=every)),        # a guess of 2 rows
    ]
    a, b = _fields(_step(obs, meas, applied, 2, idx)), _fields(_step(twin, meas, applied, 2, idx))
    for key in a:
        np.testing.assert_array_equal(a[key], b[key], err_msg=f"{name} n={n} {key}: a rejected reset changed the state")
    return [re.sub(r"\d+", "#", m) for m in got]


@pytest.mark.parametrize("name", NAMES)
def test_row_reset_errors_are_one_layer_with_the_same_message_at_every_n(name, flight):
    meas, applied = flight
    one, three = _mistakes(name, 1, meas, applied), _mistakes(name, 3, meas, applied)
    assert one == three
    assert len(set(three)) == len(three), "each mistake gets its own message"


@pytest.mark.parametrize("n", [1, 3])
@pytest.mark.parametrize("name", NAMES)
def test_all_false_mask_is_a_no_op_and_all_true_mask_a_full_reset(name, n, flight):
    meas, applied = flight
    idx = slice(0, n)
    noop, untouched, masked_full, full = (_build(name) for _ in range(4))
    for obs in (noop, untouched, masked_full, full):
        obs.reset(_rows(meas[0], idx))
        for k in range(1, RESET_STEP + 1):
            _step(obs, meas, applied, k, idx)
    at = _rows(meas[RESET_FROM], idx)
    noop.reset(at, force=FORCE_GUESS[idx], rows=np.zeros(n, dtype=bool))
    masked_full.reset(at, force=FORCE_GUESS[idx], torque=TORQUE_GUESS, rows=np.ones(n, dtype=bool))
    full.reset(at, force=FORCE_GUESS[idx], torque=TORQUE_GUESS)
    fresh = _build(name)  # a reset keeps nothing of the past (e.g. an N = 1 float cache)
    fresh.reset(at, force=FORCE_GUESS[idx], torque=TORQUE_GUESS)
    for k in range(RESET_STEP + 1, STEPS + 1):
        a, b = _fields(_step(noop, meas, applied, k, idx)), _fields(_step(untouched, meas, applied, k, idx))
        c, d = _fields(_step(masked_full, meas, applied, k, idx)), _fields(_step(full, meas, applied, k, idx))
        e = _fields(_step(fresh, meas, applied, k, idx))
        for key in a:
            what = f"{name} n={n} step {k} {key}"
            np.testing.assert_array_equal(a[key], b[key], err_msg=f"{what}: all-False mask")
            np.testing.assert_array_equal(c[key], d[key], err_msg=f"{what}: all-True mask")
            _close(c[key], e[key], f"{what}: all-True mask vs a freshly built observer")


def test_qb_thrust_option_is_taken_per_row(flight):
    """The QB observer's own reset option ``thrust`` (N,) follows the mask like the measurement."""
    meas, applied = flight
    thrust = np.array([9.0, 11.0, 10.0])
    obs, fresh = _build("qb"), _build("qb")
    obs.reset(meas[0])
    obs.reset(meas[RESET_FROM], thrust=thrust, rows=MASK)
    fresh.reset(_rows(meas[RESET_FROM], MASK), thrust=thrust[MASK])
    got, want = _fields(_step(obs, meas, applied, 1)), _fields(_step(fresh, meas, applied, 1, MASK))
    for key, x in got.items():
        _close(x[MASK], want[key], f"qb {key}")
