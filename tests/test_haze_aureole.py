"""A low sun through haze: the haze on the horizon under the sun is lit by the sky around the sun.

The near-ground layer (sky/haze.py) held the clear sky's light as isotropic flux (a two-stream
model). Under a sun 0.47 deg up through 30 km visibility the direct sun reaching the low haze has
crossed ~63 air masses of it (optical depth ~8.5) and is gone; the light that lights the haze there
comes from the bright sky 2-20 deg up around the sun (the clear air's aureole) through a few air
masses, and the haze (g = 0.7) scatters it forward, toward an eye looking at the sun's azimuth.
Spread isotropically it lit the horizon as the mean sky does: a grey-blue band 14x darker than 6 deg
up, under the brightest sky in view. Photographs and measured sky scans of hazy sunsets show the
horizon toward the sun bright (the aureole reaching down to the horizon): the CIE standard general
skies for turbid atmospheres (ISO 15469 / CIE S 011, types 11-15) have a gradation that brightens
monotonically toward the horizon and an indicatrix peaking at the sun, so in the sun's vertical
nothing darkens toward the horizon. sky/haze_lobe.glsl haze_sky_lobe() scatters the clear sky
that reaches the layer through it (delta-scaled, as the two-stream's own direct part) by the
layer's Henyey-Greenstein phase instead, and moves the same light out of the isotropic term; over
a sea, the sky the sea mirrors into the layer from below (Fresnel at its facets' incidence) likewise.
"""

from __future__ import annotations

import math

import numpy as np

from igserver.photometry import LUMA
from igserver.render.frame import build_frame, sun_and_moon
from igserver.scene import apply_patch
from igserver.scene.files import load_scene

ISSUE = {"camera": {"position": [0.0, 0.0, 15.0], "heading": 300.0, "pitch": 2.0, "width": 480, "height": 270},
         "time": {"utc": "2026-06-21T19:17:20Z"}, "atmosphere": {"visibility_transition": 0.0}}


def luminance_and_angles(renderer, scene):
    """Linear luminance (cd/m^2) of every pixel, its elevation (deg) and its azimuth from the sun (deg)."""
    renderer.render(scene)
    frame = build_frame(renderer.ctx, scene)
    lum = (renderer.read_hdr()[..., :3] / frame.exposure) @ LUMA
    u = frame.uniforms
    h, w = lum.shape
    right, up, fwd = (np.array(u[k]) for k in ("u_camera_right", "u_camera_up", "u_camera_forward"))
    tl, tr, tb, tt = u["u_frustum_tangents"]
    x = tl + (tr - tl) * (np.arange(w) + 0.5) / w
    y = tb + (tt - tb) * (1.0 - (np.arange(h) + 0.5) / h)  # rows top first
    d = fwd + x[None, :, None] * right + y[:, None, None] * up
    d /= np.linalg.norm(d, axis=-1, keepdims=True)
    sun = np.asarray(sun_and_moon(scene).sun_dir)
    elevation = np.degrees(np.arcsin(d[..., 2]))
    azimuth = np.degrees(np.arctan2(d[..., 0], d[..., 1]) - math.atan2(sun[0], sun[1]))
    azimuth = (azimuth + 180.0) % 360.0 - 180.0
    off_sun = np.degrees(np.arccos(np.clip(d @ sun, -1.0, 1.0)))
    return lum, elevation, azimuth, off_sun


def strip(lum, elevation, azimuth, off_sun, lo, hi):
    """Mean luminance of the pixels lo..hi deg up within 15 deg of the sun's azimuth, the sun's disk
    and its glare (1 deg) left out."""
    m = (elevation > lo) & (elevation < hi) & (np.abs(azimuth) < 15.0) & (off_sun > 1.0)
    assert m.sum() > 100, m.sum()
    return float(lum[m].mean())


def test_no_dark_band_on_the_horizon_under_a_low_sun_through_haze(renderer):
    # The issue's view: sun 0.47 deg up, 30 km visibility, the camera 15 m over a calm sea (1 m/s).
    # Strip just above the horizon (0.1-0.9 deg) against 5.5-6.5 deg up. Before: 0.08 (132 against
    # 1860 cd/m^2); now 0.32, the horizon's haze lit by the sky around the sun from above and by the
    # sea mirroring it from below (0.23 with the sky alone; the lobe's 160-tap quadrature within 4 %
    # of a 512-tap one there). Bound 0.25: the 0.32 less 20 % for the quadrature, the tables'
    # interpolation and the platform's float. The darkening that is left is the layer's: looking
    # horizontally the eye sees the haze of the lowest tens of metres (optical depth 13 along the
    # horizon), lit through 1-5 air masses of haze, where 6 deg up it sees the sky through 1.3.
    # Upper bound 1.2: the horizon never outshines the aureole above it (the prototype that spread
    # the whole sky's light by the phase washed the scenes out).
    s = apply_patch(load_scene("sea_calm_dawn"), ISSUE)
    lum, el, az, off = luminance_and_angles(renderer, s)
    ratio = strip(lum, el, az, off, 0.1, 0.9) / strip(lum, el, az, off, 5.5, 6.5)
    assert 0.25 < ratio < 1.2, ratio


def test_the_ground_below_the_horizon_shows_the_same_haze_as_the_sky_above(renderer):
    # One haze function for the sky and for surfaces (common/atmosphere.glsl haze_lobe, read by the
    # sky's haze_ray and by aerial_ray, which fills the surfaces' and the sea's tables). From 300 m
    # over a black ground plane (no sea) the ground 0.1-0.5 deg under the horizon (dip 0.56 deg) lies
    # 17-30 km away, behind haze of optical depth 2-3.5: it shows 0.86-0.97 of the haze's saturated
    # light, plus the clear air in front of it; the sky 0.1-0.5 deg above the horizon shows the haze
    # along the limb (optical depth > 10). Measured 1.04; a surface pass without the lobe: 0.40 (a
    # seam at the horizon); before the lobe 1.64 (the sky's dark band over the ground's haze). Bounds
    # 0.85-1.25.
    s = apply_patch(load_scene("sea_calm_dawn"), {
        **ISSUE, "ocean": {"enabled": False}, "camera": {**ISSUE["camera"], "position": [0.0, 0.0, 300.0], "pitch": 0.0},
        "ground": {"enabled": True, "color": [0.0, 0.0, 0.0], "level": 0.0}})
    lum, el, az, off = luminance_and_angles(renderer, s)
    dip = -math.degrees(math.acos(6360e3 / (6360e3 + 300.0)))
    ratio = strip(lum, el, az, off, dip - 0.5, dip - 0.1) / strip(lum, el, az, off, dip + 0.1, dip + 0.5)
    assert 0.85 < ratio < 1.25, ratio
