"""Sun, moon and stars from date, time and location (PyEphem)."""

from .ephemeris import CelestialState, celestial_state, direction_enu
from .stars import StarField, star_field

__all__ = ["CelestialState", "StarField", "celestial_state", "direction_enu", "star_field"]
