"""Vehicle presets: mass properties, rotor geometry, motor and aerodynamic coefficients.

Every preset is a quad X in PX4's motor order (body FRD, arm length ``l``)::

    motor 1: front-right, CCW      motor 3: front-left, CW
    motor 2: rear-left,   CCW      motor 4: rear-right, CW

``rotor_directions`` is +1 for a rotor spinning counter-clockwise seen from above.  Its reaction
torque on the body is ``+k_M T`` about FRD z (a CCW rotor yaws the body clockwise seen from above,
which is positive yaw in FRD).

Rotor model (used by :mod:`fawtgym.envs.motors`): thrust ``T = k_T w^2`` [N], reaction torque
``k_M T`` [N m] (``k_M`` in metres), first-order speed lag with ``tau_up`` when accelerating and
``tau_down`` when slowing, speeds limited to ``[omega_min, omega_max]`` (``omega_min`` is the
armed idle speed).

Aerodynamic coefficients (used by :mod:`fawtgym.envs.aero`):

* ``rotor_drag`` k_d [N/((m/s)(rad/s))]: linear rotor (induced + blade-profile) drag,
  ``F = -k_d w v_inplane`` per rotor (Faessler et al. 2018; PX4 Gazebo motor model).
* ``rolling_moment`` k_r [N m/((m/s)(rad/s))]: rotor rolling/flapping moment per unit in-plane
  airspeed and rotor speed (PX4 Gazebo motor model ``rollingMomentCoefficient``).
* ``body_drag`` [N/(m/s)^2] per body axis: quadratic parasitic drag ``0.5 rho C_D A``.
* ``cop_offset`` [m]: centre of pressure of the body drag relative to the CoM, body FRD.

Users pass their own preset as a :class:`VehiclePreset`, a mapping (e.g. loaded from YAML), or a
YAML/JSON path; invalid values raise ``ValueError`` naming the field.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from fawtgym.core.arrays import REAL_KINDS, as_array
from fawtgym.core.checks import check_number, listed, shown
from fawtgym.core.constants import GRAVITY  # defined in core; importable from here too (compatibility)
from fawtgym.core.files import DATA_SUFFIXES, load_data

AIR_DENSITY = 1.225  #: ISA sea-level air density [kg/m^3]

#: PX4 quad X motor order: unit arm directions in body FRD and spin directions (+1 = CCW).
QUAD_X_ARMS = np.array([[1.0, 1.0, 0.0], [-1.0, -1.0, 0.0], [1.0, -1.0, 0.0], [-1.0, 1.0, 0.0]]) / math.sqrt(2.0)
QUAD_X_DIRECTIONS = np.array([1.0, 1.0, -1.0, -1.0])


#: the longest vehicle name (it names the MJCF model and the leaderboard's vehicle)
MAX_NAME = 200

#: The physical range of each scalar field: (lowest, highest, unit).  Every range spans orders of magnitude around
#: the presets (from a 10 g micro quad to a 10 t airframe); outside it a value is a typo or a unit slip, and huge or
#: tiny values overflow the model (omega_max^2, 1 / tau) or MuJoCo's mass matrix.  A lowest of 0 is inclusive.
SCALAR_RANGES: dict[str, tuple[float, float, str]] = {
    "mass": (1e-4, 1e4, "kg"),
    "arm_length": (1e-3, 100.0, "m"),
    "k_thrust": (1e-12, 1.0, "N/(rad/s)^2"),
    "k_moment": (1e-6, 1.0, "m"),
    "omega_min": (0.0, 1e5, "rad/s"),
    "omega_max": (1.0, 1e5, "rad/s"),
    "tau_up": (1e-4, 10.0, "s"),
    "tau_down": (1e-4, 10.0, "s"),
    "rotor_radius": (1e-3, 10.0, "m"),
    "rotor_drag": (0.0, 0.1, "N/((m/s)(rad/s))"),
    "rolling_moment": (0.0, 0.1, "N m/((m/s)(rad/s))"),
}
#: principal moments of inertia [kg m^2] (a 10 g micro quad has ~1e-5)
INERTIA_RANGE = (1e-7, 1e5)
#: each body_drag entry [N/(m/s)^2] (0.5 rho C_D A: 100 is a 150 m^2 flat plate) and cop_offset entry [m]
BODY_DRAG_RANGE = (0.0, 100.0)
COP_OFFSET_RANGE = (-100.0, 100.0)


@dataclasses.dataclass(frozen=True)
class VehiclePreset:
    """Physical description of a quad X multirotor (SI units, body FRD).

    Construct through :func:`make_vehicle` or directly; ``__post_init__`` validates every field.
    """

    name: str
    mass: float  #: [kg]
    inertia: tuple[float, ...]  #: diagonal (3) or full row-major (9) inertia about the CoM [kg m^2]
    arm_length: float  #: CoM to rotor hub [m]
    k_thrust: float  #: k_T [N/(rad/s)^2]
    k_moment: float  #: k_M, reaction torque / thrust [m]
    omega_min: float  #: armed idle rotor speed [rad/s]
    omega_max: float  #: maximum rotor speed [rad/s]
    tau_up: float  #: motor time constant when spinning up [s]
    tau_down: float  #: motor time constant when spinning down [s]
    rotor_radius: float  #: propeller radius [m]
    rotor_drag: float = 0.0  #: k_d [N/((m/s)(rad/s))]
    rolling_moment: float = 0.0  #: k_r [N m/((m/s)(rad/s))]
    body_drag: tuple[float, float, float] = (0.0, 0.0, 0.0)  #: quadratic drag 0.5 rho C_D A [N/(m/s)^2]
    cop_offset: tuple[float, float, float] = (0.0, 0.0, 0.0)  #: centre of pressure, body FRD [m]
    source: str = ""  #: where the numbers come from

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name.strip() or len(self.name) > MAX_NAME:
            raise ValueError(f"vehicle field 'name' must be a non-empty str of at most {MAX_NAME} characters, got "
                             f"{shown(self.name)}")
        for field, (lowest, highest, unit) in SCALAR_RANGES.items():
            # any real number (numpy scalars too, stored as float); bool, str, None and complex are refused
            value = check_number(getattr(self, field), f"vehicle field {field!r}", minimum=lowest, maximum=highest,
                                 inclusive_minimum=True, note=unit)
            object.__setattr__(self, field, value)
        if self.omega_min >= self.omega_max:
            raise ValueError(f"vehicle field 'omega_min' ({self.omega_min}) must be below "
                             f"'omega_max' ({self.omega_max})")
        inertia = _real_vector("inertia", self.inertia)
        if inertia.shape not in ((3,), (9,), (3, 3)):
            raise ValueError(f"vehicle field 'inertia' must have 3 (diagonal) or 9 entries, got shape {inertia.shape}")
        j = np.diag(inertia) if inertia.shape == (3,) else inertia.reshape(3, 3)
        if not np.all(np.isfinite(j)) or not np.allclose(j, j.T, rtol=1e-9, atol=1e-12):
            raise ValueError(f"vehicle field 'inertia' must be finite and symmetric, got {j.tolist()}")
        eig = np.linalg.eigvalsh(j)
        if eig.min() <= 0:
            raise ValueError(f"vehicle field 'inertia' must be positive definite, eigenvalues {eig.tolist()}")
        if eig.min() < INERTIA_RANGE[0] or eig.max() > INERTIA_RANGE[1]:
            raise ValueError(f"vehicle field 'inertia' principal moments must be in [{INERTIA_RANGE[0]:g}, "
                             f"{INERTIA_RANGE[1]:g}] kg m^2, got {eig.tolist()}")
        if eig[0] + eig[1] < eig[2] * (1 - 1e-9):
            raise ValueError("vehicle field 'inertia' violates the triangle inequality of principal moments "
                             f"{eig.tolist()}")
        object.__setattr__(self, "inertia", tuple(float(x) for x in j.reshape(-1)))
        for field in ("body_drag", "cop_offset"):
            vec = _real_vector(field, getattr(self, field))
            if vec.shape != (3,) or not np.all(np.isfinite(vec)):
                raise ValueError(f"vehicle field {shown(field)} must be 3 finite numbers, got {getattr(self, field)!r}")
            (lowest, highest), unit = ((BODY_DRAG_RANGE, "N/(m/s)^2") if field == "body_drag"
                                       else (COP_OFFSET_RANGE, "m"))
            if np.any(vec < lowest) or np.any(vec > highest):
                raise ValueError(f"vehicle field {shown(field)} entries must be in [{lowest:g}, {highest:g}] {unit}, "
                                 f"got {vec.tolist()}")
            object.__setattr__(self, field, tuple(float(x) for x in vec))

    # ---- derived quantities -------------------------------------------------------------
    @property
    def inertia_matrix(self) -> NDArray[np.float64]:
        """J as a (3, 3) array [kg m^2]."""
        return np.asarray(self.inertia, dtype=float).reshape(3, 3)

    @property
    def rotor_positions(self) -> NDArray[np.float64]:
        """Rotor hub positions in body FRD, shape (4, 3) [m], PX4 quad X order."""
        return QUAD_X_ARMS * self.arm_length

    @property
    def rotor_directions(self) -> NDArray[np.float64]:
        """+1 for CCW rotors (seen from above), shape (4,)."""
        return QUAD_X_DIRECTIONS.copy()

    @property
    def max_thrust_per_rotor(self) -> float:
        """k_T omega_max^2 [N]."""
        return self.k_thrust * self.omega_max**2

    @property
    def thrust_to_weight(self) -> float:
        return 4.0 * self.max_thrust_per_rotor / (self.mass * GRAVITY)

    @property
    def hover_omega(self) -> float:
        """Rotor speed that holds the vehicle's weight [rad/s]."""
        return math.sqrt(self.mass * GRAVITY / (4.0 * self.k_thrust))

    def replace(self, **changes: Any) -> VehiclePreset:
        """A validated copy with some fields changed."""
        return dataclasses.replace(self, **changes)

    def to_dict(self) -> dict[str, Any]:
        return dataclasses.asdict(self)


