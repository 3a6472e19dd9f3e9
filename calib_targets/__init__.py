"""Printable calibration targets at exact physical scale: ChArUco boards and marker-kit sheets."""

__all__: list[str] = []
