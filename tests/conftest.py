"""Shared pytest configuration: headless rendering and a non-interactive matplotlib."""

import os

os.environ.setdefault("MUJOCO_GL", "egl")
os.environ.setdefault("MPLBACKEND", "Agg")