def _real_vector(field: str, value: Any) -> NDArray[np.float64]:
    """A vector field's entries as float64 if all are real numbers (int, float, numpy reals); bool, complex, str,
    None and ragged nestings are refused with a ValueError naming the field (as the scalar fields are)."""
    raw = as_array(value)
    if raw.dtype.kind not in REAL_KINDS:
        raise ValueError(f"vehicle field {shown(field)} must be real numbers (not bool, complex or str), got "
                         f"{shown(value)}")
    return raw.astype(np.float64)


def _s500() -> VehiclePreset:
    """S500 quad X of Wang et al. (2024), Sec. 7 (m = 1.0 kg, J = diag(0.03, 0.03, 0.06)).

    Derived from public data for a T-Motor Air 2216 880 KV motor with 10x4.5" props on 4S:
    the manufacturer's tables give roughly 0.9 kg of thrust per motor at full throttle at about
    8,400 rpm loaded (880 rad/s).  With a static thrust coefficient C_T ~ 0.09 for a 10x4.5 prop
    (UIUC propeller database range 0.09-0.11), k_T = C_T rho D^4 / (4 pi^2) = 1.15e-5 N/(rad/s)^2,
    so T_max = 8.9 N per rotor and thrust-to-weight 3.6.  Power coefficient C_P ~ 0.040 gives
    C_Q = C_P / (2 pi) and k_M = C_Q D / C_T = 0.018 m.  Motor time constants of ~30 ms up
    (10" props on 22xx motors; PX4 gz x500 uses 12.5/25 ms for its lighter-loaded motors) and
    45 ms down (no active braking).  Idle 10 % of max speed (PX4 armed idle).  Arm 0.24 m
    (480 mm S500 wheelbase).

    Aerodynamics (calibration in docs/wind.md, rule in fawtgym.envs.aero.calibrated_rotor_drag):
    rotor drag k_d = 0.40 N/(m/s) per kg / (4 omega_hover) = 2.2e-4 (linear drag 0.40 N s/m at
    hover; rotorpy's Hummingbird has 0.31 per kg, a two-point fit to Neural-Fly's data 0.37); body drag
    0.5 rho C_D A with C_D ~ 1.1, frontal area ~0.025 m^2 (frame plates, battery, landing gear)
    -> 0.017, top area ~0.045 m^2 (arms, plates; the discs are in the rotor model) -> 0.03;
    flapping-moment coefficient 1e-6 (PX4 gz x500 rollingMomentCoefficient magnitude);
    centre of pressure 2 cm above the CoM (battery strapped on top).  Horizontal drag at hover:
    2.0 N at 4.2 m/s, 4.7 N at 8.5 m/s (Neural-Fly: 2-3 N and 6-8 N), 4.5 N at FAWT 50 %, 6.5 N at 70 %.
    """
    return VehiclePreset(
        name="s500", mass=1.0, inertia=(0.03, 0.03, 0.06), arm_length=0.24,
        k_thrust=1.15e-5, k_moment=0.018, omega_min=88.0, omega_max=880.0,
        tau_up=0.030, tau_down=0.045, rotor_radius=0.127,
        rotor_drag=2.2e-4, rolling_moment=1.0e-6, body_drag=(0.017, 0.017, 0.030),
        cop_offset=(0.0, 0.0, -0.02),
        source="Wang et al. (2024), Sec. 7 (mass, inertia); T-Motor Air 2216 880KV + 10x4.5 public data (rotor)",
    )


