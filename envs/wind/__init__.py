"""Wind fields: still air, Dryden turbulence, the fan-array wind tunnel (FAWT), outdoor presets."""

from .base import CalmWind, WindModel, make_wind, register_wind, wind_names

__all__ = ["CalmWind", "WindModel", "make_wind", "register_wind", "wind_names"]
