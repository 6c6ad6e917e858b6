"""Geodetic (WGS 84 lat/lon/alt) <-> the scene's ENU metres, and body-frame rotations.

The scene is a flat local frame at ``scene.location`` (x east, y north, z up). CIGI positions are
geodetic; they map through a local equirectangular projection on the ellipsoid's radii of curvature at
the origin (x = dlon * (N + h0) cos lat0, y = dlat * (M + h0)), with altitude kept as height: a ship at
0 m MSL is on the scene's flat sea at any distance (an exact tangent plane would sink it 7.8 m at 10 km).
The projection is exact at the origin and inverts exactly; its scale error is below 0.1 % within 50 km.
Altitude is taken as height above MSL = the ellipsoid (no geoid model).
"""

from __future__ import annotations

import math

import numpy as np

WGS84_A = 6_378_137.0  # m, semi-major axis
WGS84_E2 = 6.69437999014e-3  # first eccentricity squared


def _radii(lat_deg: float) -> tuple[float, float]:
    """(M, N): meridional and prime-vertical radii of curvature at ``lat_deg`` (m)."""
    s = math.sin(math.radians(lat_deg))
    w = math.sqrt(1.0 - WGS84_E2 * s * s)
    return WGS84_A * (1.0 - WGS84_E2) / w**3, WGS84_A / w


class LocalFrame:
    """The projection about one origin (``scene.location``)."""

    def __init__(self, lat0: float, lon0: float, alt0: float = 0.0):
        self.lat0, self.lon0, self.alt0 = lat0, lon0, alt0
        m, n = _radii(lat0)
        self.m_per_deg_lat = math.radians(1.0) * (m + alt0)
        # at the poles the east scale vanishes: keep it finite (the scene is then a polar cap, x ~ 0)
        self.m_per_deg_lon = max(math.radians(1.0) * (n + alt0) * math.cos(math.radians(lat0)), 1e-6)

    @classmethod
    def of(cls, location) -> "LocalFrame":
        return cls(location.lat, location.lon, location.altitude)

    def to_enu(self, lat: float, lon: float, alt: float) -> tuple[float, float, float]:
        dlon = (lon - self.lon0 + 180.0) % 360.0 - 180.0  # across the antimeridian the short way
        return (dlon * self.m_per_deg_lon, (lat - self.lat0) * self.m_per_deg_lat, alt - self.alt0)

    def to_geodetic(self, x: float, y: float, z: float) -> tuple[float, float, float]:
        lon = (self.lon0 + x / self.m_per_deg_lon + 180.0) % 360.0 - 180.0
        return (self.lat0 + y / self.m_per_deg_lat, lon, z + self.alt0)


def angles(matrix: np.ndarray) -> tuple[float, float, float]:
    """(heading 0..360, pitch, roll) of a body->ENU rotation (inverse of render.camera.body_to_world)."""
    forward, starboard, up = matrix[:, 1], matrix[:, 0], matrix[:, 2]
    heading = math.degrees(math.atan2(forward[0], forward[1])) % 360.0
    pitch = math.degrees(math.asin(max(-1.0, min(1.0, forward[2]))))
    roll = math.degrees(math.atan2(-starboard[2], up[2]))
    return heading, pitch, roll


def cigi_body(x_forward: float, y_right: float, z_down: float) -> np.ndarray:
    """A CIGI body-axis vector (x forward, y right, z down) in the scene's body axes (starboard, forward, up)."""
    return np.array([y_right, x_forward, -z_down])
