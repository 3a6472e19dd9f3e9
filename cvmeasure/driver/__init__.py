"""Driving the bender: calibration sessions, compensation, G-code, streaming, cameras.

Modules: ``calibration`` (the ``diwire-material/1`` calibration JSON),
``compensation`` (springback and motion curves), ``camera`` (gphoto2, watched
folder, simulated), ``session`` (the automatic calibration session),
``session_report`` (plots and the HTML report), ``session_demo`` (its demo
stage), and the G-code / protocol / streaming / transport / double modules of
the bender side.
"""

__all__: list[str] = []
