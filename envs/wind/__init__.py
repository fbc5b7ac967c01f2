"""Wind fields: still air, Dryden turbulence, the fan-array wind tunnel (FAWT), outdoor presets.

Registered names (``make_wind(name)`` or ``make_wind({"name": ..., **options})``):

* ``calm``: still air.
* ``fawt-30`` ... ``fawt-70``: the Wang et al. (2024) Table 3 FAWT presets (duty 30-70 %); ``fawt`` takes
  ``duty`` as a fraction in [0, 1] (interpolated inside [0.3, 0.7], policy outside, see
  :mod:`.fawt`).  Options: ``on_time``, ``off_time``, ``spin_tau``, ``spin_down_tau``,
  ``length_scale``, ``form``, ``rates``, ``span``, ``turbulence``, ``discretization``.
* ``dryden-light`` / ``-moderate`` / ``-severe``: MIL-spec low-altitude turbulence (:mod:`.outdoor`);
  options ``altitude``, ``form``, ``mean_wind``, ``direction_deg``, ``length_scale``, ``rates``, ``span``.
* ``gust-1cos``: discrete 1-cosine gust; options ``amplitude``, ``length``, ``speed``,
  ``start_time``, ``direction_deg``, ``shape``.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from fawtgym.core.checks import check_known, keyword_names, shown

from .base import CalmWind, WindModel, make_wind, register_wind, wind_names
from .dryden import DrydenParams, dryden_psd
from .dryden_process import DrydenProcess
from .fawt import TABLE3, FawtWind, fawt_statistics
from .outdoor import DrydenWind, OneCosineGust
from .schedule import FanSchedule


def _checked(name: str, cls: Callable[..., WindModel], *fixed: Any) -> Callable[..., WindModel]:
    """Factory for ``name``: unknown option names raise ValueError listing the valid ones."""
    params = keyword_names(cls)[len(fixed):]

    def factory(**options: Any) -> WindModel:
        hint = " (its duty is fixed; use the 'fawt' wind with duty=...)" if "duty" in options and fixed else ""
        check_known(options, params, f"wind {shown(name)}", hint)
        return cls(*fixed, **options)

    factory.__doc__ = f"{name}: {cls.__doc__}"
    return factory


for _duty in sorted(TABLE3):
    _name = f"fawt-{round(_duty * 100)}"
    register_wind(_name, _checked(_name, FawtWind, _duty))
register_wind("fawt", _checked("fawt", FawtWind))
for _level in ("light", "moderate", "severe"):
    register_wind(f"dryden-{_level}", _checked(f"dryden-{_level}", DrydenWind, _level))
register_wind("gust-1cos", _checked("gust-1cos", OneCosineGust))
register_wind("calm", _checked("calm", CalmWind))  # (base registers the bare class: it takes no options)

__all__ = ["TABLE3", "CalmWind", "DrydenParams", "DrydenProcess", "DrydenWind", "FanSchedule", "FawtWind",
           "OneCosineGust", "WindModel", "dryden_psd", "fawt_statistics", "make_wind", "register_wind",
           "wind_names"]
