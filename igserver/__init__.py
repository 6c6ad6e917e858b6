"""igserver: a network image generator for training simulators."""

__version__ = "0.1.0"
