"""The sea from under its surface (docs/water.md#under-water): Snell's window, Jerlov attenuation, the bed,
and the crossing of the surface. Small frames, the session renderer."""

from __future__ import annotations

import math

import numpy as np
import pytest

from igserver.photometry import LUMA
from igserver.scene import apply_patch
from igserver.scene.model import Scene
from igserver.water import sea_surface

SNELL_HALF_ANGLE = math.degrees(math.asin(1.0 / 1.333))  # 48.6 deg


def _scene(**patch) -> Scene:
    base = {"camera": {"position": [0.0, 0.0, -2.0], "heading": 90.0, "pitch": 0.0, "fov_y": 60.0,
                       "width": 96, "height": 64},
            "time": {"utc": "2026-06-21T10:00:00Z", "sim_time": 100.0}, "location": {"lat": 43.0, "lon": 5.0},
            "weather": {"wind_speed": 8.0, "wind_direction": 220.0}, "ocean": {"enabled": True}}
    out = apply_patch(Scene(), base)
    return apply_patch(out, patch)


def _lum(rgba: np.ndarray) -> np.ndarray:
    return rgba[..., :3].astype(np.float64) @ LUMA


def _angle_from_axis(width: int, height: int, fov_y: float) -> np.ndarray:
    """Per pixel, the angle (deg) between its ray and the view axis of a square pinhole frame."""
    t = math.tan(math.radians(fov_y) / 2.0)
    y, x = np.mgrid[0:height, 0:width]
    u = ((x + 0.5) / width * 2.0 - 1.0) * t * width / height
    v = ((y + 0.5) / height * 2.0 - 1.0) * t
    return np.degrees(np.arctan(np.hypot(u, v)))


def test_looking_up_shows_snells_window(renderer):
    """From 3 m down, looking up: the sky is seen only inside Snell's window, a cone of half-angle
    asin(1/1.333) = 48.6 deg about the zenith (Snell's law; e.g. Lynch & Livingston, "Color and Light
    in Nature", 2001, the optical manhole); outside it the surface totally reflects the dark water
    below. Inside 35 deg at least 5 times as bright as 55-70 deg in linear radiance (106 measured; before,
    the mesh's underside shaded as its top, reflecting the sky: 1.3)."""
    s = _scene(camera={"position": [0.0, 0.0, -3.0], "pitch": 90.0, "fov_y": 150.0, "width": 96, "height": 96})
    renderer.render(s)
    lum = renderer.read_hdr()[..., :3].astype(np.float64) @ LUMA  # linear: the LDR frame's white clips
    angle = _angle_from_axis(96, 96, 150.0)
    inside = lum[angle < 35.0].mean()
    outside = lum[(angle > 55.0) & (angle < 70.0)].mean()
    assert inside > 5.0 * outside, (inside, outside)
    assert renderer.graph.passes["water"].stats["underwater"]


def test_level_view_fades_to_the_water_colour(renderer):
    """Looking level from 5 m down into deep water: every ray ends in the water column, whose colour is
    the Jerlov type II water's (K_d 0.33, 0.093, 0.065 1/m for red, green, blue; Jerlov 1976): red
    absorbed, the blue-green background, no sky or haze at the horizon row (before: the sky's white
    horizon, red/blue 0.8). Rows at the horizon: red < 0.35 x blue, green within 0.6-1.4 x blue."""
    s = _scene(camera={"position": [0.0, 0.0, -5.0], "pitch": 0.0})
    rgb = renderer.render(s).rgba[..., :3].astype(np.float64)
    row = rgb[28:36].reshape(-1, 3).mean(axis=0)
    assert row[0] < 0.35 * row[2], row
    assert 0.6 * row[2] < row[1] < 1.4 * row[2], row


def test_shallow_bed_fades_with_distance(renderer):
    """A sand bed 2.5 m below the eye (uniform depth 4 m, eye at -1.5 m), looking 35 deg down: the bed
    near the eye (short path) keeps more red against blue than the bed far off (long path), which fades
    into the water colour (Beer-Lambert along the path with the Jerlov K_d, red 0.33 1/m against blue
    0.065). Red/blue of the bottom rows > 2 x that of rows 8-16, the bed some 10-30 m off (3.7 measured;
    before, the bed was not drawn)."""
    s = _scene(camera={"position": [0.0, 0.0, -1.5], "pitch": -35.0},
               ocean={"enabled": True, "bathymetry": {"type": "uniform", "depth": 4.0}})
    rgb = renderer.render(s).rgba[..., :3].astype(np.float64) + 1.0
    near = rgb[48:].reshape(-1, 3).mean(axis=0)
    far = rgb[8:16].reshape(-1, 3).mean(axis=0)
    assert near[0] / near[2] > 2.0 * far[0] / far[2], (near, far)


