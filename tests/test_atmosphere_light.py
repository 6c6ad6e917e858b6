"""Light levels, fog and the eye (issues 10 and 11, the atmosphere's part), on tiny frames.

Tolerances carry their independent reason beside them; published values come from the AMS
Glossary of Meteorology (twilight illuminance) and Koschmieder's law (visibility)."""

from __future__ import annotations

import math
import time

import numpy as np
import pytest

from igserver.quality.light import AMS_ILLUMINANCE, FULL_MOON_UTC, MOONLESS_UTC
from igserver.photometry import LUMA
from igserver.render.frame import build_frame
from igserver.render.post.exposure import EyeAdaptation, TAU_LIGHT
from igserver.render.sky.tables import AtmosphereTables
from igserver.scene.model import Scene


def scene(el=30.0, az=180.0, heading=180.0, pitch=5.0, w=32, h=18, utc=MOONLESS_UTC, sim_time=0.0,
          adaptation=False, **sections) -> Scene:
    d = {"camera": {"width": w, "height": h, "heading": heading, "pitch": pitch, "position": [0.0, 0.0, 2.0],
                    "adaptation": adaptation},
         "time": {"utc": utc, "sun_override": {"elevation": el, "azimuth": az}, "sim_time": sim_time},
         "atmosphere": {"visibility_transition": 0.0}}
    for key, value in sections.items():
        if isinstance(value, dict):
            d.setdefault(key, {}).update(value)
        else:
            d[key] = value
    return Scene.model_validate(d)


def mean_display(renderer, s: Scene) -> float:
    return float(renderer.render(s).rgba[..., :3].mean())


def radiance(renderer, s: Scene) -> np.ndarray:
    """Linear radiance (cd/m^2) of the last frame: the HDR target over the exposure actually shown."""
    result = renderer.render(s)
    exposure = 1.0 / (1.2 * 2.0 ** result.ev100)
    frame = build_frame(renderer.ctx, s)
    # The HDR target is pre-exposed with the provisional exposure of build_frame; the post pass
    # corrects only the display. Undo the provisional one.
    return renderer.read_hdr()[..., :3] / frame.exposure, exposure


# --- exposure through dusk ------------------------------------------------------------------

# (180, True) failed from the wave sea's merge until the water pass stopped binding its third detail
# map on the frame's haze-table unit (8): the sky and every later pass read wave slopes as fog light.
@pytest.mark.parametrize("heading,ocean", [(180.0, False), (0.0, False), (180.0, True)])
def test_displayed_brightness_never_rises_while_the_sun_sets(renderer, heading, ocean):
    # +20 -> -30 deg: 0.5-deg steps over the whole range plus 0.1-deg steps across sunset and the
    # old 32-column table nodes (-1.85, -5.55, -9.28, -13.05 deg) where main jumped by 1-1.5 EV.
    coarse = np.arange(20.0, -30.01, -0.5)
    fine = np.concatenate([np.arange(c + 0.3, c - 0.31, -0.1) for c in (2.0, -1.85, -5.55, -9.28, -13.05)])
    for els in (coarse, fine):
        # A calm sea (sea state 0): on a wind sea at 32x18 the sun's glitter, point-sampled on wave
        # facets, pops in and out between frames (the water's aliasing, not the light's).
        values = [mean_display(renderer, scene(float(e), heading=heading, ocean={"enabled": ocean, "sea_state": 0}))
                  for e in np.round(els, 2)]
        rises = np.diff(values)
        # Half an 8-bit level: the dither of the post pass moves a 32x18 frame's mean by < 0.1 level,
        # the meter's block means (not per-pixel display) by a few tenths at most.
        assert rises.max() <= 0.5, (heading, ocean, float(rises.max()), list(np.round(values, 2)))
    assert values[0] > 5 * mean_display(renderer, scene(-30.0, heading=heading, ocean={"enabled": ocean, "sea_state": 0}))


