"""Pictures from the core pipeline on llvmpipe: pass lists, sky vs time of day, the sun where the
ephemeris puts it, camera-relative precision, no NaN/Inf, and lights falling on the ground."""

import numpy as np
import pytest

from igserver.astro import celestial_state
from igserver.render.camera import make_view
from igserver.render.graph import plan_passes

from helpers import luminance, tiny


def test_pass_list_follows_the_scene(renderer):
    sky_only = tiny({"ground": {"enabled": False}})
    assert plan_passes(sky_only) == ["sky", "post"]
    assert renderer.graph.plan(sky_only) == ["sky", "post"]
    ocean = tiny({"ocean": {"enabled": True}})
    assert "water" in plan_passes(ocean) and "surfaces" not in plan_passes(ocean)
    plain = tiny()
    for absent in ("water", "volumes", "depth_copy", "precip"):
        assert absent not in plan_passes(sky_only) and absent not in plan_passes(plain)
    # An effect behind the camera: no volume pass and no depth copy.
    behind = tiny({"camera": {"heading": 0}, "effects": [{"id": "f", "position": [0, -200, 0]}]})
    assert "volumes" not in plan_passes(behind) and "depth_copy" not in plan_passes(behind)


def _render(renderer, patch, **kw):
    result = renderer.render(tiny(patch, **kw))
    hdr = renderer.read_hdr()
    assert np.isfinite(hdr).all(), "NaN/Inf in the HDR target"
    return result.rgba


def test_sky_changes_with_time_of_day(renderer):
    # A fixed exposure so the HDR radiance of the three skies compares directly.
    look_up = {"ground": {"enabled": False}, "camera": {"pitch": 30, "heading": 90, "exposure_ev": 10}}
    hdr = {}
    for name, elevation in (("noon", 60), ("dusk", -4), ("night", -18)):
        _render(renderer, {**look_up, "time": {"sun_override": {"elevation": elevation, "azimuth": 200}}})
        hdr[name] = renderer.read_hdr()[..., :3]
    means = {k: float(luminance(v).mean()) for k, v in hdr.items()}
    assert means["noon"] > 10 * means["dusk"] > 10 * 10 * means["night"] > 0
    noon = hdr["noon"].reshape(-1, 3).mean(axis=0)
    assert noon[2] > 1.2 * noon[0]  # the noon sky is blue


def test_auto_exposure_keeps_every_time_of_day_visible(renderer):
    for elevation in (60, 5, -6):
        rgba = _render(renderer, {"time": {"sun_override": {"elevation": elevation, "azimuth": 90}}})
        assert 5 < luminance(rgba).mean() < 250, elevation


def _sun_pixel_expected_and_found(renderer, scene, elevation: float, azimuth: float):
    """Where the direction (elevation, azimuth) projects (pixel coordinates, x right, y down) and where
    the rendered HDR radiance peaks (the centre of the pixel holding the maximum)."""
    renderer.render(scene)
    hdr = renderer.read_hdr()
    assert np.isfinite(hdr).all()
    view = make_view(scene.camera)
    el, az = np.radians(elevation), np.radians(azimuth)
    sun = np.array([np.cos(el) * np.sin(az), np.cos(el) * np.cos(az), np.sin(el), 0.0])  # ENU, heading from north
    clip = view.view_proj @ sun
    expect = ((clip[0] / clip[3] * 0.5 + 0.5) * scene.camera.width,
              (1 - (clip[1] / clip[3] * 0.5 + 0.5)) * scene.camera.height)
    lum = luminance(hdr)
    y, x = np.unravel_index(np.argmax(lum), lum.shape)
    return np.array(expect), np.array([x + 0.5, y + 0.5])


# The disk (0.27 deg radius: 0.65 px at 96 px per 40 deg) is brightest at its centre (limb darkening), so
# the peak is the pixel containing the centre: within half a pixel; 1 px allows the centre on an edge.
SUN_PIXEL_TOLERANCE = 1.0


