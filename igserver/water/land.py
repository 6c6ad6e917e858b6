"""The land behind a plane beach (``bathymetry.type = "slope"``): the dry side of the same profile, so
the picture (render/water/shore.glsl ``land_profile``, the same formulas in float32) and the host's
height queries (CIGI HAT/HOT: cigi/queries.py) see one beach.

Across the shore, at s metres inland of the still-water line (a beach profile as drawn in Komar,
Beach Processes and Sedimentation, fig. 2-1; Short 1999 for the dimensions):

* the **foreshore**, the bed's own plane continued: z = β s, up to the berm crest ``berm_height``
  (1-3 m above mean sea level on sandy beaches), at s_b = berm_height / β;
* the **backshore**, nearly flat (BACKSHORE_SLOPE), BACKSHORE_M wide on average, level from the
  dune's foot on;
* a **foredune ridge**: ``dune_height`` (foredunes are 2-20 m) reached over DUNE_RISE_M by a
  smoothstep, then falling back by DUNE_LEE of its height over DUNE_FALL_M to the flat hinterland.

Along the shore the dune's height and the backshore's width vary by a few sines (periods that divide
LAND_PERIOD, so the shader gets the camera's along-shore coordinate modulo it without a jump): a
ridge, not a ruler-straight wall. The land is smooth (C0 at the berm crest, where real beaches have
their break of slope, C1 elsewhere) and drawn by the sea mesh's vertices, so it carries no detail
below the mesh's spacing; sand and grass are the shader's colours.
"""

from __future__ import annotations

import math

import numpy as np

from .bathymetry import _unit

BACKSHORE_SLOPE = 0.005
BACKSHORE_M = 40.0  # mean width of the backshore, m
BACKSHORE_SWING = 0.3  # its width varies by +-30 % along the shore
DUNE_RISE_M = 35.0  # foot to crest, m
DUNE_FALL_M = 80.0  # crest to hinterland, m
DUNE_LEE = 0.3  # the hinterland lies 30 % of the dune's height below its crest
LAND_PERIOD = 1000.0  # m: every along-shore variation repeats on it
# (amplitude, cycles per LAND_PERIOD, phase rad) of the dune height's along-shore variation, and of the
# backshore width's
DUNE_SINES = ((0.2, 6, 0.7), (0.1, 17, 2.1))
BACKSHORE_SINE = (BACKSHORE_SWING, 4, 0.0)


def _smoothstep(e0: float, e1: float, x):
    t = np.clip((x - e0) / (e1 - e0), 0.0, 1.0)
    return t * t * (3.0 - 2.0 * t)


def _wave(sines, y):
    return sum(a * np.sin(2.0 * math.pi * n * y / LAND_PERIOD + phase) for a, n, phase in sines)


def profile(s, y, slope: float, berm_height: float, dune_height: float) -> np.ndarray:
    """Height (m above the still water level) of the land s m inland of the still-water line at the
    world along-shore coordinate y (m); offshore (s < 0) the bed's plane, β s."""
    s = np.asarray(s, dtype=np.float64)
    y = np.asarray(y, dtype=np.float64)
    s_b = berm_height / slope
    foot = s_b + BACKSHORE_M * (1.0 + _wave((BACKSHORE_SINE,), y))
    z = np.where(s <= s_b, slope * s, berm_height + BACKSHORE_SLOPE * (np.minimum(s, foot) - s_b))
    height = dune_height * (1.0 + _wave(DUNE_SINES, y))
    u = s - foot
    ridge = _smoothstep(0.0, DUNE_RISE_M, u) - DUNE_LEE * _smoothstep(DUNE_RISE_M, DUNE_RISE_M + DUNE_FALL_M, u)
    return z + height * ridge


def shore_axes(bathy) -> tuple[np.ndarray, np.ndarray]:
    """(unit toward the shore, unit along it) of a slope beach, world x east, y north."""
    to_shore = _unit(bathy.shore_heading)
    return to_shore, np.array([to_shore[1], -to_shore[0]])


def land_elevation(bathy, xy) -> np.ndarray:
    """Height (m above the still water level) of the ground at world points (..., 2): the land and the
    bed of a slope beach (NaN for other bathymetries: no land is modelled there)."""
    xy = np.asarray(xy, dtype=np.float64)
    if bathy.type != "slope":
        return np.full(xy.shape[:-1], np.nan)
    to_shore, along = shore_axes(bathy)
    s = xy @ to_shore - bathy.shore_distance
    z = profile(s, xy @ along, bathy.slope, bathy.berm_height, bathy.dune_height)
    return np.maximum(z, -bathy.depth)
