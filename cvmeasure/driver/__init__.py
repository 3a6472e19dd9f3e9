"""Driving the bender: calibration sessions, compensation, G-code, streaming, cameras.

Modules: ``calibration`` (the ``diwire-material/1`` calibration JSON),
``compensation`` (springback and motion curves), ``camera`` (gphoto2, watched
folder, simulated), ``session`` (the automatic calibration session), and the
G-code / protocol / streaming / transport / double modules of the bender side.
"""

__all__: list[str] = []
