"""Precomputed sky: tables, cache, colours, aerial perspective, extreme cases (tiny frames)."""

from __future__ import annotations

import numpy as np
import pytest

from igserver.render.frame import build_frame
from igserver.render.renderer import Renderer
from igserver.render.shaders import GLSL_VERSION, expand
from igserver.render.sky.atmosphere_model import atmosphere_parameters
from igserver.render.sky.frame_sky import scene_atmosphere
from igserver.render.sky.tables import AtmosphereTables
from igserver.scene.model import Scene

W, H = 64, 36


@pytest.fixture(scope="module", autouse=True)
def fresh_table_cache(tmp_path_factory):
    """Tables computed (and cached) in this module's own directory: the cache test starts cold."""
    mp = pytest.MonkeyPatch()
    mp.setenv("IGSERVER_CACHE", str(tmp_path_factory.mktemp("igcache")))
    yield
    mp.undo()


def scene(el=45.0, az=180.0, alt=2.0, pitch=10.0, heading=None, fov=60.0, x=0.0, **sections) -> Scene:
    d = {"camera": {"width": W, "height": H, "fov_y": fov, "position": [x, 0.0, alt],
                    "heading": az if heading is None else heading, "pitch": pitch},
         "time": {"sun_override": {"elevation": el, "azimuth": az}}}
    for key, value in sections.items():
        d.setdefault(key, {}).update(value)
    return Scene.model_validate(d)


def radiance(renderer: Renderer, s: Scene) -> np.ndarray:
    """Rendered linear radiance (cd/m^2), un-exposed."""
    renderer.render(s)
    exposure = build_frame(renderer.ctx, s).exposure
    return renderer.read_hdr()[..., :3] / exposure


def test_default_model_is_precomputed():
    assert Scene().atmosphere.model == "precomputed"


def test_tables_finite_and_transmittance_monotone(renderer):
    s = scene()
    renderer.render(s)
    tables = AtmosphereTables.get(renderer.ctx, scene_atmosphere(s))
    arrays = tables.arrays()
    for name, a in arrays.items():
        assert np.all(np.isfinite(a)), name
        assert np.all(a[..., :3] >= 0.0), name
    tau = arrays["transmittance"][..., :3]  # rows r, columns x_mu: path length grows along x
    assert np.all(np.diff(tau, axis=1) >= -1e-5)
    # And falls with altitude at a fixed path-length coordinate (less air above).
    assert np.all(np.diff(tau[:, 0, :], axis=0) <= 1e-5)
    assert tables.irradiance_host[..., :3].max() > 0.05


def test_cache_hit_on_second_construction(renderer):
    # Low-preset tables: the cache mechanics are the same, and a cold medium set (16 density samples
    # for twilight) costs ~30 s of precompute on llvmpipe.
    params = scene_atmosphere(scene(atmosphere={"quality": "low"}))
    first = AtmosphereTables(renderer.ctx, params)  # computed (cold module cache) or loaded: saved either way
    first.release()
    again = AtmosphereTables(renderer.ctx, params)
    try:
        assert again.from_cache and again.precompute_s == 0.0
    finally:
        again.release()
    # Same parameters: the resident tables are reused, not rebuilt.
    assert AtmosphereTables.get(renderer.ctx, params) is AtmosphereTables.get(renderer.ctx, params)


def test_parameters_change_the_key():
    # Tables depend on the turbidity CLASS (steps of 0.5), never on the visibility.
    a, b = atmosphere_parameters(2.0), atmosphere_parameters(5.0)
    assert a.key() != b.key() and a.key() == atmosphere_parameters(2.0).key()
    assert atmosphere_parameters(2.1).key() == a.key()  # quantised: nearby values share tables
    s1 = scene(atmosphere={"visibility": 12345.0})
    s2 = scene(atmosphere={"visibility": 12346.0})
    assert scene_atmosphere(s1).key() == scene_atmosphere(s2).key() == scene_atmosphere(scene()).key()