def test_sun_is_where_the_ephemeris_puts_it(renderer):
    scene = tiny({"ground": {"enabled": False}, "time": {"utc": "2026-06-21T08:00:00Z"}}, 96, 96)
    state = celestial_state(scene.time.utc, scene.location.lat, scene.location.lon)
    scene = scene.model_copy(update={"camera": scene.camera.model_copy(update={
        "heading": state.sun_azimuth - 8.0, "pitch": state.sun_elevation - 5.0, "fov_y": 40.0})})
    expect, found = _sun_pixel_expected_and_found(renderer, scene, state.sun_elevation, state.sun_azimuth)
    assert np.all(np.abs(found - expect) <= SUN_PIXEL_TOLERANCE), (expect, found)
    assert expect[0] > 48 and expect[1] < 48  # sun right of and above the view axis, as placed


@pytest.mark.parametrize("azimuth, elevation", [(250.0, 12.0), (35.0, 3.0), (160.0, 30.0)])
def test_sun_override_puts_the_disk_where_its_direction_points(renderer, azimuth, elevation):
    """``time.sun_override`` (elevation, azimuth: degrees, azimuth clockwise from north) pins the disk's
    pixel: camera 8 deg left of and 4 deg below the sun, so the disk is right of and above the centre."""
    scene = tiny({"ground": {"enabled": False}, "time": {"sun_override": {"elevation": elevation, "azimuth": azimuth}},
                  "camera": {"heading": azimuth - 8.0, "pitch": elevation - 4.0, "fov_y": 40.0}}, 96, 96)
    expect, found = _sun_pixel_expected_and_found(renderer, scene, elevation, azimuth)
    assert expect[0] > 48 and expect[1] < 48
    assert np.all(np.abs(found - expect) <= SUN_PIXEL_TOLERANCE), (expect, found)


def test_far_from_origin_renders_like_the_origin(renderer):
    patch = {"entities": [{"id": "b", "position": [0, 40, 0], "scale": [6, 6, 6]}],
             "ground": {"level": 0.0}, "camera": {"position": [0, 0, 3]}}
    near = _render(renderer, patch).astype(int)
    far_patch = {"entities": [{"id": "b", "position": [1e6, 1e6 + 40, 0], "scale": [6, 6, 6]}],
                 "ground": {"level": 0.0}, "camera": {"position": [1e6, 1e6, 3]}}
    far = _render(renderer, far_patch).astype(int)
    assert np.abs(near - far).max() <= 2  # only the dither may differ


def test_point_light_lights_the_ground_at_night(renderer):
    night = {"time": {"sun_override": {"elevation": -20, "azimuth": 0}}, "camera": {"pitch": -20, "exposure_ev": 0},
             "ground": {"level": 0.0}}
    dark = luminance(_render(renderer, night)).mean()
    lit = luminance(_render(renderer, {**night, "lights": [{"id": "l", "position": [0, 25, 3], "intensity": 2000}]})).mean()
    assert lit > dark + 10


@pytest.mark.parametrize("patch", [
    {"camera": {"position": [0, 0, 0.001]}, "ocean": {"enabled": True}},
    {"camera": {"position": [0, 0, 100_000], "pitch": -10}, "ocean": {"enabled": True}},
    {"camera": {"pitch": 90}}, {"camera": {"pitch": -90}},
    {"time": {"sun_override": {"elevation": 90, "azimuth": 0}}},
    {"time": {"sun_override": {"elevation": 0, "azimuth": 0}}},
    {"time": {"sun_override": {"elevation": -18, "azimuth": 0}}},
    {"atmosphere": {"visibility": 50}}, {"atmosphere": {"visibility": 200_000}},
    {"time": {"sim_time": 1e9}},
    {"camera": {"frustum": {"left": -50, "right": 10, "bottom": -5, "top": 30}}},
])
def test_extreme_cases_are_finite(renderer, patch):
    rgba = _render(renderer, patch)
    assert rgba[..., :3].max() > 0