def test_no_glow_band_toward_the_sun_below_minus_16(renderer):
    # Main showed a near-white band on the horizon toward the sun at -15 (row means 252/231/191
    # sRGB). Below -16 deg only the faint residual glow the AMS Glossary places until -18 may
    # remain: the rows 0..10 deg above the horizon toward the sun, as displayed (automatic
    # exposure), stay dark (< 20 of 255) and within a few levels of the same rows away from it.
    for elevation, max_excess in ((-16.5, 8.0), (-18.0, 5.0)):
        rows = {}
        for heading in (180.0, 0.0):
            rgba = renderer.render(scene(elevation, heading=heading, pitch=5.0, w=64, h=36)).rgba
            rows[heading] = rgba[12:19, :, :3].astype(float).mean(axis=(1, 2))  # 0..10 deg up
        assert rows[180.0].max() < 20.0, (elevation, rows[180.0])
        assert (rows[180.0] - rows[0.0]).max() < max_excess, (elevation, rows)


@pytest.mark.parametrize("elevation", [0.0, -6.0, -12.0, -18.0])
def test_twilight_illuminance_within_a_factor_two_of_measurements(renderer, elevation):
    # Issue 11's bound (a factor of 2 of published clear-sky measurements): the spread of the AMS
    # Glossary's own ranges (410-585 lx, 2-3.5 lx) and of clear-sky turbidity between evenings.
    e = build_frame(renderer.ctx, scene(elevation)).illuminance_lux
    published = AMS_ILLUMINANCE[elevation]
    assert 0.5 < e / published < 2.0, (elevation, e, published)


# The AMS Glossary's clear-evening ranges ("civil twilight", "nautical twilight") at the sun's TRUE
# (unrefracted) elevation: 410-585 lx at 0 deg, 2-3.5 lx at -6 deg, ~0.008 lx at -12 deg.
AMS_RANGES = {0.0: (410.0, 585.0), -6.0: (2.0, 3.5), -12.0: (0.008, 0.008)}


@pytest.mark.parametrize("true_elevation", [0.0, -6.0, -12.0])
def test_twilight_illuminance_within_one_and_a_half_of_the_glossary_ranges(renderer, true_elevation):
    # The frame's sun is the apparent one (SPA refraction, 0.48 deg at a true 0): the test turns the
    # glossary's true elevation into it. Bound: x1.5 beyond each end of the glossary's range, the
    # spread of clear-sky turbidity and ozone between evenings (the range itself is the spread of
    # the glossary's sources); the middle of the range was 1054 lx at a true 0 deg when the sky
    # was lit by the sun at the disk's refracted elevation.
    from igserver.astro.ephemeris import refraction_deg
    apparent = true_elevation + refraction_deg(true_elevation)
    e = build_frame(renderer.ctx, scene(apparent)).illuminance_lux
    lo, hi = AMS_RANGES[true_elevation]
    assert lo / 1.5 < e < 1.5 * hi, (true_elevation, apparent, e, (lo, hi))


def test_sky_sees_a_quarter_of_the_refraction_and_stays_continuous():
    # The sky's sun (sky_sun_elevation): the apparent elevation less 3/4 of the refraction (the
    # density-weighted bending of the rays that light the scattering air: module docstring), equal
    # to it where there is no refraction, continuous and rising across the ephemeris's gap
    # (-0.83 .. -0.21 deg apparent, reachable by an instructor's fixed sun).
    from igserver.astro.ephemeris import refraction_deg
    from igserver.render.sky.frame_sky import SKY_REFRACTION_FRACTION, sky_sun_elevation
    assert 0.2 < SKY_REFRACTION_FRACTION < 0.3
    r0 = refraction_deg(0.0)
    assert sky_sun_elevation(r0) == pytest.approx(SKY_REFRACTION_FRACTION * r0, abs=1e-6)
    assert sky_sun_elevation(-6.0) == -6.0 and sky_sun_elevation(45.0) == pytest.approx(45.0, abs=0.02)  # R(45) = 0.017 deg
    e = np.arange(-2.0, 3.0, 0.01)
    sky = np.array([sky_sun_elevation(float(x)) for x in e])
    assert np.all(np.diff(sky) > 0.0) and np.abs(np.diff(sky)).max() < 0.05


