"""The sun's disk as displayed: a setting sun stays orange-red when it overexposes, a high sun white.

The disk's radiance is the sun's through the view's transmittance (test_atmosphere_light.py: within
0.8-1.2 of the light it casts; at a fixed EV 18 the setting sun is red, (157, 35, 1)). At automatic
exposure the same disk is ~140x the sky beside it, and a per-channel tone curve, saturating red and
then green, showed it lemon-yellow (255, 245, 98) while the eye sees the setting sun orange-red
(the reddening of the setting sun in Minnaert, "Light and Colour in the Open Air", 1954; the
display keeps the hue of what it cannot show the brightness of)."""

from __future__ import annotations

import numpy as np

from igserver.render.camera import make_view
from igserver.render.frame import sun_and_moon
from igserver.scene import apply_patch
from igserver.scene.files import load_scene


def disk_pixel(renderer, scene) -> np.ndarray:
    """The brightest displayed pixel within 3 px of where the sun's direction projects."""
    rgba = renderer.render(scene).rgba[..., :3].astype(float)
    h, w = rgba.shape[:2]
    clip = make_view(scene.camera).view_proj @ np.append(np.asarray(sun_and_moon(scene).sun_dir) * 1e6, 1.0)
    col, row = int((clip[0] / clip[3] * 0.5 + 0.5) * w), int((0.5 - clip[1] / clip[3] * 0.5) * h)
    win = rgba[row - 3:row + 4, col - 3:col + 4].reshape(-1, 3)
    return win[np.argmax(win.sum(axis=1))]


def test_an_overexposed_setting_sun_is_displayed_orange_not_yellow(renderer):
    # The view (sun 0.47 deg up through 30 km visibility, automatic exposure). Bound: green
    # under 0.75 of red in sRGB (orange; measured 0.34, (246, 84, 38)); yellow was 0.96.
    s = apply_patch(load_scene("sea_calm_dawn"), {
        "camera": {"position": [0.0, 0.0, 15.0], "heading": 300.0, "pitch": 2.0},
        "time": {"utc": "2026-06-21T19:17:20Z"}})
    p = disk_pixel(renderer, s)
    assert p[0] > 200.0 and p[1] < 0.75 * p[0], p


def test_a_high_sun_stays_white(renderer):
    # 30 deg up: every channel saturated, as before (only a disk with green under half its red, a sun
    # within a few degrees of the horizon, is displayed with its hue kept).
    s = apply_patch(load_scene("sea_calm_dawn"), {
        "camera": {"position": [0.0, 0.0, 15.0], "heading": 180.0, "pitch": 30.0, "width": 160, "height": 90},
        "time": {"sun_override": {"elevation": 30.0, "azimuth": 180.0}}})
    assert np.all(disk_pixel(renderer, s) >= 254.0), disk_pixel(renderer, s)
