"""Boolean options are booleans: a truthy stand-in ("False", -1, 1.0) is refused with the option's name."""

import numpy as np
import pytest

from fawtgym.core.checks import check_flag
from fawtgym.envs.hover_batch_env import HoverBatchEnv
from fawtgym.envs.wind import make_wind


@pytest.mark.parametrize("value", [True, False, np.bool_(True), np.bool_(False)])
def test_booleans_pass(value: object) -> None:
    assert check_flag(value, "x") is bool(value)


@pytest.mark.parametrize("value", ["False", "True", -1, 0, 1, 1.0, None, [True]])
def test_stand_ins_are_refused_by_name(value: object) -> None:
    with pytest.raises(ValueError, match=r"^turbulence must be True or False, got "):
        check_flag(value, "turbulence")


@pytest.mark.parametrize("wind, name", [({"name": "fawt", "duty": 0.5, "turbulence": "False"}, "turbulence"),
                                        ({"name": "fawt", "duty": 0.5, "rates": -1}, "rates"),
                                        ({"name": "dryden-moderate", "rates": "no"}, "rates")])
def test_wind_options_refuse_stand_ins(wind: dict, name: str) -> None:
    with pytest.raises(ValueError, match=rf"{name} must be True or False"):
        make_wind(wind)


@pytest.mark.parametrize("n", [1, 3])
def test_env_gives_the_same_error_at_every_batch_size(n: int) -> None:
    with pytest.raises(ValueError, match=r"turbulence must be True or False, got 'False' \(str\)"):
        HoverBatchEnv(num_envs=n, wind={"name": "fawt", "duty": 0.5, "turbulence": "False"})
