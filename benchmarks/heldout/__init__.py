"""Held-out models of the bender, its wire and its controller, written from physics and the
firmware's documentation.

Nothing here imports ``cvmeasure``: these models are the other side of the wire and the
machine that the project's code is measured against, so they must not share its
assumptions. Code under test must never import this package.
"""
