"""Vehicle presets and their validation."""

import json

import numpy as np
import pytest

from fawtgym.envs.motors import allocation_matrix, command_to_thrust, hover_command, mix, rotor_wrench
from fawtgym.envs.vehicles import VEHICLE_NAMES, make_vehicle


@pytest.mark.parametrize("name", VEHICLE_NAMES)
def test_presets_are_valid_and_can_hover(name):
    p = make_vehicle(name)
    assert p.thrust_to_weight > 1.5
    u = hover_command(p)
    assert 0 < u < 1
    assert np.isclose(4 * command_to_thrust(p, u), p.mass * 9.80665)


def test_seed_numbers():
    s500 = make_vehicle("s500")
    assert s500.mass == 1.0 and np.allclose(np.diag(s500.inertia_matrix), [0.03, 0.03, 0.06])
    assert 3.0 <= s500.thrust_to_weight <= 4.0
    x4 = make_vehicle("pounds_x4")
    assert np.allclose(np.diag(x4.inertia_matrix), [0.0820, 0.0845, 0.1377]) and x4.mass == 4.34
    shi = make_vehicle("shi_geso")
    assert shi.k_thrust == 8.82e-6 and np.isclose(shi.k_moment * shi.k_thrust, 1.09e-7)
    x500 = make_vehicle("x500")
    assert (x500.k_thrust, x500.k_moment, x500.tau_up, x500.tau_down, x500.omega_max) == (
        8.54858e-6, 0.016, 0.0125, 0.025, 1000.0)


@pytest.mark.parametrize(("field", "value"), [("mass", -1.0), ("mass", float("nan")), ("inertia", (0.03, -0.03, 0.06)),
                                              ("inertia", (0.01, 0.01, 0.05)), ("tau_up", 0.0), ("omega_min", 2000.0)])
def test_invalid_values_name_the_field(field, value):
    with pytest.raises(ValueError, match=field):
        make_vehicle("s500").replace(**{field: value})


def test_user_presets_from_mapping_and_file(tmp_path):
    p = make_vehicle({"base": "s500", "mass": 1.2})
    assert p.mass == 1.2 and p.arm_length == 0.24
    path = tmp_path / "v.json"
    path.write_text(json.dumps({**make_vehicle("x500").to_dict(), "name": "mine"}))
    assert make_vehicle(path).name == "mine"
    yaml = pytest.importorskip("yaml")
    ypath = tmp_path / "v.yaml"
    ypath.write_text(yaml.safe_dump({"base": "hummingbird", "tau_up": 0.02}))
    assert make_vehicle(ypath).tau_up == 0.02
    with pytest.raises(ValueError, match="unknown vehicle field"):
        make_vehicle({"base": "s500", "mas": 1.0})
    with pytest.raises(ValueError, match="missing field"):
        make_vehicle({"mass": 1.0})
    with pytest.raises(ValueError, match="valid presets"):
        make_vehicle("s5000")


def test_allocation_round_trip_and_signs():
    p = make_vehicle("s500")
    b = allocation_matrix(p)
    wrench = np.array([9.0, 0.1, -0.2, 0.05])
    t = mix(p, wrench[0], wrench[1:])
    f, tau = rotor_wrench(p, t)
    assert np.isclose(f, 9.0) and np.allclose(tau, wrench[1:])
    # a positive roll torque (right side down) needs the left rotors (3: front-left, 2: rear-left) pushed harder
    dt = mix(p, 0.0, [1.0, 0, 0])
    assert dt[2] > 0 and dt[1] > 0 and dt[0] < 0 and dt[3] < 0
    # positive yaw torque (nose right, FRD) comes from speeding up the CCW rotors 1 and 2
    assert np.all(b[3, :2] > 0) and np.all(b[3, 2:] < 0)
