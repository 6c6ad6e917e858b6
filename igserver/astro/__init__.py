"""Sun, moon and stars from date, time and location (PyEphem)."""

from .ephemeris import CelestialState, celestial_state, direction_enu

__all__ = ["CelestialState", "celestial_state", "direction_enu"]
