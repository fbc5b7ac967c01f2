"""fawtgym: quadrotor disturbance-rejection lab (MuJoCo hover env, FAWT wind, ESOs, PX4-style control).

Importing the package registers the Gymnasium env ids (``fawtgym/Hover-v0``, ...).
"""

import os

# Headless MuJoCo rendering: EGL unless the user chose a backend (MUJOCO_GL=egl|osmesa|glfw).
if "MUJOCO_GL" not in os.environ and not os.environ.get("DISPLAY"):
    os.environ["MUJOCO_GL"] = "egl"

from ._registration import ENV_NAMESPACE, register_envs

__version__ = "0.1.0"

register_envs()

__all__ = ["ENV_NAMESPACE", "__version__", "register_envs"]