def test_patat_fit_matches_the_digitised_paper_points():
    # The quadratic V-band zenith fit the study uses (coefficients first written from memory) against
    # the points digitised independently from Patat et al. (2006)'s figure: 0.2 mag, the reading
    # error of a digitised log plot (~0.1 mag) plus the scatter of the data about the paper's fit
    # (~0.1 mag). Largest difference found: 0.16 mag at z = 100 deg (a wrong coefficient, e.g. a1 off
    # by 10 %, would miss by 0.5 mag or more at z = 99..105).
    from igserver.quality.light import PATAT_V_DIGITISED, patat_v_mag
    for z, m in PATAT_V_DIGITISED:
        if z <= 105.0:
            assert abs(patat_v_mag(z) - m) < 0.2, (z, patat_v_mag(z), m)


@pytest.mark.parametrize("elevation", [-6.0, -9.0, -12.0, -14.0])
def test_twilight_zenith_luminance_within_a_factor_two_of_patat(renderer, elevation):
    # Issue 11's factor 2 against Patat et al. (2006), sea-level corrected (+30 %).
    from igserver.quality.light import SkyEvaluator, patat_zenith_luminance, zenith_and_illuminance
    lz, _ = zenith_and_illuminance(SkyEvaluator(renderer), elevation)
    published = patat_zenith_luminance(elevation)
    assert 0.5 < lz / published < 2.0, (elevation, lz, published)


def test_twilight_is_smooth_at_tenth_degree_steps(renderer):
    # Issue 11: no step larger than x1.25 per 0.1 deg in the horizontal illuminance (0 .. -18).
    values = [build_frame(renderer.ctx, scene(float(e))).illuminance_lux for e in np.arange(0.0, -18.01, -0.1)]
    r = np.asarray(values[:-1]) / np.asarray(values[1:])
    assert r.max() < 1.25 and r.min() > 0.999, (r.max(), r.min())


def test_moonlit_night_is_brighter_than_moonless(renderer):
    moon = build_frame(renderer.ctx, scene(-30.0, utc=FULL_MOON_UTC)).illuminance_lux
    dark = build_frame(renderer.ctx, scene(-30.0)).illuminance_lux
    # Full moon 30 deg up: 0.31 lx * sin(30) * ~0.75 transmission ~ 0.12 lx (Krisciunas & Schaefer).
    assert 0.05 < moon < 0.3 and moon > 20 * dark, (moon, dark)
    # ... and the picture shows it.
    assert mean_display(renderer, scene(-30.0, utc=FULL_MOON_UTC, heading=0.0)) > mean_display(
        renderer, scene(-30.0, heading=0.0)) + 2.0


def test_eye_adapts_to_a_fire_with_its_time_constant(renderer):
    # Night, a 1 MW-ish lamp/fire appears 5 m away at t = 0; frames every 1/30 s.
    night = dict(el=-20.0, heading=0.0, pitch=-5.0, adaptation=True)
    base = scene(**night)
    renderer.render(base)  # adapted to the dark
    lit = {"lights": [{"id": "fire", "position": [0.0, 5.0, 1.0], "intensity": 5e4, "range": 200.0}]}
    steady = renderer.render(scene(**night, sim_time=50.0, **lit)).ev100  # same sim_time jump: adapted
    dark_ev = renderer.render(scene(**night, sim_time=100.0)).ev100
    assert steady > dark_ev + 3.0  # the fire brightens the view by > 8x
    evs = [renderer.render(scene(**night, sim_time=100.0 + k / 30.0, **lit)).ev100 for k in range(1, 31)]
    # First-order response: after t the remaining gap is exp(-t / TAU_LIGHT) (0.4 s).
    gap0 = steady - dark_ev
    for k, ev in enumerate(evs, start=1):
        t = k / 30.0
        expected = steady - gap0 * math.exp(-t / TAU_LIGHT)
        assert abs(ev - expected) < 0.15 * gap0, (t, ev, expected)
    assert steady - evs[-1] < 0.1 * gap0  # 1 s = 2.5 tau: within 10 %


