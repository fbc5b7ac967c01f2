"""Domain randomization for training: which quantities are drawn, from what ranges, how often, seeded.

Options (``make_train_env(randomize={...})``; ``fawtgym train --randomize key=value``), all optional:

============== =========================== ===================================================================
key            value                       drawn at each episode start of each row
============== =========================== ===================================================================
``duty``       ``[lo, hi]``, fractions     FAWT duty ~ U(lo, hi): the row flies the scenario's FAWT wind (same
               in [0, 1], e.g. [0.3, 0.7]  fan schedule and options) at that duty (Table 3 covers 0.3-0.7)
``mass``       f in [0, 0.9]               vehicle mass x U(1 - f, 1 + f)
``inertia``    f in [0, 0.9]               inertia x U(1 - f, 1 + f), one factor for the whole tensor (its
                                           shape, hence physical validity, is kept)
``drag``       f in [0, 1]                 aerodynamic wrench x U(1 - f, 1 + f): the rotor drag, flapping-moment
                                           and body-drag coefficients together (the wrench is linear in them)
``gyro_bias``  b >= 0 [rad/s]              gyroscope turn-on bias ~ U(-b, b) per axis (replaces the sensor
                                           preset's own bias draw; noisy sensor presets only)
``accel_bias`` b >= 0 [m/s^2]              accelerometer turn-on bias ~ U(-b, b) per axis (likewise)
============== =========================== ===================================================================

Per row or per batch.  Everything is drawn per row, at the row's episode start (a full reset and every
autoreset), and held for the episode: the batched env gives a row with a drawn mass or inertia its own
MuJoCo model copy (``mujoco.rollout`` takes one model per row), scales the row's aero wrench, writes the
row's IMU biases, and runs a row with a drawn duty on its own FAWT wind model (a wind cohort of one row;
with a fan schedule the batched env runs cohorts anyway, with steady wind this costs one small wind call
per row and step instead of one for the batch).  Nothing is per batch: with same-step autoreset (SB3)
a full reset happens once per training run, so a per-batch draw would be one draw for the whole run.

Seeding: each draw comes from a generator of the row's own episode seed (see
:class:`~fawtgym.envs.hover_batch_env.HoverBatchEnv`), so ``reset(seed=s)`` reproduces every draw of
every episode, and the initial states, wind and sensor streams are the unrandomized env's.

Who knows the draws: only the simulated vehicle.  The observers of
:class:`~fawtgym.train.wrappers.ObserverFeatures`, the base agent of
:class:`~fawtgym.train.wrappers.ResidualAction`, the env's ``ctbr`` rate loop and its hover action keep the
nominal preset, as a flight controller would.  The draws of the latest episode of each row are in
:attr:`RowSampler.last` (and the env's ``mass_scale``, ``inertia_scale``, ``drag_scale``, ``sensor.gyro_bias``,
``sensor.accel_bias``).
"""

from __future__ import annotations

import dataclasses
import re
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

from fawtgym.core.checks import check_number, listed, shown

#: the randomization options (module docstring)
RANDOMIZE_KEYS = ("duty", "mass", "inertia", "drag", "gyro_bias", "accel_bias")
_FRACTION_MAX = {"mass": 0.9, "inertia": 0.9, "drag": 1.0}
_FAWT = re.compile(r"fawt(-\d+)?")


def _number(key: str, value: Any) -> float:
    """A randomization bound as a float (:func:`~fawtgym.core.checks.check_number`: bool, str, None, inf and ints
    beyond float range refused, naming the key)."""
    return check_number(value, f"randomize {shown(key)}")


