"""PX4 parameter set: defaults, S500 overrides, files, errors (agents/px4_params.py)."""

from __future__ import annotations

import pytest

from fawtgym.agents.px4_params import PARAM_SPECS, S500_PARAMS_FILE, PX4Params


def test_defaults_are_px4_v113_values() -> None:
    p = PX4Params()
    expected = {"MPC_XY_P": 0.95, "MPC_XY_VEL_P_ACC": 1.8, "MPC_XY_VEL_I_ACC": 0.4, "MPC_XY_VEL_D_ACC": 0.2,
                "MPC_Z_P": 1.0, "MPC_Z_VEL_P_ACC": 4.0, "MPC_Z_VEL_I_ACC": 2.0, "MC_ROLL_P": 6.5, "MC_PITCH_P": 6.5,
                "MC_YAW_P": 2.8, "MC_ROLLRATE_P": 0.15, "MC_ROLLRATE_I": 0.2, "MC_ROLLRATE_D": 0.003,
                "MC_YAWRATE_P": 0.2, "MC_YAWRATE_I": 0.1, "MC_RR_INT_LIM": 0.3, "MC_PR_INT_LIM": 0.3,
                "MC_YR_INT_LIM": 0.3, "MPC_TILTMAX_AIR": 45.0, "MPC_THR_MIN": 0.12, "MPC_THR_MAX": 1.0,
                "MC_YAW_WEIGHT": 0.4, "MC_ROLLRATE_MAX": 220.0, "MC_PITCHRATE_MAX": 220.0, "MC_YAWRATE_MAX": 200.0}
    for name, value in expected.items():
        assert p[name] == value, name


def test_s500_overrides() -> None:
    p = PX4Params.s500()
    assert (p["MC_ROLLRATE_P"], p["MC_PITCHRATE_P"]) == (0.18, 0.18)
    assert (p["MC_ROLLRATE_I"], p["MC_PITCHRATE_I"]) == (0.15, 0.15)
    assert (p["MC_ROLLRATE_D"], p["MC_PITCHRATE_D"]) == (0.003, 0.003)
    assert p["MC_YAWRATE_P"] == 0.2  # not overridden
    assert PX4Params.s500(MPC_XY_P=1.2)["MPC_XY_P"] == 1.2


def test_save_load_round_trip_qgc_format(tmp_path) -> None:
    p = PX4Params.s500(MPC_XY_P=1.1, MC_YAW_WEIGHT=0.6)
    path = p.save(tmp_path / "x.params")
    lines = [ln for ln in path.read_text().splitlines() if ln and not ln.startswith("#")]
    assert len(lines) == len(PARAM_SPECS)
    assert all(len(ln.split("\t")) == 5 for ln in lines)
    q = PX4Params.load(path)
    assert dict(q) == dict(p)


def test_load_plain_name_value_lines_on_defaults(tmp_path) -> None:
    path = tmp_path / "y.params"
    path.write_text("# my tuning\nMPC_XY_P 1.3\n\nMC_ROLL_P\t7.0  # comment\n")
    q = PX4Params.load(path)
    assert q["MPC_XY_P"] == 1.3 and q["MC_ROLL_P"] == 7.0
    assert q["MC_ROLLRATE_P"] == PARAM_SPECS["MC_ROLLRATE_P"].default  # base = PX4 defaults


def test_shipped_s500_file_matches_s500_set() -> None:
    assert dict(PX4Params.load(S500_PARAMS_FILE)) == dict(PX4Params.s500())
    assert dict(PX4Params.coerce(str(S500_PARAMS_FILE))) == dict(PX4Params.s500())


def test_unknown_name_suggests_closest() -> None:
    with pytest.raises(ValueError, match="did you mean MC_ROLLRATE_P"):
        PX4Params(MC_ROLRATE_P=0.1)
    with pytest.raises(ValueError, match="did you mean MPC_XY_VEL_P_ACC"):
        PX4Params.s500({"MPC_XY_VEL_P": 2.0})


def test_out_of_range_and_bad_values_refused(tmp_path) -> None:
    with pytest.raises(ValueError, match=r"MPC_XY_P=5 is out of range \[0, 2\]"):
        PX4Params(MPC_XY_P=5)
    with pytest.raises(ValueError, match="must be finite"):
        PX4Params(MC_ROLL_P=float("nan"))
    with pytest.raises(ValueError, match="must be a number"):
        PX4Params(MC_ROLL_P="fast")
    bad = tmp_path / "bad.params"
    bad.write_text("MPC_XY_P 0.9\nMPC_TILTMAX_AIR 120\n")
    with pytest.raises(ValueError, match=r"bad.params:2: .*MPC_TILTMAX_AIR=120 is out of range"):
        PX4Params.load(bad)
    bad.write_text("MPC_XY_P\n")
    with pytest.raises(ValueError, match="bad.params:1: expected"):
        PX4Params.load(bad)
    with pytest.raises(ValueError, match="does not exist"):
        PX4Params.load(tmp_path / "missing.params")