def test_adaptation_is_a_first_order_lag():
    eye = EyeAdaptation()
    assert eye.update(0.0, 0.0) == 0.0
    assert eye.update(10.0, 0.0) == 10.0  # same instant: adapted at once (deterministic re-render)
    assert eye.update(0.0, 5.0) == 0.0  # after a jump of > 1 s: adapted
    v = eye.update(4.0, 5.4)  # 0.4 s toward more light: 1 - 1/e of the way
    assert abs(v - 4.0 * (1 - math.exp(-1.0))) < 1e-9
    v2 = eye.update(0.0, 5.8)  # darker: the slow constant (4 s)
    assert v2 > v * math.exp(-0.4 / 4.0) - 1e-9 and v2 < v


def test_fixed_exposure_wins(renderer):
    s = scene(10.0, camera={"exposure_ev": 3.0})
    assert renderer.render(s).ev100 == 3.0


# --- fog and visibility -----------------------------------------------------------------------

def test_visibility_never_rebuilds_tables(renderer):
    renderer.render(scene(atmosphere={"visibility": 20_000.0}))
    tables = AtmosphereTables._resident[renderer.ctx]
    for v in (12_345.0, 12_346.0, 50.0, 200_000.0):
        renderer.render(scene(atmosphere={"visibility": v}))
        assert AtmosphereTables._resident[renderer.ctx] is tables


def test_visibility_ramp_has_no_slow_frame(renderer):
    # 20 km -> 100 m in 50 steps, one step per frame at 30 Hz of sim_time, easing on (1 s).
    times = []
    for i, v in enumerate(np.geomspace(20_000.0, 100.0, 50)):
        s = scene(sim_time=1000.0 + i / 30.0, w=64, h=36, atmosphere={"visibility": float(v),
                                                                        "visibility_transition": 1.0})
        t0 = time.perf_counter()
        renderer.render(s)
        times.append(time.perf_counter() - t0)
    times = np.asarray(times)
    # Issue 10: a new visibility value must not freeze the stream. The frames share the machine with
    # other processes, so a step that overran is re-timed (best of 3 at its own state). The bound is
    # absolute, not a ratio to the median: a freeze is a table rebuild or a synchronous precompute,
    # and the cheapest of those (the `low` atmosphere tables) takes 0.3 s on this machine, while a
    # 64x36 frame takes ~5 ms; 100 ms over the median is also where a stall becomes visible in a
    # 30 Hz stream (three frames). Rebuilds themselves are caught by test_visibility_never_rebuilds_tables.
    median = float(np.median(times))
    for i in np.nonzero(times > median + 0.1)[0]:
        times[i] = min(_retime(renderer, float(np.geomspace(20_000.0, 100.0, 50)[i]), 3000.0 + i + k)
                       for k in range(3))
    assert times.max() <= median + 0.1, (median, times.max())


def _retime(renderer, visibility: float, sim_time: float) -> float:
    s = scene(sim_time=sim_time, w=64, h=36, atmosphere={"visibility": visibility, "visibility_transition": 1.0})
    t0 = time.perf_counter()
    renderer.render(s)
    return time.perf_counter() - t0


def test_visibility_change_eases_in_without_a_pop(renderer):
    clear = scene(sim_time=500.0, atmosphere={"visibility": 20_000.0, "visibility_transition": 1.0})
    renderer.render(clear)
    values = [mean_display(renderer, scene(sim_time=500.0 + k * 0.1, atmosphere={
        "visibility": 200.0, "visibility_transition": 1.0})) for k in range(1, 16)]
    target = mean_display(renderer, scene(sim_time=900.0, atmosphere={"visibility": 200.0}))
    steps = np.abs(np.diff(values))
    # Smooth: no single 0.1 s step carries more than 40 % of the change (a pop would carry ~100 %).
    assert steps.max() < 0.4 * abs(values[-1] - values[0]) + 0.5, values
    # Settled within 2 s (here 1 s): the last frames equal the steady state within a level.
    assert abs(values[-1] - target) < 1.0, (values[-1], target)


