"""Depth from 1 mm to 10,000 km: reversed-Z, float depth, an infinite far plane.

Each stiff case is a regression test here: a far plane of 1e7 m renders the sky, the
ground and the sea; boxes a few tens of metres apart at 5 km and 80 km occlude in the right order
(and, generally, objects 0.1 % of their distance apart from 1 m to 100 km); from 100 km up the sea
reaches its horizon with no holes; no dark line on the sea horizon at narrow fields of view.
Occlusion is read from the view-distance target (what the winning surface wrote), which does not
depend on haze or colour.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from igserver.render.camera import make_view
from igserver.scene import load_scene

from helpers import luminance, tiny

SEA_LEVEL = -0.5  # the ocean's default level (m)
EARTH_RADIUS = 6.371e6  # m, the sea sphere of surfaces/plane.glsl
SKY = 1e29  # the distance target holds 1e30 where the sky shows


def _render(renderer, patch, w=64, h=36):
    rgba = renderer.render(tiny(patch, w, h)).rgba
    hdr = renderer.read_hdr()
    assert np.isfinite(hdr).all(), "NaN/Inf in the HDR target"
    return rgba, renderer.read_distance()


def test_clip_control_and_float_depth_are_in_effect(renderer):
    # llvmpipe implements GL 4.5, so clip control must take; the depth buffer is float32.
    assert renderer.reversed_z
    renderer.render(tiny())
    assert renderer.targets_for(64, 36).float_depth


def test_both_clip_ranges_give_window_depth_near_over_distance():
    # The projection's promise (render/depth.py): window depth = near / d in either clip range.
    cam = tiny({"camera": {"near": 0.25, "heading": 30, "pitch": 10}}).camera
    for zero_to_one in (True, False):
        view = make_view(cam, zero_to_one)
        for d in (0.25, 3.0, 4e3, 2e6):
            rel = view.forward * d
            clip = view.view_proj @ np.append(rel, 1.0)
            ndc = clip[2] / clip[3]
            window = ndc if zero_to_one else 0.5 * ndc + 0.5
            assert window == pytest.approx(0.25 / d, rel=1e-9, abs=1e-15)
        clip = view.view_proj @ np.append(view.forward, 0.0)  # a direction: at infinity
        assert (clip[2] / clip[3] if zero_to_one else 0.5 * clip[2] / clip[3] + 0.5) == 0.0


@pytest.mark.parametrize("near,far", [(1e-3, 1e7), (1e-3, 1.0), (0.1, 1e6), (1e4, 1e7)])
@pytest.mark.parametrize("surface", ["ocean", "ground"])
def test_any_near_far_renders_sky_and_surface(renderer, near, far, surface):
    patch = {"camera": {"near": near, "far": far, "pitch": -3.0, "fov_y": 40},
             "time": {"sun_override": {"elevation": 35, "azimuth": 200}}}
    if surface == "ocean":
        patch["ocean"] = {"enabled": True}
    rgba, dist = _render(renderer, patch)
    lum = luminance(rgba)
    # Top rows: sky (a day sky at sun 35 deg is far from black); bottom rows: the surface.
    assert (dist[:4] > SKY).all() and lum[:4].mean() > 40
    assert (dist[-6:] < SKY).all() and lum[-6:].mean() > 8


def test_sky_only_with_far_1e7_is_not_black(renderer):
    scene = load_scene("sky_only")
    scene = scene.model_copy(update={"camera": scene.camera.model_copy(update={"far": 1e7, "width": 64, "height": 36})})
    rgba = renderer.render(scene).rgba
    assert luminance(rgba).mean() > 40  # the black frame had mean 0


def _two_boxes(distance: float, gap: float, near: float, far: float, camera_z: float = 10.0) -> dict:
    """A small near box whose front face is on the view axis at ``distance`` and a larger box whose
    front face is ``gap`` further, listed (and so drawn) FIRST: draw order cannot hide a depth error."""
    s = 0.02 * distance  # 1.1 deg: ~18 px of the 4 deg field
    return {
        "camera": {"near": near, "far": far, "position": [0.0, 0.0, camera_z], "fov_y": 4.0},
        "atmosphere": {"visibility": 200_000.0},
        "time": {"sun_override": {"elevation": 40, "azimuth": 200}},
        "entities": [
            {"id": "far", "position": [0.0, distance + gap + 1.5 * s, camera_z - 1.5 * s], "scale": [3 * s, 3 * s, 3 * s]},
            {"id": "near", "position": [0.0, distance + 0.5 * s, camera_z - 0.5 * s], "scale": [s, s, s]},
        ],
    }


@pytest.mark.parametrize("distance,gap,near,far", [
    (5_000.0, 40.0, 0.01, 1e5),   # the case
    (80_000.0, 40.0, 0.01, 1e6),  # the second distance
])
def test_boxes_tens_of_metres_apart_far_away_occlude(renderer, distance, gap, near, far):
    _, dist = _render(renderer, _two_boxes(distance, gap, near, far), 64, 64)
    centre = dist[30:34, 30:34]
    # On the axis the near box's face is at `distance`; the far box's at `distance + gap`: the
    # middle of the two separates them.
    assert (centre < distance + gap / 2).all(), centre


@pytest.mark.parametrize("distance", [1.0, 100.0, 1e4, 1e5])
def test_objects_a_thousandth_of_their_distance_apart_resolve(renderer, distance):
    # Extreme clip planes the model accepts: near 1 mm, far 1e7 m.
    _, dist = _render(renderer, _two_boxes(distance, 1e-3 * distance, 1e-3, 1e7), 64, 64)
    centre = dist[30:34, 30:34]
    assert (centre < distance * (1 + 0.5e-3)).all(), centre


def test_sea_from_100_km_reaches_its_horizon_without_holes(renderer):
    h = 100_000.0
    rgba, dist = _render(renderer, {"camera": {"position": [0.0, 0.0, h], "pitch": -12.0, "fov_y": 40},
                                    "ocean": {"enabled": True},
                                    "time": {"sun_override": {"elevation": 30, "azimuth": 200}}}, 96, 54)
    sea = dist < SKY
    # Below the first sea row of each column everything is sea: no speckles of sky in the sea.
    for col in range(sea.shape[1]):
        rows = np.nonzero(sea[:, col])[0]
        assert rows.size and sea[rows[0]:, col].all(), f"hole in the sea, column {col}"
    # The far plane (default 1e6 m) does not clip the sea: its geometric horizon is at
    # sqrt(2 R h + h^2) ~ 1.13e6 m; the last sea pixel's centre lies short of that (the distance
    # grows steeply at grazing incidence) but beyond the old clip at 1e6 m.
    horizon = math.sqrt(2 * EARTH_RADIUS * (h - SEA_LEVEL) + h * h)
    far = tiny().camera.far
    assert horizon > 1.1 * far and dist[sea].max() > 1.02 * far
    # No seam: along each column the sea's brightness changes gradually (a clipped ring made a
    # step of tens of levels; the smooth gradient changes by a few per row at this size).
    lum = luminance(rgba)
    for col in range(0, sea.shape[1], 8):
        rows = np.nonzero(sea[:, col])[0]
        steps = np.abs(np.diff(lum[rows[0] + 2:, col]))
        assert steps.max() < 12, (col, steps.max())


@pytest.mark.parametrize("fov", [1.0, 0.2])
@pytest.mark.parametrize("height", [2.0, 10.0, 300.0])
def test_no_dark_line_on_the_sea_horizon_at_narrow_fov(renderer, fov, height):
    dip = math.degrees(math.acos(EARTH_RADIUS / (EARTH_RADIUS + height - SEA_LEVEL)))
    rgba, _ = _render(renderer, {"camera": {"position": [0.0, 0.0, height], "pitch": -dip, "fov_y": fov},
                                 "ocean": {"enabled": True}, "atmosphere": {"visibility": 200_000.0},
                                 # glassy (wind 0): waves seen through a 0.2-1 deg telescope are rows of
                                 # crests and troughs; the seam this guards against is the horizon's
                                 "weather": {"wind_speed": 0.0},
                                 "time": {"sun_override": {"elevation": 20, "azimuth": 200}}}, 32, 96)
    rows = luminance(rgba).mean(axis=1)
    # A line: a row darker than both neighbours. Sky and sea meet in a gradient with at most a
    # small step; the regression was a row ~100 levels darker.
    dips = np.minimum(rows[:-2], rows[2:]) - rows[1:-1]
    assert dips.max() < 3.0, (int(np.argmax(dips)) + 1, dips.max())
