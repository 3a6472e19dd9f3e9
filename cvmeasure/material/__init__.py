"""Material calibration and compensation: what the wire does, fitted from measured bends.

``calibration`` (the ``diwire-material/1`` calibration JSON: raw samples and fitted
models) and ``compensation`` (springback and motion curves, their fits and scores).
It sits beside :mod:`cvmeasure.sim` (the forward model) and :mod:`cvmeasure.diagnose`
(what the model gets wrong); :mod:`cvmeasure.driver` (talking to the bender) uses it
to compensate G-code and to fit what a session measured.
"""

__all__: list[str] = []
