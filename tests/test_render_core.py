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
    """Sky and ground without the sun in view, at noon, low sun and civil twilight: the automatic exposure
    puts the mid-tones mid-range and clips nothing. Median 8-bit level within [32, 224]: sRGB 32 is 3.6
    stops below middle grey (sRGB 118, linear 0.18) and 224 is 2 stops above it — beyond that a frame
    reads as under- or over-exposed; fewer than 1 % of pixels crushed (<= 2) or blown (>= 253), since
    nothing in these views is brighter than the sky near the sun's side or darker than the ground."""
    for elevation in (60, 5, -6):
        lum = luminance(_render(renderer, {"time": {"sun_override": {"elevation": elevation, "azimuth": 90}}}))
        assert 32 <= np.median(lum) <= 224, (elevation, np.median(lum))
        assert (lum <= 2).mean() < 0.01 and (lum >= 253).mean() < 0.01, elevation


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
    far_patch = {"entities": [{"id": "b", "position": [1e6, 1e6 + 40, 0], "scale": [6, 6, 6]}],
                 "ground": {"level": 0.0}, "camera": {"position": [1e6, 1e6, 3]}}
    # Without shadows only the dither may differ. The key shadow map's texels are snapped to a grid
    # fixed in the world (no sub-texel crawl while the camera moves), so 1000 km away the box sits
    # elsewhere in its texel and the filtered self-shadow on its lit faces differs by a few levels
    # at single pixels, as it would a texel's width away from the origin.
    no_shadows = {"shadows": {"enabled": False}}
    near = _render(renderer, {**patch, **no_shadows}).astype(int)
    far = _render(renderer, {**far_patch, **no_shadows}).astype(int)
    assert np.abs(near - far).max() <= 2
    near, far = _render(renderer, patch).astype(int), _render(renderer, far_patch).astype(int)
    assert np.abs(near - far).mean() < 0.25 and np.abs(near - far).max() <= 12


def test_point_light_lights_the_ground_at_night(renderer):
    night = {"time": {"sun_override": {"elevation": -20, "azimuth": 0}}, "camera": {"pitch": -20, "exposure_ev": 0},
             "ground": {"level": 0.0}}
    dark = luminance(_render(renderer, night)).mean()
    lit = luminance(_render(renderer, {**night, "lights": [{"id": "l", "position": [0, 25, 3], "intensity": 2000}]})).mean()
    assert lit > dark + 10


# --------------------------------------------------------------------------- extreme cases: what the picture must be

EARTH_RADIUS = 6.371e6  # m, the mean earth radius (the sea and the ground are this sphere seen from above)
SKY = 1e29  # the distance target holds 1e30 m where the sky shows