def _pounds_x4() -> VehiclePreset:
    """Pounds X-4 simulation vehicle of Wang et al. (2024), Sec. 6: m = 4.34 kg, J = diag(0.0820, 0.0845, 0.1377).

    Rotor data from Pounds, Mahony, Corke (2010), "Modelling and control of a large quadrotor
    robot": arm 0.315 m, rotor radius 0.165 m, C_T = 0.0048 in T = C_T rho A R^2 w^2, hence
    k_T = C_T rho pi R^4 = 1.32e-5 N/(rad/s)^2 (rho = 1.184); max speed 1300 rad/s chosen for thrust-to-weight ~2.1.
    The simulation of Wang et al. (2024) itself has no actuator dynamics (the Wang et al. (2024) study bypasses motors).
    Aerodynamics by the docs/wind.md rule: k_d = 0.40 * m / (4 omega_hover) = 4.8e-4, body drag
    scaled from the s500 by frontal area ~ m^(2/3): 0.017 * 4.34^(2/3) = 0.045.
    """
    return VehiclePreset(
        name="pounds_x4", mass=4.34, inertia=(0.0820, 0.0845, 0.1377), arm_length=0.315,
        k_thrust=1.32e-5, k_moment=0.02, omega_min=130.0, omega_max=1300.0,
        tau_up=0.05, tau_down=0.08, rotor_radius=0.165,
        rotor_drag=4.8e-4, rolling_moment=2.0e-6, body_drag=(0.045, 0.045, 0.08),
        source="Wang et al. (2024), Sec. 6 (mass, inertia); Pounds et al. 2010 (rotor)",
    )


