"""Disturbance observers on recorded flights: PX4 ULog (``.ulg``) and MAVLink telemetry (``.tlog``) logs.

``fawtgym observe LOG --observer ffts_eso,leso --vehicle x500`` runs registered observers
(:mod:`fawtgym.observers`) on what a flight controller recorded and writes the estimated disturbance
force (world NED) and torque (body FRD) over time, figures and a per-phase summary.  One module per job:

=================== ============================================================================
module              job
=================== ============================================================================
:mod:`.logdata`     :class:`FlightLog`: topics as time series (seconds), parameters, version
:mod:`.ulog`        read a PX4 ULog with pyulog (PX4's own parser)
:mod:`.tlog`        read a MAVLink ``.tlog`` with pymavlink, mapped onto PX4 topic names
:mod:`.topics`      which topic gives what, in which PX4 versions; one-line missing-topic errors
:mod:`.timebase`    one time grid at the observer rate; sample-and-hold, no look-ahead
:mod:`.inputs`      known thrust/torque: motor commands or setpoints through the vehicle's motor model
:mod:`.phases`      armed/airborne from the log's land detector; ground/climb/hover/...; flight modes
:mod:`.runner`      run the observers over the airborne segments (batch-first, N = 1)
:mod:`.outputs`     CSV/Parquet, per-phase summary, figures
:mod:`.synth_tlog`  a test ``.tlog`` written from our own env (known truth)
:mod:`.cli`         ``fawtgym observe``
=================== ============================================================================
"""

from .errors import FlightLogError
from .logdata import FlightLog, Topic, read_log

__all__ = ["FlightLog", "FlightLogError", "Topic", "read_log"]
