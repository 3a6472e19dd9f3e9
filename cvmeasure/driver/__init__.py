"""Talking to the bender: G-code, the TinyG protocol and streamer, cameras, the session.

Modules: ``gcode`` (designs -> compensated G-code), ``protocol`` (TinyG's JSON
protocol), ``transport`` (serial, ``socket://``, ``sim://``), ``stream`` (flow
control, journal, resume), ``double`` (the TinyG double behind ``sim://``),
``camera`` (gphoto2, watched folder), ``session`` (the automatic calibration
session) and ``session_report`` (its plots and HTML report). The material
calibration it fits and compensates with is :mod:`cvmeasure.material`.
"""

__all__: list[str] = []