@pytest.mark.parametrize("pitch", [5.0, -10.0])
def test_a_passing_crest_takes_the_eye_under_without_a_flash(renderer, pitch):
    """An eye 0.2 m below the mean level while the waves pass (Beaufort 5, 0.1 s steps over 4 s, a
    fixed exposure): the frame is the under-water one exactly while the surface at the eye's xy (the
    host's height query) is above the eye — every such frame darker than 0.6 x the darkest frame with
    the eye in the air (before: the mesh's underside shaded as its top, the sky in it, as bright as
    the frames above: 0.9-1.0) — and no frame is brighter than both of its neighbours by more than
    10 % of the brighter one (a flash at the crossing)."""
    s0 = _scene(camera={"position": [0.0, 0.0, -0.2], "pitch": pitch, "width": 64, "height": 40,
                        "exposure_ev": 14.0})
    sea = sea_surface(s0.ocean, s0.weather)
    under, lum = [], []
    for t in np.arange(100.0, 104.0, 0.1):
        s = apply_patch(s0, {"time": {"sim_time": float(t)}})
        under.append(float(sea.query(np.zeros((1, 2)), float(t))["height"][0]) > -0.2)
        lum.append(float(_lum(renderer.render(s).rgba).mean()))
    under, lum = np.array(under), np.array(lum)
    assert under.any() and (~under).any()  # the sweep crosses the surface both ways
    assert lum[under].max() < 0.6 * lum[~under].min(), (under, lum.round(1))
    for i in range(1, len(lum) - 1):
        assert lum[i] <= 1.1 * max(lum[i - 1], lum[i + 1]), (i, lum.round(1))


def test_objects_under_water_fade_with_distance(renderer):
    """A crate 2 m down seen from 2 m down at 5 m and at 40 m: the water between the eye and the crate
    (Jerlov type II, e^{-K d}: 72 % of the blue left at 5 m, 7 % at 40 m; red 19 % and 0.0002 %) takes its
    contrast against the water behind it: at 40 m under 0.07 of the contrast at 5 m (0.03 measured;
    before, the surfaces drawn before the sea were not attenuated by the water: 0.14)."""
    def contrast(distance: float) -> float:
        base = {"camera": {"position": [0.0, 0.0, -2.0], "heading": 0.0, "pitch": 0.0, "fov_y": 20.0,
                           "width": 64, "height": 48, "exposure_ev": 12.0}}
        crate = {"id": "crate", "model": "crate", "position": [0.0, distance, -2.5],
                 "scale": [distance / 5.0] * 3}  # the same size on screen at both distances
        empty = _lum(renderer.render(_scene(**base)).rgba)
        seen = _lum(renderer.render(_scene(**base, entities=[crate])).rgba)
        mask = np.abs(seen - empty) > 0.5
        assert mask.sum() > 20, mask.sum()  # the crate is on screen
        return float(np.abs(seen - empty)[mask].mean()) * mask.mean()

    near, far = contrast(5.0), contrast(40.0)
    assert far < 0.07 * near, (near, far)


def test_caustics_on_a_shallow_bed(renderer):
    """Sunlight through the rippled surface onto a sand bed 1 m below the eye (2 m deep, eye at -1 m,
    looking 60 deg down, noon sun): ray optics gives the bed irradiance 1 / |det(I - a H)| of its mean,
    a = h (1 - 1/n), H the surface's Hessian (e.g. Nye 1999, "Natural focusing and fine structure of
    light"): a net of bright lines over darker cells. The bed's luminance varies (std/mean > 0.25: 0.83
    measured, 0.01 evenly lit) while its mean stays within 25 % of the evenly lit bed's (0.95 measured;
    0.93-1.16 over winds of 3-25 m/s and beds 1-4 m below the eye: light is moved, not made)."""
    water = renderer.graph.passes["water"]
    s = _scene(camera={"position": [0.0, 0.0, -1.0], "pitch": -60.0, "exposure_ev": 14.0},
               ocean={"enabled": True, "bathymetry": {"type": "uniform", "depth": 2.0}},
               time={"utc": "2026-06-21T11:30:00Z"})

    def bed() -> np.ndarray:
        renderer.render(s)
        return (renderer.read_hdr()[..., :3].astype(np.float64) @ LUMA)[32:]  # the lower half: bed only

    try:
        water.caustics = False
        even = bed()
        water.caustics = True
        lit = bed()
    finally:
        water.caustics = True
    assert lit.std() / lit.mean() > 0.25 and even.std() / even.mean() < 0.1, (lit.std(), even.std())
    assert abs(lit.mean() / even.mean() - 1.0) < 0.25, (lit.mean(), even.mean())


def test_rain_and_fire_stay_above_the_surface(renderer):
    """rain_harbour (rain, a burning boat, lamps) from 2 m under the water: the rain's streaks, the fire's
    and smoke's volumes and the lights' halos in the rainy air are hidden by the water (before, the rain
    fell through the frame under water and the halos lit it orange); from 2 m above, all are drawn."""
    from igserver.scene import load_scene, resolve_scene_path

    base = load_scene(resolve_scene_path("rain_harbour"))
    for z, drawn in ((2.0, True), (-2.0, False)):
        s = apply_patch(base, {"camera": {"position": [-20.0, -40.0, z], "heading": 300.0, "pitch": 5.0,
                                          "width": 64, "height": 36}})
        renderer.render(s)
        passes = renderer.graph.passes
        assert passes["water"].stats["underwater"] is not drawn
        assert (passes["precip"].stats["streaks"] > 0) is drawn
        assert (passes["volumes"].stats["drawn"] > 0) is drawn
        assert (passes["post"].stats["halos"] > 0) is drawn  # the lamps' and the fire's glow in the rainy air
