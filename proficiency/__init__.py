"""The comparison domain: comparisons, devices, measurement points, reference values."""

__version__ = "0.1.0"
