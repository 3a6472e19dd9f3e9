"""Test and demo doubles: the TinyG double behind ``sim://``.

Modules: ``double`` (:class:`~cvmeasure.testing.double.FakeTinyG`, a TinyG-like
board on a pseudo-terminal), ``double_firmware`` and ``double_records`` (its
firmware layer and records), ``protocol_sim`` (the pyserial URL handler that
serves ``sim://`` ports) and ``bender`` (the double behind the session's
streamer). The driver never imports this package: :mod:`cvmeasure.driver.transport`
only names it in pyserial's ``protocol_handler_packages``, so pyserial imports
``protocol_sim`` the first time a ``sim://`` URL is opened.
"""

__all__: list[str] = []