def _first_surface_row(renderer, patch, width, height) -> int:
    """Row (from the top) of the first surface pixel in the centre column of the distance target."""
    renderer.render(tiny(patch, width, height))
    distance = renderer.read_distance()
    column = distance[:, width // 2]
    assert np.isfinite(distance).all()
    below = np.nonzero(column < SKY)[0]
    assert len(below), "no surface in the centre column"
    assert np.all(column[below[0]:] < SKY), "sky below the horizon"
    return int(below[0])


@pytest.mark.parametrize("height_m, pitch, tan_bottom_top", [
    (0.001, 0.0, None),             # on the water: dip 0.001 deg, the horizon on the view axis
    (10_000.0, 0.0, None),          # dip 3.2 deg
    (50_000.0, -5.0, None),         # dip 7.2 deg, horizon 800 km away (inside the default far plane)
    (2.0, 0.0, (-5.0, 30.0)),       # asymmetric frustum: the horizon 5 deg above the bottom edge
])
def test_horizon_row_is_where_geometry_puts_it(renderer, height_m, pitch, tan_bottom_top):
    """The sea seen from height h is a sphere of the earth's radius: the horizon dips by
    acos(R / (R + h)) below the horizontal, and a pinhole camera (pitch p, vertical half-angles b..t)
    images elevation e at ndc_y = (2 tan(e - p) - tan t - tan b) / (tan t - tan b)."""
    width, height = 33, 91  # odd: a centre column on the view axis
    camera = {"position": [0.0, 0.0, height_m], "pitch": pitch, "fov_y": 40.0}
    if tan_bottom_top is None:
        bottom, top = -20.0, 20.0
    else:
        bottom, top = tan_bottom_top
        camera["frustum"] = {"left": -20.0, "right": 20.0, "bottom": bottom, "top": top}
    # Wind 0: a glassy sea (Hs 0), so the sphere's geometry alone sets the horizon (waves would hide
    # it from a camera 1 mm above the mean level, as they do at sea).
    patch = {"camera": camera, "ocean": {"enabled": True}, "ground": {"enabled": False},
             "weather": {"wind_speed": 0.0}}
    dip = np.arccos(EARTH_RADIUS / (EARTH_RADIUS + height_m))
    tb, tt = np.tan(np.radians(bottom)), np.tan(np.radians(top))
    ndc = (2.0 * np.tan(-dip - np.radians(pitch)) - tt - tb) / (tt - tb)
    horizon_y = (1.0 - ndc) / 2.0 * height  # continuous pixel coordinate from the top
    # The first surface row is the first whose pixel centre (row + 0.5) lies below the horizon:
    # 0 <= row + 0.5 - horizon_y < 1. Slack of 0.1 px each way: a ray grazing the sphere that close to
    # the horizon is decided in float32.
    row = _first_surface_row(renderer, patch, width, height)
    assert -0.1 <= row + 0.5 - horizon_y < 1.1, (row, horizon_y)


def test_far_plane_at_its_maximum_still_renders(renderer):
    """From 100 km the horizon is 1130 km away: only a far plane beyond 1e6 m shows it (dip 10.1 deg)."""
    patch = {"camera": {"position": [0.0, 0.0, 100_000.0], "pitch": -5.0, "fov_y": 40.0, "far": 1e7},
             "ocean": {"enabled": True}, "ground": {"enabled": False}}
    dip = np.arccos(EARTH_RADIUS / (EARTH_RADIUS + 100_000.0))
    horizon_y = (1.0 - np.tan(-dip + np.radians(5.0)) / np.tan(np.radians(20.0))) / 2.0 * 91
    row = _first_surface_row(renderer, patch, 33, 91)
    assert -0.1 <= row + 0.5 - horizon_y < 1.1, (row, horizon_y)


def test_looking_straight_down_and_up(renderer):
    """Pitch -90 from 5 km: every pixel is ground, at the distance a sphere of the earth's radius puts it
    (h at the nadir, ~h / cos(angle off nadir) towards the corners); pitch +90: every pixel is sky."""
    h, size, fov = 5_000.0, 33, 40.0
    renderer.render(tiny({"camera": {"position": [0.0, 0.0, h], "pitch": -90.0, "fov_y": fov}}, size, size))
    distance = renderer.read_distance().astype(np.float64)
    assert np.all(distance < SKY)
    # angle off nadir of each pixel centre, pinhole with square pixels
    t = np.tan(np.radians(fov / 2.0)) * ((np.arange(size) + 0.5) / size * 2.0 - 1.0)
    off = np.arctan(np.hypot(t[None, :], t[:, None]))
    # flat-earth distance h / cos(off) is short by ~h^2 tan^2 / (2 R cos) < 0.1 %, and the float32
    # ray-sphere solve at 6.4e6 m holds ~1e-4: 2e-3 relative covers both
    assert np.allclose(distance, h / np.cos(off), rtol=2e-3)
    assert abs(distance[size // 2, size // 2] - h) < 2e-3 * h
    renderer.render(tiny({"camera": {"position": [0.0, 0.0, 2.0], "pitch": 90.0}}, size, size))
    assert np.all(renderer.read_distance() >= SKY)


def test_sky_brightness_orders_by_sun_elevation(renderer):
    """Zenith-ward sky radiance (fixed exposure) falls monotonically as the sun sinks from the zenith to
    -18 deg, and the sunlit sky is blue (Rayleigh: more blue scattered than red), the twilight sky less so."""
    look_up = {"ground": {"enabled": False}, "camera": {"pitch": 60.0, "heading": 90.0, "exposure_ev": 10}}
    means, blue_over_red = [], []
    for elevation in (90.0, 45.0, 10.0, 0.0, -6.0, -12.0, -18.0):
        _render(renderer, {**look_up, "time": {"sun_override": {"elevation": elevation, "azimuth": 270.0}}})
        rgb = renderer.read_hdr()[..., :3].reshape(-1, 3).astype(np.float64)
        means.append(float(luminance(rgb).mean()))
        # medians: the sun (in view at the zenith) keeps its energy on a pixel's footprint at tiny sizes
        blue_over_red.append(float(np.median(rgb[:, 2]) / np.median(rgb[:, 0])))
    assert all(a > b for a, b in zip(means, means[1:])), means
    assert means[-1] > 0.0
    assert blue_over_red[0] > 1.2 and blue_over_red[1] > 1.2, blue_over_red  # the day sky is blue


def test_neighbouring_inputs_give_neighbouring_pictures(renderer):
    """No singularity or seam: a small change of the input changes the picture a little. Pairs that differ
    by 0.01 deg or 1 mm must agree to within 2 levels on average (the dither alone moves +-1)."""
    pairs = [
        ({"camera": {"pitch": 90.0}}, {"camera": {"pitch": 89.99}}),  # the pole of the heading
        ({"camera": {"pitch": -90.0}}, {"camera": {"pitch": -89.99}}),
        ({"camera": {"position": [0, 0, 0.001]}, "ocean": {"enabled": True}, "ground": {"enabled": False}},
         {"camera": {"position": [0, 0, 0.002]}, "ocean": {"enabled": True}, "ground": {"enabled": False}}),
        ({"time": {"sun_override": {"elevation": 0.0, "azimuth": 0.0}}},
         {"time": {"sun_override": {"elevation": -0.01, "azimuth": 0.0}}}),  # the sun crossing the horizon
        ({"time": {"sun_override": {"elevation": 90.0, "azimuth": 0.0}}},
         {"time": {"sun_override": {"elevation": 89.99, "azimuth": 123.0}}}),  # azimuth undefined at the zenith
        ({"time": {"sim_time": 0.0}}, {"time": {"sim_time": 1e9}}),  # a static scene does not depend on time
    ]
    for a, b in pairs:
        pa, pb = _render(renderer, a).astype(int), _render(renderer, b).astype(int)
        assert np.abs(pa - pb).mean() <= 2.0, (a, b, np.abs(pa - pb).mean())


@pytest.mark.parametrize("patch", [
    {"atmosphere": {"visibility": 50}}, {"atmosphere": {"visibility": 200_000}},
    {"camera": {"frustum": {"left": -50, "right": 10, "bottom": -5, "top": 30}}},
    {"time": {"sun_override": {"elevation": -18, "azimuth": 0}}},
])
def test_extreme_cases_are_finite(renderer, patch):
    rgba = _render(renderer, patch)
    assert rgba[..., :3].max() > 0