@dataclasses.dataclass(frozen=True)
class Randomization:
    """The ranges of the draws (module docstring); zero / None: not randomized."""

    duty: tuple[float, float] | None = None
    mass: float = 0.0
    inertia: float = 0.0
    drag: float = 0.0
    gyro_bias: float = 0.0
    accel_bias: float = 0.0

    def __post_init__(self) -> None:
        if self.duty is not None:
            d = self.duty
            if isinstance(d, (str, bytes)) or not isinstance(d, Sequence) or len(d) != 2:
                raise ValueError(f"randomize 'duty' must be [lo, hi] (fractions, e.g. [0.3, 0.7]), got {shown(d)}")
            lo, hi = _number("duty", d[0]), _number("duty", d[1])
            if not 0.0 <= lo <= hi <= 1.0:
                raise ValueError(f"randomize 'duty' must be [lo, hi] with 0 <= lo <= hi <= 1 (fractions, e.g. "
                                 f"[0.3, 0.7]), got {list(d)!r}")
            object.__setattr__(self, "duty", (lo, hi))
        for key, top in _FRACTION_MAX.items():
            v = _number(key, getattr(self, key))
            if not 0.0 <= v <= top:
                raise ValueError(f"randomize {shown(key)} is a fraction f in [0, {top:g}] (scale ~ U(1 - f, 1 + "
                                 f"f)), got {getattr(self, key)!r}")
            object.__setattr__(self, key, v)
        for key in ("gyro_bias", "accel_bias"):
            v = _number(key, getattr(self, key))
            if v < 0:
                raise ValueError(f"randomize {shown(key)} is a half-range b >= 0 (bias ~ U(-b, b)), got {shown(v)}")
            object.__setattr__(self, key, v)

    @classmethod
    def from_options(cls, options: Mapping[str, Any] | None) -> Randomization | None:
        """From the ``randomize`` mapping (None or empty: None); unknown keys give a one-line ValueError."""
        if options is None:
            return None
        if not isinstance(options, Mapping):
            raise ValueError(f"randomize must be a mapping of {', '.join(RANDOMIZE_KEYS)}, got "
                             f"{type(options).__name__}")
        unknown = set(options) - set(RANDOMIZE_KEYS)
        if unknown:
            raise ValueError(f"unknown randomize key(s) {listed(unknown)}; valid: {', '.join(RANDOMIZE_KEYS)}")
        out = cls(**{k: v for k, v in options.items() if v is not None})
        return out if out.active else None

    @property
    def active(self) -> bool:
        return self.duty is not None or any(getattr(self, k) > 0 for k in RANDOMIZE_KEYS[1:])

    def to_dict(self) -> dict[str, Any]:
        """The non-default options (JSON-able)."""
        out: dict[str, Any] = {}
        if self.duty is not None:
            out["duty"] = list(self.duty)
        out.update({k: getattr(self, k) for k in RANDOMIZE_KEYS[1:] if getattr(self, k) > 0})
        return out

    def sampler(self, wind: Any = None) -> RowSampler:
        """The env's ``randomizer`` callable; ``wind`` is the scenario's wind (needed for ``duty``)."""
        return RowSampler(self, wind)


class RowSampler:
    """Draws one episode's values per starting row: ``sampler(rows, rngs) -> draws`` for ``HoverBatchEnv``.

    Each row's generator gives, in this order, the duty, mass, inertia and drag factors and the gyro and
    accelerometer biases (only the randomized ones).
    """

    def __init__(self, config: Randomization, wind: Any = None) -> None:
        self.config = config
        self.last: dict[int, dict[str, Any]] = {}
        self._wind_options: dict[str, Any] | None = None
        if config.duty is not None:
            self._wind_options = _fawt_options(wind)
            self._make_wind(config.duty[0])  # a bad wind option fails here, not at the first reset

    def _make_wind(self, duty: float) -> Any:
        from fawtgym.envs.wind import make_wind

        if self._wind_options is None:
            raise RuntimeError("RowSampler draws no duty (config.duty is None): there is no FAWT wind to make")
        return make_wind({**self._wind_options, "name": "fawt", "duty": duty})

    def __call__(self, rows: NDArray[np.intp], rngs: Sequence[np.random.Generator]) -> dict[str, Any]:
        c = self.config
        k = len(rows)
        draws: dict[str, Any] = {}
        values: dict[str, NDArray[np.float64]] = {}
        for key, lo, hi, shape in (("duty", *(c.duty or (0.0, 0.0)), ()),
                                   ("mass", 1.0 - c.mass, 1.0 + c.mass, ()),
                                   ("inertia", 1.0 - c.inertia, 1.0 + c.inertia, ()),
                                   ("drag", 1.0 - c.drag, 1.0 + c.drag, ()),
                                   ("gyro_bias", -c.gyro_bias, c.gyro_bias, (3,)),
                                   ("accel_bias", -c.accel_bias, c.accel_bias, (3,))):
            if (key == "duty" and c.duty is None) or (key != "duty" and getattr(c, key) == 0.0):
                continue
            values[key] = np.array([g.uniform(lo, hi, shape) for g in rngs]).reshape((k, *shape))
        if "duty" in values:
            draws["wind"] = [self._make_wind(float(d)) for d in values["duty"]]
        for key, env_key in (("mass", "mass_scale"), ("inertia", "inertia_scale"), ("drag", "drag_scale"),
                             ("gyro_bias", "gyro_bias"), ("accel_bias", "accel_bias")):
            if key in values:
                draws[env_key] = values[key]
        for j, row in enumerate(np.asarray(rows).tolist()):
            self.last[row] = {key: (v[j].tolist() if v.ndim > 1 else float(v[j])) for key, v in values.items()}
        return draws


def _fawt_options(wind: Any) -> dict[str, Any]:
    """The options of a FAWT wind spec (name, mapping or FawtWind) without its name and duty."""
    name = wind.get("name") if isinstance(wind, Mapping) else wind
    if not (isinstance(name, str) and _FAWT.fullmatch(name)):
        raise ValueError(f"randomize 'duty' needs a FAWT wind (fawt, fawt-30 ... fawt-70, with or without a fan "
                         f"schedule); the scenario's wind is {shown(wind)}")
    if not isinstance(wind, Mapping):
        return {}
    return {k: v for k, v in wind.items() if k not in ("name", "duty")}