def _xy(rgb: np.ndarray) -> np.ndarray:
    m = np.array([[0.4124, 0.3576, 0.1805], [0.2126, 0.7152, 0.0722], [0.0193, 0.1192, 0.9505]])
    xyz = m @ np.asarray(rgb, dtype=np.float64)
    return xyz[:2] / xyz.sum()


@pytest.mark.parametrize("visibility", [200.0, 1000.0])
def test_noon_fog_is_neutral_and_kilolux(renderer, visibility):
    s = scene(60.0, heading=0.0, pitch=10.0, w=64, h=36, atmosphere={"visibility": visibility})
    frame = build_frame(renderer.ctx, s)
    # Issue 10: horizontal illuminance under the fog in kilolux (noon clear sky at 60 deg ~ 100 klx;
    # a 200-m fog thinning with height transmits ~30-70 % by diffusion, ~1/(1 + 0.75 (1-g) tau)).
    assert 5e3 < frame.illuminance_lux < 1.2e5, frame.illuminance_lux
    hdr, _ = radiance(renderer, s)
    fog = hdr[5:15].reshape(-1, 3).mean(axis=0)  # sky pixels 10-25 deg up, away from the sun
    sun_xy = _xy(np.asarray(frame.uniforms["u_haze_sun"]))
    assert np.all(np.abs(_xy(fog) - sun_xy) < 0.02), (_xy(fog), sun_xy)


def _box_contrast(renderer, visibility: float, distance: float, size: float, **extra) -> float:
    base = dict(el=45.0, heading=0.0, pitch=0.0, w=64, h=36, atmosphere={"visibility": visibility}, **extra)
    box = {"entities": [{"id": "b", "model": "box", "position": [0.0, distance, -size / 2], "scale": [size, size, size],
                         "color": [0.05, 0.05, 0.05]}]}
    with_box, _ = radiance(renderer, scene(**base, **box))
    without, _ = radiance(renderer, scene(**base))
    centre = (slice(16, 20), slice(30, 34))
    a, b = with_box[centre] @ LUMA, without[centre] @ LUMA
    return float(np.abs(a - b).mean() / b.mean())


def test_visibility_hides_and_shows_a_box(renderer):
    # Koschmieder: a black object's contrast at distance d is exp(-3.912 d / V): 4e-4 at d = 2V,
    # 0.68 at d = V / 10. Thresholds 2 % (the definition of visibility) and 20 %.
    assert _box_contrast(renderer, 50.0, 100.0, 20.0) < 0.02
    assert _box_contrast(renderer, 200_000.0, 20_000.0, 2_000.0) > 0.2


def test_snow_lowers_the_visibility_unless_the_host_already_did(renderer):
    # Snow at 2 mm/h has an extinction of ~1e-2 /m (igserver.weather, Gunn-Marshall flakes: 1 mm/h
    # gives ~0.74 km): a box at 1.5 km then keeps exp(-15) of its contrast, far under the 2 % of the
    # definition of visibility; with lowers_visibility = false the host's 200 km stands (contrast
    # ~0.97 > 20 %). The falling flakes are the same in the frames with and without the box.
    snow = {"type": "snow", "rate": 2.0}
    hidden = _box_contrast(renderer, 200_000.0, 1_500.0, 150.0, weather={"precipitation": snow})
    shown = _box_contrast(renderer, 200_000.0, 1_500.0, 150.0,
                          weather={"precipitation": {**snow, "lowers_visibility": False}})
    assert hidden < 0.02 and shown > 0.2, (hidden, shown)


# --- photometric read-out on the wire --------------------------------------------------------------

def test_frame_reports_ev100_and_illuminance(renderer):
    from igserver.protocol.encoded_frame import EncodedFrame
    from igserver.protocol.routers.frames import frame_message
    from igserver.render.worker import Frame

    result = renderer.render(scene(30.0))
    # Noon-ish clear sky at 30 deg: 60-80 klx horizontal (sun 50 klx on the ground + sky 15-20 klx).
    assert 3e4 < result.illuminance_lux < 1.2e5 and 10.0 < result.ev100 < 18.0
    frame = Frame(result.rgba, 7, 3, 1.0, ev100=result.ev100, illuminance_lux=result.illuminance_lux)
    encoded = EncodedFrame(frame, revision=1, accepted_at=0.0, render_call_ms=1.0)
    headers = encoded.headers()
    assert float(headers["X-IG-EV100"]) == pytest.approx(result.ev100, abs=1e-3)
    assert float(headers["X-IG-Illuminance-Lux"]) == pytest.approx(result.illuminance_lux, rel=1e-5)
    message = frame_message(encoded, "png", b"", 0.0)
    assert message["ev100"] == pytest.approx(result.ev100, abs=1e-3)
    assert message["illuminance_lux"] == pytest.approx(result.illuminance_lux, rel=1e-5)


