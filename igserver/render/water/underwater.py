"""The sea from under its surface (docs/water.md#under-water): when the eye is below the local surface
(the host's height query at its xy, the same sum of waves the mesh draws), the water program is
compiled with WATER_UNDERWATER (water/underwater.glsl: Snell's window, total internal reflection,
Jerlov type II attenuation and scattering, the bed) and a full-screen pass (water/underwater.frag.glsl)
fills what the mesh leaves: the column, the bed, the surface missed by the near plane. Above the
surface nothing here runs, so every frame with the eye in the air is what it was."""

from __future__ import annotations

import numpy as np

from ...scene.model import Scene
from ...water.bathymetry import depth_at
from ...water.surface import SeaSurface

BED_SLOPE_STEP = 10.0  # m: the bed's plane is fitted to the depths this far either side of the eye
DEEP_BED = 1e4  # m below the eye: no bed seen (the water is opaque past ~110 m)


def eye_depth(scene: Scene, sea: SeaSurface, eye) -> float:
    """Metres of water above the eye (< 0: the eye is in the air): the surface height at the eye's xy
    (``SeaSurface.query``) less the eye's height above the mean level."""
    surface = float(sea.query(np.asarray(eye[:2], dtype=np.float64)[None], scene.time.sim_time)["height"][0])
    return surface - (float(eye[2]) - scene.ocean.level)


def bed_plane(scene: Scene, eye) -> tuple[float, float, float]:
    """The bed near the eye as the plane z = a + b x + c y in camera-relative metres: the bathymetry's
    depth at the eye and its slope over ±BED_SLOPE_STEP (exact for the plane beach, uniform depth
    gives a level bed; deeper than DEEP_BED is no bed)."""
    bathy = scene.ocean.bathymetry
    x, y, z = (float(v) for v in eye)
    s = BED_SLOPE_STEP
    pts = np.array([[x, y], [x + s, y], [x - s, y], [x, y + s], [x, y - s]])
    d = depth_at(bathy, pts)
    level_z = scene.ocean.level - z
    depth0 = float(d[0])
    if depth0 > DEEP_BED:
        return (level_z - 2.0 * DEEP_BED, 0.0, 0.0)
    # the bed's height is -depth: its slope is minus the depth's
    return (level_z - depth0, -float(d[1] - d[2]) / (2.0 * s), -float(d[3] - d[4]) / (2.0 * s))


def underwater_uniforms(scene: Scene, eye, reach: float) -> dict:
    """The values of water/underwater.glsl's uniforms (and the fill's highest-crest reach, m)."""
    return {"u_uw_bed": bed_plane(scene, eye), "u_uw_level_z": float(scene.ocean.level - float(eye[2])),
            "u_uw_reach": float(reach)}
