"""Held-out models of the bender's controller, written from the firmware's documentation.

Nothing here imports ``cvmeasure``: these models are the other side of the wire that the
project's streaming code is measured against, so they must not share its assumptions.
"""