# --- the table cache is bounded ------------------------------------------------------------------

def test_table_cache_evicts_least_recently_used(tmp_path):
    import os

    from igserver.render.sky.tables import evict_least_recently_used

    for i in range(6):  # six "table sets" of 1 MB, used in order 0..5
        path = tmp_path / f"k{i}.npz"
        path.write_bytes(b"\0" * 1_000_000)
        os.utime(path, (1000.0 + i, 1000.0 + i))
    os.utime(tmp_path / "k0.npz", (2000.0, 2000.0))  # k0 loaded again: most recently used
    removed = evict_least_recently_used(tmp_path, 3_500_000, keep=tmp_path / "k5.npz")
    assert sorted(p.name for p in removed) == ["k1.npz", "k2.npz", "k3.npz"]
    assert sorted(p.name for p in tmp_path.glob("*.npz")) == ["k0.npz", "k4.npz", "k5.npz"]


def test_cache_key_holds_the_format_version(monkeypatch):
    from igserver.render.sky import atmosphere_model as am

    key = am.atmosphere_parameters(2.0).key()
    monkeypatch.setattr(am, "TABLE_FORMAT_VERSION", am.TABLE_FORMAT_VERSION + 1)
    assert am.atmosphere_parameters(2.0).key() != key


@pytest.mark.parametrize("elevation", [0.0, 0.5, 1.0, 2.0, 5.0, 20.0, 60.0])
@pytest.mark.parametrize("height", [0.0, 300.0])
@pytest.mark.parametrize("layer_args", [(30_000.0, None), (800.0, 150.0)], ids=["haze", "fog"])
def test_low_sun_beam_crosses_the_layer_on_a_round_earth(elevation, height, layer_args):
    # The sun's optical depth through the haze or a fog layer down to height h, tau_above(h) /
    # slant_mu: against the integral of the layer's extinction along the straight ray on the sphere
    # (float64, 1 m steps over 600 km). Flat earth (tau / sin e) overshoots at a low sun: 1.37x the
    # haze's path at 1 deg, so the low haze got 7-9x too little sun at sunrise (30 km visibility).
    # slant_mu's closed form (Chapman with erfcx's upper bound) is within 5.5 % at every elevation
    # (the bound's own error), 11 % inside a fog at the horizon (a flat-topped layer, not exponential).
    from igserver.render.sky.haze import EARTH_RADIUS_M, haze_layer

    visibility, fog_top = layer_args
    layer = haze_layer(visibility, 2.0, fog_top, 1.2e-5)
    mu = math.sin(math.radians(elevation))
    got = float(layer.tau_above(height)[1] / layer.slant_mu(mu, height)[0])
    r0 = EARTH_RADIUS_M + height
    s = np.linspace(0.0, 600_000.0, 600_001)
    h = np.sqrt(r0 * r0 + s * s + 2.0 * r0 * s * mu) - EARTH_RADIUS_M
    want = float(np.trapezoid(layer.density(h), s) * layer.beta[1])
    tolerance = 0.12 if (fog_top is not None and elevation == 0.0 and height < fog_top) else 0.06
    assert got == pytest.approx(want, rel=tolerance)
    if fog_top is None and 0.0 < elevation <= 1.0:
        assert layer.tau_above(height)[1] / mu > 1.3 * want  # what the flat earth did