def test_sky_colour_noon_sunset_night(renderer):
    noon = radiance(renderer, scene(el=60.0, pitch=60.0))
    # Medians: the sun is in this view, and at 64x36 its disk (spread over a pixel's footprint,
    # energy kept) carries most of the frame's mean.
    assert np.median(noon[..., 2]) > np.median(noon[..., 0]) * 1.3  # blue sky
    assert 2e3 < np.median(noon) < 2e4  # cd/m^2
    sunset = radiance(renderer, scene(el=0.5, pitch=2.0))
    row = sunset[H // 2 - 2 : H // 2 + 2, W // 2 - 4 : W // 2 + 4]  # just above the horizon toward the sun
    assert row[..., 0].mean() > row[..., 2].mean()  # reddened
    night = radiance(renderer, scene(el=-18.0, pitch=30.0))
    assert night.mean() < 1e-2 * sunset.mean()
    # Twilight fades without steps as the sun sinks: zenith luminance non-increasing degree by
    # degree down to -18 (the natural night sky is the floor) and never black.
    zen = [radiance(renderer, scene(el=float(e), pitch=89.0, fov=5.0))[H // 2, W // 2].mean()
           for e in range(0, -19, -1)]
    assert all(a >= 0.999 * b for a, b in zip(zen, zen[1:])), zen
    # The natural night sky (airglow + starlight, ~21.7 V mag/arcsec^2) is ~1.7e-4 cd/m^2 at the zenith.
    assert min(zen) > 1e-4  # cd/m^2
    # The fall per degree is never steeper than single scattering's, computed independently in float64
    # (quality/reference_sky.py, no tables): light scattered twice or more also reaches the zenith column
    # from air that is still sunlit beyond the earth's shadow, so it fades more slowly than the directly
    # lit part. Single scattering vanishes below -10 deg (the shadow rises above the atmosphere), so the
    # bound applies from 0 to -10. The 10 % slack is the tables' interpolation error on each of the two
    # radiances of a ratio (2.6 % mean at zenith angle 65 deg, more toward the terminator: igserver quality sky).
    ratios = [a / b for a, b in zip(zen, zen[1:])]
    single = _reference_single_scattering_zenith(range(0, -11, -1))
    bound = [a / b for a, b in zip(single, single[1:])]
    assert all(r <= 1.1 * b for r, b in zip(ratios, bound)), (ratios[:10], bound)


def _reference_single_scattering_zenith(elevations) -> list[float]:
    """Zenith single-scattered radiance (cd/m^2, mean of R, G, B) of the default atmosphere for each sun
    elevation (deg), from the float64 ray-marching reference (96 samples: ratios converge to < 1 %)."""
    from igserver.quality.reference_sky import single_scattering

    params = scene_atmosphere(scene())
    out = []
    for e in elevations:
        el = np.radians(e)
        sun = np.array([0.0, np.cos(el), np.sin(el)])
        out.append(float(single_scattering(params, 2.0, np.array([[0.0, 0.0, 1.0]]), sun, samples=96)[0].mean()))
    return out


def _aerial(renderer: Renderer, s: Scene, points: np.ndarray, surface: float) -> np.ndarray:
    """apply_aerial_perspective(surface radiance, rel) for camera-relative points, on the GPU."""
    frame = build_frame(renderer.ctx, s)
    src = "\n".join([GLSL_VERSION, "#define COMPUTE_SHADER 1", "layout(local_size_x = 1) in;",
                     expand("common/frame.glsl"),
                     expand("common/atmosphere.glsl", frozenset({"common/frame.glsl"})),
                     "layout(std430, binding = 0) buffer Points { vec4 p[]; };",
                     "layout(std430, binding = 1) buffer Out { vec4 o[]; };",
                     "uniform float u_surface;",
                     "void main() { uint i = gl_GlobalInvocationID.x;",
                     "  o[i] = vec4(apply_aerial_perspective(vec3(u_surface), p[i].xyz), 0.0); }"])
    prog = renderer.ctx.compute_shader(src)
    for name, value in {**frame.uniforms, "u_surface": surface}.items():
        if name in prog and hasattr(prog[name], "value"):
            prog[name].value = value
    pts = np.zeros((len(points), 4), "f4")
    pts[:, :3] = points
    inp = renderer.ctx.buffer(pts.tobytes())
    out = renderer.ctx.buffer(reserve=pts.nbytes)
    inp.bind_to_storage_buffer(0)
    out.bind_to_storage_buffer(1)
    prog.run(len(points))
    result = np.frombuffer(out.read(), "f4").reshape(-1, 4)[:, :3].copy()
    for obj in (inp, out, prog):
        obj.release()
    return result


def test_aerial_perspective_distance_and_visibility(renderer):
    # Low-preset tables (0.3 s each): four visibilities are four table sets.
    dist = np.array([10.0, 100.0, 1e3, 5e3, 2e4, 6e4])
    pts = np.stack([np.zeros_like(dist), dist, -1.9 * np.ones_like(dist)], axis=1)  # ground ahead
    for vis in (30_000.0, 5_000.0):
        s = scene(el=30.0, atmosphere={"visibility": vis, "quality": "low"})
        black = _aerial(renderer, s, pts, 0.0).mean(axis=1)
        white = _aerial(renderer, s, pts, 1e4).mean(axis=1)
        assert np.all(np.isfinite(black)) and np.all(np.isfinite(white))
        # in-scattering grows with distance (until it saturates in haze) ...
        assert np.all(np.diff(black) >= -1e-2 * black[1:]), (vis, black)  # (directions differ by 0.01 deg)
        assert np.all(np.diff(black[:4]) > 0) and black[-1] > 10 * black[0], (vis, black)
        # ... and the surface's own light falls
        transmittance = (white - black) / 1e4
        assert np.all(np.diff(transmittance) <= 1e-6) and transmittance[0] > 0.99, (vis, transmittance)
    clear = _aerial(renderer, scene(el=30.0, atmosphere={"visibility": 50_000.0, "quality": "low"}), pts, 1e4).mean(axis=1)
    hazy = _aerial(renderer, scene(el=30.0, atmosphere={"visibility": 2_000.0, "quality": "low"}), pts, 1e4).mean(axis=1)
    # At 5 km a 10 klx-ish white wall keeps less of its own light in haze (~exp(-3.9*5/2)).
    t_clear = _aerial(renderer, scene(el=30.0, atmosphere={"visibility": 50_000.0, "quality": "low"}), pts, 0.0).mean(axis=1)
    t_hazy = _aerial(renderer, scene(el=30.0, atmosphere={"visibility": 2_000.0, "quality": "low"}), pts, 0.0).mean(axis=1)
    assert (hazy - t_hazy)[3] < 0.1 * (clear - t_clear)[3]


EXTREMES = {
    "sun_zenith": dict(el=90.0),
    "sun_horizon": dict(el=0.0, pitch=0.0),
    "sun_minus18": dict(el=-18.0),
    "observer_0m": dict(alt=0.0),
    "observer_10km": dict(alt=10_000.0, pitch=-10.0),
    "observer_100km": dict(alt=100_000.0, pitch=-20.0),
    "water_1mm": dict(alt=0.001, pitch=-5.0, ocean={"enabled": True}),
    "horizon_view": dict(pitch=0.0, fov=1.0),
    "looking_down": dict(pitch=-90.0, alt=5_000.0),
    "fog_50m": dict(atmosphere={"visibility": 50.0}),
    "clear_200km": dict(atmosphere={"visibility": 200_000.0, "quality": "low"}),
    "camera_1e6m": dict(x=1e6, weather={"cirrus_coverage": 0.6}),
    "cirrus_twilight": dict(el=-4.0, pitch=30.0, weather={"cirrus_coverage": 0.8, "wind_speed": 40.0},
                            time={"sim_time": 1e9}),
    "gradient_tier": dict(atmosphere={"model": "gradient"}, weather={"cirrus_coverage": 0.5}),
}


@pytest.mark.parametrize("name", list(EXTREMES))
def test_extreme_cases_render_finite(renderer, name):
    s = scene(**EXTREMES[name])
    result = renderer.render(s)
    hdr = renderer.read_hdr()
    assert np.all(np.isfinite(hdr)), name
    assert hdr[..., :3].max() > 1e-3, name  # not a black frame
    assert result.rgba[..., :3].mean() > 1.0, name


def test_cirrus_table_matches_the_per_pixel_layer(renderer):
    # The cirrus layer drawn once per frame at half resolution per axis (sky.py CIRRUS_TABLE_SCALE)
    # against the per-pixel layer, at dusk with the layer toward the sun, 640x360. Bound: 35 dB PSNR
    # / a mean of 2 levels; bilinear upsampling of the premultiplied layer only blurs the streaks
    # narrower than 2 px near the horizon (measured 37.5 dB, mean 1.5 levels); a 256-px-wide frame
    # on a 128-px table fell to 32 dB, hence CIRRUS_TABLE_MIN_WIDTH.
    from igserver.render.sky.sky import SkyPass
    s = scene(1.0, 180.0, pitch=8.0, weather={"cirrus_coverage": 0.5})
    s = s.model_copy(update={"camera": s.camera.model_copy(update={"width": 640, "height": 360})})
    old = SkyPass.cirrus_scale
    try:
        SkyPass.cirrus_scale = 1
        a = renderer.render(s).rgba[..., :3].astype(float)
        SkyPass.cirrus_scale = 2
        b = renderer.render(s).rgba[..., :3].astype(float)
    finally:
        SkyPass.cirrus_scale = old
    mse = float(((a - b) ** 2).mean())
    assert mse > 0.0  # the two paths did run
    assert 10 * np.log10(255.0 ** 2 / mse) > 35.0 and np.abs(a - b).mean() < 2.0


@pytest.mark.parametrize("heading,pitch,fov", [(170.0, 10.0, 20.0), (188.0, 4.0, 20.0), (180.0, 16.0, 20.0),
                                              (205.0, 30.0, 60.0), (180.0, 10.0, 2.0)])
def test_sun_disk_box_holds_the_whole_disk(renderer, heading, pitch, fov, monkeypatch):
    # The sun's disk is drawn only inside a scissor box (sky.py disk_box); wherever it sits in the
    # frame (centre, off-axis, near the edge, a 2-deg telephoto where the disk spans pixels) the
    # frame must be the one drawn with the box grown to the whole frame. Exact: the same shader
    # runs on the same pixels; any pixel of the disk outside the box would differ.
    from igserver.render.sky import sky
    s = scene(10.0, 180.0, heading=heading, pitch=pitch, fov=fov)
    boxed = radiance(renderer, s)
    box = sky.disk_box

    def sun_box_whole_frame(frame, d, r):
        return (0, 0, frame.view.width, frame.view.height) if d is frame.celestial.sun_dir else box(frame, d, r)
    monkeypatch.setattr(sky, "disk_box", sun_box_whole_frame)
    whole = radiance(renderer, s)
    assert whole[..., 1].max() > 100.0 * np.median(whole[..., 1])  # the sun is in the frame
    np.testing.assert_array_equal(boxed, whole)


def test_planets_are_drawn_where_and_as_bright_as_pyephem_says(renderer):
    # Jupiter at 2026-03-19 00:00 UTC from 43 N 5 E: 26.1 deg up, V -2.2 (PyEphem). The star field
    # holds it at PyEphem's apparent place (to 0.01 deg: the same computation) and magnitude, and a
    # night frame pointed at it shows its point at the frame's centre (within 1.5 px: the point
    # sprite is 2 px wide) as the brightest pixel.
    import math
    from datetime import datetime, timezone

    import ephem

    from igserver.astro import star_field
    field = star_field(datetime(2026, 3, 19, tzinfo=timezone.utc), 43.0, 5.0)
    obs = ephem.Observer()
    obs.lat, obs.lon, obs.date, obs.pressure = "43", "5", "2026/3/19 00:00", 1013.25
    jupiter = ephem.Jupiter(obs)
    i = field.names.index("Jupiter")
    d = field.directions[i]
    assert math.degrees(math.asin(d[2])) == pytest.approx(math.degrees(jupiter.alt), abs=0.01)
    assert -2.5 * math.log10(field.illuminance[i] / 2.54e-6) == pytest.approx(jupiter.mag, abs=0.01)
    az = math.degrees(math.atan2(d[0], d[1])) % 360.0
    s = Scene.model_validate({
        "camera": {"width": 64, "height": 36, "fov_y": 10.0, "heading": az, "pitch": math.degrees(math.asin(d[2]))},
        "time": {"utc": "2026-03-19T00:00:00Z"}, "location": {"lat": 43.0, "lon": 5.0}})
    y = radiance(renderer, s)[..., 1]
    row, col = np.unravel_index(int(np.argmax(y)), y.shape)
    assert abs(row + 0.5 - 18.0) <= 1.5 and abs(col + 0.5 - 32.0) <= 1.5, (row, col)


@pytest.mark.parametrize("case", [
    dict(pitch=1.0, roll=25.0, heading=200.0),           # tilted horizon across the frame: clipped
    dict(pitch=-20.0, roll=-10.0, heading=170.0, fov=70.0),  # horizon near the top: a thin strip
    dict(pitch=-60.0, heading=180.0),                    # no sky at all: nothing drawn
    dict(pitch=10.0, heading=180.0, alt=12_000.0),       # above the layer: the whole frame
    dict(pitch=-4.0, heading=180.0, alt=5_000.0),        # 2.3 deg of layer below the level view
])
def test_cirrus_table_polygon_holds_every_texel_the_layer_reaches(renderer, monkeypatch, case):
    # The cirrus table is drawn only inside the polygon of the frame whose rays can meet the
    # layer (sky.py cirrus_polygon), the rest cleared to no cloud. The frame must be the one drawn
    # with the table filled over the whole frame, bit for bit (exact: the same shader runs on the
    # texels inside; outside, the layer is zero by construction and the margin covers the bilinear
    # footprint). 640x360 so that the table path (not the per-pixel layer) is taken.
    from igserver.render.sky import sky
    case = dict(case)
    roll = case.pop("roll", 0.0)
    s = scene(2.0, 180.0, weather={"cirrus_coverage": 0.6}, **case)
    s = s.model_copy(update={"camera": s.camera.model_copy(update={"width": 640, "height": 360, "roll": roll})})
    polygon = sky.cirrus_polygon
    areas = []

    def measured(frame, size):
        tris = polygon(frame, size)
        t = np.zeros((0, 3, 2)) if tris is None else tris.reshape(-1, 3, 2).astype(float)
        e1, e2 = t[:, 1] - t[:, 0], t[:, 2] - t[:, 0]
        areas.append(float(np.abs(e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]).sum() / 2))
        return tris
    monkeypatch.setattr(sky, "cirrus_polygon", measured)
    clipped = radiance(renderer, s)
    monkeypatch.setattr(sky, "cirrus_polygon",
                        lambda frame, size: np.array([[0, 0], [1, 0], [1, 1], [0, 0], [1, 1], [0, 1]], "f4"))
    whole = radiance(renderer, s)
    np.testing.assert_array_equal(clipped, whole)
    if case.get("alt", 0.0) > 9_000.0:
        assert areas[-1] == pytest.approx(1.0)  # from above the layer every ray may meet it
    elif case["pitch"] < -40.0:
        assert areas[-1] == 0.0  # the frame is all sea/ground below the horizon
    else:
        assert 0.05 < areas[-1] < 0.8, areas  # the polygon did clip the frame
        sky_px = clipped[..., 1] > 0
        assert sky_px.any()


def test_cirrus_layer_wraps_on_its_period_without_a_jump(renderer):
    # The layer's noise offset (frame_sky.cirrus_offset_units) wraps on a 64-unit (384 km) period;
    # a camera 1 m either side of the wrap sees the same layer: 1 m moves it ~1e-4 px here, so only
    # 8-bit rounding may differ (1 level). With a streak period of 22.4 units (not a whole number
    # of lattice units) the streaks jumped there by up to 67 levels.
    period_m = 64.0 * 6000.0
    frames = [renderer.render(scene(20.0, 180.0, pitch=20.0, x=period_m + dx, camera={"exposure_ev": 12.0},
                                    weather={"cirrus_coverage": 0.6})).rgba[..., :3].astype(int)
              for dx in (-0.5, 0.5)]
    assert frames[0][..., 1].std() > 2.0  # there is a textured layer in view
    assert np.abs(frames[0] - frames[1]).max() <= 1


def test_cirrus_table_drawn_per_change(renderer):
    # The cirrus table (640x360: the table path) is drawn again only when an input other than the
    # layer's drift changed or the drift could move the layer by more than 0.25 px (sky.py
    # cirrus_drift_px). A still camera at 30 Hz under a 40 m/s jet: ~1.3 m of drift a frame.
    from igserver.render.sky.sky import CIRRUS_REDRAW_PX
    sky = renderer.graph.passes["sky"]
    base = scene(3.0, 200.0, pitch=10.0, camera={"exposure_ev": 11.0},  # fixed: no metering feedback
                 weather={"cirrus_coverage": 0.5, "cirrus_wind_speed": 40.0})
    base = base.model_copy(update={"camera": base.camera.model_copy(update={"width": 640, "height": 360})})

    def at(i, s=base):
        return s.model_copy(update={"time": s.time.model_copy(update={"sim_time": 1000.0 + i / 30.0})})

    n = 30
    stream, drew = [], []
    for i in range(n):
        before = sky.cirrus_draws
        stream.append(renderer.render(at(i)).rgba[..., :3].astype(int))
        drew.append(sky.cirrus_draws - before)
    assert drew[0] == 1 and drew[1] == 0  # the first frame draws it; 1.3 m of drift is far below a pixel
    assert 2 <= sum(drew) <= n // 3, drew  # the drift does redraw it, every few frames, not every frame
    try:
        sky.cirrus_redraw_px = 0.0  # the reference: drawn whenever anything moved
        fresh = [renderer.render(at(i)).rgba[..., :3].astype(int) for i in range(n)]
    finally:
        sky.cirrus_redraw_px = CIRRUS_REDRAW_PX
    for i in range(n):
        err = np.abs(stream[i] - fresh[i]).max()
        if drew[i]:
            assert err == 0, i  # a redrawn table is the fresh one, bit for bit
        else:
            # <= 0.25 px of drift on streaks that change by a few levels per pixel here, so under a
            # level, plus 8-bit rounding: 1 level.
            assert err <= 1, (i, err)
    # Every other input redraws it at once (a still frame first: nothing changed, nothing drawn).
    s0 = at(n)
    renderer.render(s0)
    changes = {
        "heading": {"camera": {"heading": 200.05}},
        "fov": {"camera": {"fov_y": 60.05}},
        "camera altitude": {"camera": {"position": [0.0, 0.0, 3.0]}},
        "sun": {"time": {"sun_override": {"elevation": 3.05, "azimuth": 200.0}}},
        "coverage": {"weather": {"cirrus_coverage": 0.51}},
        "layer altitude": {"weather": {"cirrus_altitude": 9100.0}},
    }
    from igserver.scene.patch import apply_patch
    for name, patch in [("none", {}), ("exposure", {"camera": {"exposure_ev": 11.5}})] + list(changes.items()):
        renderer.render(s0)
        before = sky.cirrus_draws
        renderer.render(apply_patch(s0, patch))
        assert sky.cirrus_draws - before == (name in changes), name


@pytest.mark.parametrize("pitch,heading,fov,alt,roll", [(10.0, 200.0, 60.0, 2.0, 0.0), (1.0, 288.0, 50.0, 6.0, 0.0),
                                                        (60.0, 90.0, 60.0, 2.0, 0.0), (5.0, 30.0, 5.0, 2.0, 20.0),
                                                        (-10.0, 0.0, 60.0, 12_000.0, 0.0)])
def test_cirrus_drift_bound_holds_the_largest_pixel_shift(renderer, pitch, heading, fov, alt, roll):
    # sky.py cirrus_drift_px against the shift measured on a 65 x 37 grid of the frame: each point of
    # the layer (sphere at 9 km) moved by the drift, projected back into the frame. The bound must
    # hold (a redraw is never late) and stay within 3x of the largest measured shift (it takes the
    # nearest distance and the farthest corner's magnification together: measured 1.0-2.2x in these
    # views; looser would redraw for nothing).
    from igserver.render.sky.sky import cirrus_drift_px
    s = scene(20.0, heading, alt=alt, pitch=pitch, fov=fov, weather={"cirrus_coverage": 0.5})
    s = s.model_copy(update={"camera": s.camera.model_copy(update={"width": 640, "height": 360, "roll": roll})})
    frame = build_frame(renderer.ctx, s)
    u, view = frame.uniforms, frame.view
    off = np.array([10.0, 20.0])
    delta = np.array([3e-4, -2e-4])  # noise units (6 km): ~2 m, a second of a 2 m/s drift
    bound = cirrus_drift_px(frame, tuple(off), tuple(off + delta))
    R = float(u["u_bottom_radius_km"])
    c = np.array([0.0, 0.0, R + float(u["u_camera_altitude"]) * 1e-3])
    rc = R + float(u["u_cirrus_altitude_km"])
    rot = np.asarray(view.rotation, dtype=np.float64)
    right, forward, up = rot[:, 0], rot[:, 1], rot[:, 2]
    lt, rt, bt, tt = (float(t) for t in view.tangents)
    gu, gv = np.meshgrid(np.linspace(0, 1, 65), np.linspace(0, 1, 37))
    d = forward + (lt + gu[..., None] * (rt - lt)) * right + (bt + gv[..., None] * (tt - bt)) * up
    d /= np.linalg.norm(d, axis=-1, keepdims=True)
    b = c[2] * d[..., 2]
    disc = b * b - (c[2] ** 2 - rc * rc)
    below = c[2] < rc
    t = np.where(below, -b + np.sqrt(np.maximum(disc, 0)), -b - np.sqrt(np.maximum(disc, 0)))
    ok = (disc > 0) & (t > 0)
    if below:  # rays into the earth do not meet the layer
        ok &= ~((b < 0) & (b * b - (c[2] ** 2 - R * R) > 0))
    p = c + d * t[..., None]
    q = p.copy()
    q[..., :2] -= delta * 6.0  # the pattern seen at q = p.xy / 6 + offset moves by -delta * 6 km
    q[..., 2] = np.sqrt(rc * rc - (q[..., :2] ** 2).sum(-1))

    def px(x):
        rel = x - c
        f = rel @ forward
        return np.stack([(rel @ right / f - lt) / (rt - lt) * 640, (rel @ up / f - bt) / (tt - bt) * 360], -1)
    shift = np.linalg.norm(px(q) - px(p), axis=-1)[ok]
    assert shift.size > 0
    assert shift.max() <= bound <= 3.0 * shift.max(), (shift.max(), bound)


HAZY_CASES = {
    "fog_noon": dict(el=50.0, atmosphere={"visibility": 300.0}),
    "haze_low_sun_ahead": dict(el=2.0, pitch=3.0, atmosphere={"visibility": 5000.0}),
    "just_above_a_fog_top": dict(el=20.0, alt=34.0, pitch=-1.0, atmosphere={"visibility": 300.0, "fog_top": 30.0}),
    "haze_from_1km": dict(el=3.0, alt=1000.0, pitch=0.0, atmosphere={"visibility": 3000.0}),
    "moonlit_haze": dict(el=-30.0, heading=251.0, pitch=25.0, time={"utc": "2026-11-23T00:00:00Z"},
                         atmosphere={"visibility": 2000.0}),
}


@pytest.mark.parametrize("case", list(HAZY_CASES))
def test_hazy_sky_table_matches_the_haze_per_pixel(renderer, case):
    # The sky pass reads the sky through the haze layer from a table on the sky-view map, filled
    # per change (sky/sky_hazy.glsl), instead of evaluating haze_sky() per pixel: against the
    # per-pixel evaluation, within 2 % of the radiance (p99.9; 1.6 % just above a fog top, under 0.6 %
    # elsewhere) and about one 8-bit level
    # (measured at 640x360 in fog, haze, dusk, at night with the moon's glow in the haze, and from
    # up to one scale height above the layer: max 1 level, 2 on one pixel from 1 km).
    from igserver.render.sky.sky import SkyPass
    s = scene(**HAZY_CASES[case])
    s = s.model_copy(update={"camera": s.camera.model_copy(update={"width": 320, "height": 180})})
    sky = renderer.graph.passes["sky"]
    fills = sky.hazy_fills
    try:
        SkyPass.hazy_table = False
        ref_rgb, ref = renderer.render(s).rgba[..., :3].astype(float), radiance(renderer, s)
        SkyPass.hazy_table = True
        rgb, table = renderer.render(s).rgba[..., :3].astype(float), radiance(renderer, s)
    finally:
        SkyPass.hazy_table = True
    assert sky.hazy_fills > fills  # the table path ran
    sky_px = renderer.read_distance() > 1e29
    assert sky_px.mean() > 0.3
    rel = np.abs(table - ref) / np.maximum(np.abs(ref), 1e-6 * ref.max())
    assert np.percentile(rel[sky_px], 99.9) < 0.02, np.percentile(rel[sky_px], 99.9)
    assert np.abs(rgb - ref_rgb).max() <= 2.0 and (np.abs(rgb - ref_rgb) > 1.0).mean() < 1e-3


def test_hazy_sky_table_not_used_where_its_rows_cannot_hold_the_limb(renderer):
    # From high above the haze (10 km) or a fog top (300 m above it) the layer's limb is finer than
    # the table's rows: the sky pass keeps haze_sky() per pixel there.
    sky = renderer.graph.passes["sky"]
    for s in (scene(10.0, alt=10_000.0, pitch=-3.0, atmosphere={"visibility": 10_000.0}),
              scene(20.0, alt=330.0, pitch=-1.0, atmosphere={"visibility": 300.0, "fog_top": 30.0})):
        fills = sky.hazy_fills
        renderer.render(s)
        assert sky.hazy_fills == fills


def test_hazy_sky_table_filled_per_change(renderer):
    # Filled again only when one of its inputs changed: the same frame twice, or another heading
    # (the table is in directions relative to the sun), fill nothing; a new visibility does.
    sky = renderer.graph.passes["sky"]
    s = scene(10.0, atmosphere={"visibility": 2000.0})
    renderer.render(s)
    fills = sky.hazy_fills
    renderer.render(s)
    renderer.render(s.model_copy(update={"camera": s.camera.model_copy(update={"heading": 120.0})}))
    assert sky.hazy_fills == fills
    renderer.render(scene(10.0, atmosphere={"visibility": 1500.0}))
    assert sky.hazy_fills == fills + 1