def _shi_geso() -> VehiclePreset:
    """GESO simulation vehicle, Shi et al. (2018) Table 1.

    m = 1.79 kg, Jx = Jy = 1.335e-2, Jz = 2.465e-2 kg m^2, l = 0.18 m, k_T = 8.82e-6 N/(rad/s)^2,
    drag-torque coefficient k_D = 1.09e-7 N m/(rad/s)^2, hence k_M = k_D / k_T.  Max speed for
    thrust-to-weight ~2 and a 20 ms motor lag are our choices (the table gives none).
    Aerodynamics by the docs/wind.md rule: k_d = 0.40 * m / (4 omega_hover) = 2.5e-4, body drag
    0.017 * 1.79^(2/3) = 0.025.
    """
    return VehiclePreset(
        name="shi_geso", mass=1.79, inertia=(1.335e-2, 1.335e-2, 2.465e-2), arm_length=0.18,
        k_thrust=8.82e-6, k_moment=1.09e-7 / 8.82e-6, omega_min=100.0, omega_max=1000.0,
        tau_up=0.02, tau_down=0.03, rotor_radius=0.127,
        rotor_drag=2.5e-4, rolling_moment=1.0e-6, body_drag=(0.025, 0.025, 0.045),
        source="Shi et al. (2018) Table 1",
    )