@pytest.mark.parametrize("elevation", [-30.0, -5.0, 0.0, 10.0])
@pytest.mark.parametrize("altitude", [0.0, 5_000.0, 1e6, 1e7])
def test_beams_through_the_layer_stay_finite_at_any_height(renderer, elevation, altitude):
    # Seen from 10,000 km the sun below the astronomical horizon still lights the camera; the layer's
    # scale length came out of column / density as 0 / e^-80 = 0 there, the beam's slant cosine as 0
    # and the sun disk's luminance as 0 / 0 = NaN (it reached a shader uniform). The lights must be
    # finite and non-negative for every sun elevation and height.
    scene = Scene.model_validate({"camera": {"position": [0.0, 0.0, max(altitude, 2.0)], "width": 32, "height": 18},
                                  "time": {"sun_override": {"elevation": elevation, "azimuth": 180.0}}})
    light = build_frame(renderer.ctx, scene).light
    for value in (light.sun_illuminance, light.sun_disk_luminance, light.sky_ambient, light.moon_illuminance):
        assert np.all(np.isfinite(value)) and np.all(np.asarray(value) >= 0.0)


def test_low_sun_disk_dimmed_by_the_light_it_casts(renderer):
    # A camera 15 m over the sea aimed at the sun 0.47 deg up (apparent) through 30 km visibility:
    # the disk's flux (the frame's HDR radiance summed over it, the sky around subtracted) against
    # the sun the frame casts on surfaces (light.sun_disk_luminance x its solid angle, the CPU's
    # float64 clear air times the haze over HazeLayer.slant_mu), averaged over the disk: across
    # its 0.53 deg the haze path runs from 52 to 78 airmasses, so the transmittance varies by
    # e^(+-1.7) and the disk's mean exceeds its centre's (chord-weighted 9-point mean below).
    # Tolerance 20 %: limb darkening weights the centre (u = 0.6), the disk's 1.5-px tent, the
    # float32 transmittance table at grazing. Red and green only: the blue disk is ~1e-4 of red.
    from igserver.render.camera import make_view
    from igserver.render.frame import sun_and_moon
    from igserver.render.sky.daylight import SUN_SOLID_ANGLE
    base = scene(0.47, az=300.0, pitch=0.47, heading=300.0, w=64, h=36, ocean={"enabled": False},
                 atmosphere={"visibility": 30000.0, "visibility_transition": 0.0})
    s = base.model_copy(update={"camera": base.camera.model_copy(update={"fov_y": 3.0, "exposure_ev": 18.0,
                                                                         "position": (0.0, 0.0, 15.0)})})
    renderer.render(s)
    frame = build_frame(renderer.ctx, s)
    hdr = renderer.read_hdr()[..., :3] / frame.exposure
    view = make_view(s.camera)
    clip = view.view_proj @ np.append(np.asarray(sun_and_moon(s).sun_dir) * 1e6, 1.0)
    col, row = int((clip[0] / clip[3] * 0.5 + 0.5) * 64), int((0.5 - clip[1] / clip[3] * 0.5) * 36)
    win = hdr[row - 8:row + 9, col - 8:col + 9]
    background = np.median(np.concatenate([win[0], win[-1], win[:, 0], win[:, -1]]), axis=0)
    pixel = math.radians(3.0) / 36
    flux = (win - background).sum(axis=(0, 1)) * pixel * pixel
    x = np.linspace(-0.9, 0.9, 9)
    weights = np.sqrt(1.0 - x * x)
    cast = sum(w * build_frame(renderer.ctx, s.model_copy(update={"time": s.time.model_copy(update={
        "sun_override": s.time.sun_override.model_copy(update={"elevation": 0.47 + 0.2667 * xi})})})
    ).light.sun_disk_luminance for xi, w in zip(x, weights)) / weights.sum() * SUN_SOLID_ANGLE
    ratio = flux[:2] / cast[:2]
    assert np.all((ratio > 0.8) & (ratio < 1.2)), (flux, cast, ratio)
    # ... and it is red: green under a fifth of red (the clear air alone leaves 0.5).
    assert flux[1] < 0.2 * flux[0], flux


