"""``fawtgym bench render``: frames per second of ``HoverEnv.render()`` against MuJoCo's default render quality.

Both are measured in one run on the same scene (the vehicle in FAWT-50 wind in front of the fan
array, :mod:`fawtgym.envs.render`): the env's settings (no multisampling, no shadow map or
reflections, 12 slices per round geom) and MuJoCo's defaults (4x multisampling, a 4096 shadow map,
reflections, 28 slices), so the ratio does not depend on the machine's load.  On a machine without a
GPU the offscreen renderer runs on the CPU (EGL or OSMesa on llvmpipe), where these settings matter.
"""

from __future__ import annotations

import os
import re
import time
from collections.abc import Sequence
from typing import TYPE_CHECKING

import mujoco

from fawtgym.cli_parser import ArgumentParser, positive_int

if TYPE_CHECKING:
    from fawtgym.envs.hover_env import HoverEnv

#: MuJoCo's default <quality> (what the env's model overrides)
MUJOCO_DEFAULT_QUALITY = '<quality offsamples="4" shadowsize="4096" numslices="28" numstacks="16"/>'


def frames_per_second(env: HoverEnv, frames: int, rounds: int) -> float:
    """Best of ``rounds`` of ``frames`` renders of the env's current state."""
    env.render()  # first frame: context and scene set-up, not timed
    best = float("inf")
    for _ in range(rounds):
        t = time.perf_counter()
        for _ in range(frames):
            env.render()
        best = min(best, time.perf_counter() - t)
    return frames / best


def _make(width: int, height: int, default_quality: bool) -> HoverEnv:
    from fawtgym.envs.hover_env import HoverEnv
    from fawtgym.envs.mjcf import vehicle_mjcf

    env = HoverEnv(wind={"name": "fawt-50", "on_time": 0.0}, render_mode="rgb_array", render_width=width,
                   render_height=height, control_rate=200.0, init_noise=0.0)
    if default_quality:  # the same model with MuJoCo's default quality
        text = re.sub(r"<quality [^>]*/>", MUJOCO_DEFAULT_QUALITY,
                      vehicle_mjcf(env.preset, env.physics_dt, "Euler", width, height))
        env.model = mujoco.MjModel.from_xml_string(text)
        env.data = mujoco.MjData(env.model)
    env.reset(seed=0)
    env.step(env.hover_action())
    env.render()
    renderer = env._renderer
    if renderer is None:
        raise RuntimeError("HoverEnv.render() made no renderer")
    renderer.shadows = renderer.reflections = default_quality
    return env


def main(argv: Sequence[str] | None = None) -> int:
    parser = ArgumentParser(prog="fawtgym bench render", description=__doc__.split("\n\n")[0])
    parser.add_argument("--frames", type=positive_int, default=20, help="frames per round (default 20)")
    parser.add_argument("--rounds", type=positive_int, default=3, help="timing rounds, best kept (default 3)")
    parser.add_argument("--width", type=positive_int, default=480, help="frame width [px] (default 480)")
    parser.add_argument("--height", type=positive_int, default=480, help="frame height [px] (default 480)")
    ns = parser.parse_args(list(argv) if argv is not None else None)
    results = {}
    for label, default in (("env settings", False), ("MuJoCo defaults", True)):
        env = _make(ns.width, ns.height, default)
        results[label] = frames_per_second(env, ns.frames, ns.rounds)
        env.close()
    print(f"HoverEnv.render(), {ns.width} x {ns.height}, fan array + wind + height cue, MUJOCO_GL="
          f"{os.environ.get('MUJOCO_GL', '(unset)')}:")
    for label, fps in results.items():
        print(f"  {label:16s} {fps:8.1f} frames/s")
    print(f"  ratio env / MuJoCo defaults: {results['env settings'] / results['MuJoCo defaults']:.2f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