def _hummingbird() -> VehiclePreset:
    """AscTec Hummingbird of Cayero et al. (2019) Sec. 4: m = 1.023 kg, J = diag(9.5, 9.5, 18.6)e-3.

    Rotor and drag numbers from rotorpy's Hummingbird model (k_eta = 5.57e-6, k_m = 1.36e-7,
    arm 0.17 m, rotor radius 0.1 m, max 1500 rad/s, rotor drag k_d = 1.19e-4, parasitic drag
    c_D = 0.5e-2 / 0.5e-2 / 1e-2).  rotorpy's 5 ms motor lag is kept for spin-up.
    """
    return VehiclePreset(
        name="hummingbird", mass=1.023, inertia=(9.5e-3, 9.5e-3, 18.6e-3), arm_length=0.17,
        k_thrust=5.57e-6, k_moment=1.36e-7 / 5.57e-6, omega_min=150.0, omega_max=1500.0,
        tau_up=0.005, tau_down=0.0075, rotor_radius=0.1,
        rotor_drag=1.19e-4, rolling_moment=0.0, body_drag=(0.5e-2, 0.5e-2, 1e-2),
        source="Cayero et al. (2019) Sec. 4 (mass, inertia); rotorpy hummingbird_params (rotor, drag)",
    )


def _x500() -> VehiclePreset:
    """PX4's Gazebo x500 (PX4-gazebo-models x500_base/model.sdf), for SITL use.

    m = 2.0 kg, Ixx = Iyy = 0.021667, Izz = 0.04 kg m^2, motorConstant 8.54858e-6,
    momentConstant 0.016, timeConstantUp 0.0125 s, timeConstantDown 0.025 s,
    maxRotVelocity 1000 rad/s, rotors at (+-0.174, +-0.174) m, rotorDragCoefficient 8.06428e-5,
    rollingMomentCoefficient 1e-6.  Idle 100 rad/s.
    """
    return VehiclePreset(
        name="x500", mass=2.0, inertia=(0.021667, 0.021667, 0.04), arm_length=0.174 * math.sqrt(2.0),
        k_thrust=8.54858e-6, k_moment=0.016, omega_min=100.0, omega_max=1000.0,
        tau_up=0.0125, tau_down=0.025, rotor_radius=0.127,
        rotor_drag=8.06428e-5, rolling_moment=1e-6, body_drag=(0.02, 0.02, 0.03),
        source="PX4 gz x500 model.sdf",
    )


_PRESETS = {"s500": _s500, "pounds_x4": _pounds_x4, "shi_geso": _shi_geso,
            "hummingbird": _hummingbird, "x500": _x500}

VEHICLE_NAMES: tuple[str, ...] = tuple(_PRESETS)


def vehicle_from_mapping(data: Mapping[str, Any]) -> VehiclePreset:
    """Build a preset from a mapping; ``base`` names a preset whose fields are the defaults."""
    data = dict(data)
    base = data.pop("base", None)
    fields = {f.name for f in dataclasses.fields(VehiclePreset)}
    unknown = set(data) - fields
    if unknown:
        raise ValueError(f"unknown vehicle field(s) {listed(unknown)}; valid fields: {sorted(fields)}")
    if base is not None:
        return make_vehicle(base).replace(**data)
    missing = sorted(f.name for f in dataclasses.fields(VehiclePreset)
                     if f.default is dataclasses.MISSING and f.name not in data)
    if missing:
        raise ValueError(f"vehicle mapping is missing field(s) {missing} (or give 'base': <preset name>)")
    return VehiclePreset(**data)


def make_vehicle(spec: str | VehiclePreset | Mapping[str, Any] | Path) -> VehiclePreset:
    """A preset from its name, a :class:`VehiclePreset`, a mapping, or a .yaml/.json file path."""
    if isinstance(spec, VehiclePreset):
        return spec
    if isinstance(spec, Mapping):
        return vehicle_from_mapping(spec)
    if isinstance(spec, (str, Path)):
        if str(spec) in _PRESETS:
            return _PRESETS[str(spec)]()
        path = Path(spec)
        if path.suffix.lower() in DATA_SUFFIXES:
            data = load_data(path, "vehicle file")
            if not isinstance(data, Mapping):
                raise ValueError(f"vehicle file {path} must hold a mapping of vehicle fields, got "
                                 f"{type(data).__name__}")
            return vehicle_from_mapping(data)
        raise ValueError(f"unknown vehicle {str(spec)!r}; valid presets: {list(VEHICLE_NAMES)} "
                         "(or a VehiclePreset, a mapping, or a .yaml/.json file)")
    raise ValueError(f"vehicle must be a preset name, a VehiclePreset, a mapping or a .yaml/.json path, got "
                     f"{shown(spec)} ({type(spec).__name__})")
