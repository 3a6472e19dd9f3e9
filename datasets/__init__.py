"""Synthetic photos with exact ground truth (the photo lab), and sample data."""

__all__: list[str] = []
