"""MuJoCo vehicle model, vehicle presets, wind + aerodynamics, sensors, Gymnasium envs."""

from .vehicles import VEHICLE_NAMES, VehiclePreset, make_vehicle

__all__ = ["VEHICLE_NAMES", "VehiclePreset", "make_vehicle"]
