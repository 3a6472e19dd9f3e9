"""Talking to the bender: G-code, the TinyG protocol and streamer, cameras, the session.

Modules: ``gcode`` (designs -> compensated G-code), ``protocol`` (TinyG's JSON
protocol), ``transport`` (serial, ``socket://``, ``sim://``), ``stream`` (flow
control, journal, resume), ``camera`` (gphoto2, watched folder), ``session``
(the automatic calibration session) and ``session_report`` (its plots and HTML report). The material
calibration it fits and compensates with is :mod:`cvmeasure.material`; the
TinyG double behind ``sim://`` is :mod:`cvmeasure.testing`, which the driver never
imports (``sim://`` is a pyserial URL handler).
"""

__all__: list[str] = []
