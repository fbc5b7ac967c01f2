"""MAVLink SITL hook: our env as PX4's simulator, and the replay of an agent through an autopilot.

Two hooks, both speaking real MAVLink through pymavlink (extra ``sitl``):

* :mod:`.bridge` (``fawtgym sitl px4``): a TCP server implementing the simulator side of PX4's
  ``simulator_mavlink`` module (HIL_SENSOR / HIL_GPS out, HIL_ACTUATOR_CONTROLS in, lockstep), with the
  physics, wind and sensors of :class:`fawtgym.envs.hover_env.HoverEnv` (:mod:`.plant`).
* :mod:`.replay` (``fawtgym replay``): a companion-computer client that connects to an autopilot, switches to
  OFFBOARD (PX4) or GUIDED_NOGPS (ArduPilot), arms, and flies an agent of the agent grammar on the
  autopilot's telemetry through SET_ATTITUDE_TARGET, with a ``.tlog`` of all traffic and safety aborts.

The unit and frame conversions between MAVLink fields and our measurement mapping live in one tested module,
:mod:`.convert`; the vehicle preset that matches PX4's airframe, with the motor numbering pinned, in
:mod:`.airframe`.  ``docs/sitl.md`` has the PX4 commands.
"""
