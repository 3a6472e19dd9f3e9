"""Talking to the bender: the TinyG protocol and streamer, cameras, the session.

Modules: ``protocol`` (TinyG's JSON protocol), ``transport`` (serial,
``socket://``, ``sim://``), ``stream`` (flow control, journal, resume), ``camera``
(gphoto2, watched folder), ``session`` (the automatic calibration session) and
``session_report`` (its plots and HTML report). The material calibration it fits
and compensates with is :mod:`cvmeasure.material`; jobs are made from designs by
:mod:`cvmeasure.gcode` (the driver streams them); the TinyG double behind
``sim://`` is :mod:`cvmeasure.testing`, which the driver never imports (``sim://``
is a pyserial URL handler).
"""

__all__: list[str] = []