def test_snowfall_horizon_is_no_darker_than_the_sky_above_it(renderer):
    # Moderate snow by day over a snow-covered ground (the snow scene: visibility ~0.6 km with the
    # snow's extinction, ground albedo 0.8). Deep in an optically thick layer the light is nearly
    # diffuse: the radiance looking up is F_down / pi, looking horizontally (F_down + F_up) / 2 pi,
    # and F_up = A F_down over the ground: with the layer's phase weights (up and down mixed as
    # 1/2 + z/2) horizon / 25 deg up = (1 + A) / 2 / (0.71 + 0.29 A) = 0.96 over snow, 0.74 over the
    # layer's old fixed 0.1 (the dark band). Rows 0.5-3 deg above the horizon against rows 20-26
    # deg up, linear luminance; bound 0.85: the 0.96 less the falling flakes' streaks and the
    # sun's phase term (a low winter sun at 59.9 N).
    from igserver.scene.files import load_scene
    from igserver.scene import apply_patch
    s = apply_patch(load_scene("snow"), {"camera": {"width": 64, "height": 36, "pitch": 0.0, "exposure_ev": 12.0},
                                         "entities": []})
    renderer.render(s)
    lum = renderer.read_hdr()[..., :3] @ LUMA
    deg_per_row = 55.0 / 36
    row = lambda el: int(18 - el / deg_per_row)  # noqa: E731 - rows top first, the horizon at 18
    horizon = lum[row(3.0):row(0.5) + 1].mean()
    above = lum[row(26.0):row(20.0) + 1].mean()
    assert horizon > 0.85 * above, (horizon, above)


def _fog_from_above(pitch: float, fov: float) -> Scene:
    from igserver.scene import apply_patch
    from igserver.scene.files import load_scene
    return apply_patch(load_scene("sea_beaufort5"), {
        "atmosphere": {"visibility": 300.0, "fog_top": 150.0, "visibility_transition": 0.0},
        "time": {"utc": "2026-06-21T11:40:00Z"},
        "camera": {"position": [0.0, 0.0, 500.0], "pitch": pitch, "fov_y": fov, "width": 64, "height": 36,
                   "exposure_ev": 15.0}})


def test_fog_top_from_above_has_no_bright_edge_and_reflects_its_flux(renderer):
    # A 150 m fog (visibility 300 m: optical depth 2.1) under a sun 70 deg up, seen from 500 m.
    # (1) Its far edge, 0.6-0.7 deg below the horizon (2 deg field: 0.06 deg a row): rays that graze
    # the top run level through it for kilometres. Their light is the top's, gathered where their
    # first optical depth lies; gathered at the fog's bottom it drew a line 1.7x the sky above and
    # the fog below. Bound: 1.1x the brighter of the two (the edge lies between them).
    renderer.render(_fog_from_above(-0.66, 2.0))
    frame = build_frame(renderer.ctx, _fog_from_above(-0.66, 2.0))
    lum = (renderer.read_hdr()[..., :3] / frame.exposure) @ LUMA
    rows = lum.mean(axis=1)
    assert rows[12:22].max() < 1.1 * max(rows[8], rows[30]), np.round(rows).tolist()
    # (2) Looking 20 deg down, the fog top's luminance against the layer's own reflected flux
    # (HazeLayer.fluxes: the two-stream model checked against Monte Carlo in `igserver quality
    # fog`) as a Lambertian surface, F_up / pi. Bounds 0.8-1.25: the reflection of a thin
    # forward-scattering layer is not Lambertian (brighter toward grazing views and the sun's side).
    s = _fog_from_above(-20.0, 30.0)
    renderer.render(s)
    frame = build_frame(renderer.ctx, s)
    lum = (renderer.read_hdr()[..., :3] / frame.exposure) @ LUMA
    haze = frame.resources["haze"]
    flux = haze.fluxes(haze.top + 8.0 * haze.edge, np.asarray(frame.uniforms["u_haze_sun"]),
                       float(frame.celestial.sun_dir[2]), np.asarray(frame.uniforms["u_haze_sky"]))
    lambertian = float(LUMA @ flux["up"]) / math.pi
    top = float(lum[14:22].mean())
    assert 0.8 < top / lambertian < 1.25, (top, lambertian)
