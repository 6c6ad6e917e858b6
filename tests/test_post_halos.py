"""Fog halos of point lights (post/halos.py, post/halos.frag.glsl): the closed form through one
table against a float64 quadrature, and the GPU pass against the table's numpy mirror."""

from __future__ import annotations

import math
from pathlib import Path

import moderngl
import numpy as np
import pytest

from igserver.render import bindings
from igserver.render.frame import build_frame
from igserver.render.post import halos
from igserver.render.camera import cone_on_screen, make_view
from igserver.render.post.post import DISPLAY_SLOPE, HALO_SCALE, halo_uniforms
from igserver.scene import apply_patch, load_scene

try:  # the reference quadrature's 4096 Gauss-Legendre nodes: scipy's Newton iteration (~0.1 s) instead of
    # numpy's leggauss, which takes the eigenvalues of a 4096 x 4096 matrix (3.5 s on a quiet 2-core
    # machine, 20 s on a loaded one: the slowest test of the fast GL-free subset); the same nodes to
    # 2e-16 and weights to 4e-10 relative, far inside the 3 % the table is held to
    from scipy.special import roots_legendre

    halos._NODES.setdefault(4096, roots_legendre(4096))
except ImportError:  # scipy comes with the test extras (pvlib); without it numpy's nodes, slower
    pass


def _configurations(n: int, seed: int):
    """Lights anywhere around the ray (ahead, beside, behind the camera, on the ray), fog from
    visibility ~30 m to ~30 km, surfaces from 1 m to past 20 optical depths."""
    rng = np.random.default_rng(seed)
    for _ in range(n):
        beta = 10 ** rng.uniform(-4, -1)
        g = rng.uniform(halos.G_MIN, halos.G_MAX)
        d = 10 ** rng.uniform(0, 3.5)
        angle = rng.uniform(0, math.pi) if rng.uniform() < 0.5 else 10 ** rng.uniform(-4, -0.5)
        t0, h = d * math.cos(angle), max(d * math.sin(angle), 0.05)
        D = min(10 ** rng.uniform(0, 4), 20 / beta) if rng.uniform() < 0.7 else 20 / beta
        yield t0, h, D, beta, g


def test_table_matches_the_quadrature():
    errors, scale = [], []
    for t0, h, D, beta, g in _configurations(200, seed=3):
        ref = halos.halo_reference(t0, h, D, beta, g)
        tab = halos.halo_from_table(t0, h, D, beta, g)
        assert math.isfinite(tab) and tab >= 0.0
        errors.append(abs(tab - ref) / max(ref, 1e-300))
        scale.append(ref * beta / h)  # radiance per unit omega I
    errors, scale = np.array(errors), np.array(scale)
    visible = scale > 1e-3 * scale.max()  # where a halo is within 10 EV of the brightest: what can show
    # 3 %: an order of magnitude inside the 8-midpoint quadrature the table replaced (p99 29 % over
    # the same draws); linear interpolation over phi nodes 0.7 deg apart under the HG forward
    # peak (g = 0.85: ~9 deg wide) is the limit.
    assert np.max(errors[visible]) < 0.03
    # Where the halo is faint the absolute error still is: no cancellation blow-up behind the camera.
    assert np.max(np.abs(errors * scale)) < 0.03 * scale.max()


@pytest.mark.parametrize("d, beta", [(46.0, 1.1e-4), (20.0, 5e-3), (300.0, 1e-3)])
def test_light_straight_behind_the_ray(d, beta):
    # The table's last cell (phi near pi/2: the light on the ray's backward extension, a view ray
    # near the light's antipode). A linear continuation of K there overshot the quadrature 6x within
    # 0.1 deg of the antipode (a bright dot opposite a fire behind the camera); K ~ log(pi/2 - phi).
    for angle_deg in (178.0, 179.0, 179.5, 179.9, 179.97, 180.0):
        angle = math.radians(angle_deg)
        t0, h = d * math.cos(angle), max(d * math.sin(angle), 0.05)
        ref = halos.halo_reference(t0, h, 20.0 / beta, beta, 0.75)
        assert halos.halo_from_table(t0, h, 20.0 / beta, beta, 0.75) == pytest.approx(ref, rel=0.08)


def test_light_behind_the_camera_does_not_overflow():
    # The case that overflowed a table of H itself: exp(-beta t0) ~ e^134 times a tiny H.
    t0, h, D, beta, g = -1792.4, 491.7, 29.7, 0.0751, 0.83
    ref = halos.halo_reference(t0, h, D, beta, g)
    assert halos.halo_from_table(t0, h, D, beta, g) == pytest.approx(ref, abs=1e-30)


def test_gpu_halos_match_the_table(renderer):
    scene = apply_patch(load_scene("night_fire"), {"camera": {"width": 160, "height": 90, "exposure_ev": 2.0},
                                                   "atmosphere": {"visibility": 800.0, "visibility_transition": 0.0}})
    renderer.render(scene)
    frame = build_frame(renderer.ctx, scene, None)
    uniforms = halo_uniforms(frame)
    assert uniforms["u_halo_count"] > 0, "the scene must show a halo for this test to mean anything"
    post = renderer.graph.passes["post"]
    tex = post._halo_target[0]
    w, h = tex.size
    assert (w, h) == (-(-160 // HALO_SCALE), -(-90 // HALO_SCALE))
    data = np.frombuffer(tex.read(), dtype=np.float16).reshape(h, w, 4).astype(np.float64)
    view = frame.view
    left, right, bottom, top = view.tangents
    rot = np.asarray(view.rotation, dtype=np.float64)
    pos = np.frombuffer(uniforms["u_halo_pos"], np.float32).reshape(-1, 4)[:, :3]
    col = np.frombuffer(uniforms["u_halo_intensity"], np.float32).reshape(-1, 4)[:, :3]
    beta, omega, g = uniforms["u_halo_beta"], uniforms["u_halo_omega"], uniforms["u_halo_g"]
    checked = 0
    for j, i in [(h // 2, w // 2), (h // 3, w // 4), (2 * h // 3, 3 * w // 4), (h - 1, 0), (5, w - 3)]:
        u, v = (i + 0.5) / w, (j + 0.5) / h
        d = rot[:, 1] + (left + (right - left) * u) * rot[:, 0] + (bottom + (top - bottom) * v) * rot[:, 2]
        d /= np.linalg.norm(d)
        D = 2.0 ** data[j, i, 3]
        expected = np.zeros(3)
        for p, c in zip(pos[:uniforms["u_halo_count"]], col):
            t0 = float(p @ d)
            hh = max(float(np.linalg.norm(p - t0 * d)), 0.05)
            expected += c * omega * beta / hh * halos.halo_from_table(t0, hh, D, beta, g)
        expected *= frame.exposure
        # 1 %: half-float storage of the target (0.05 %), and the texture unit's linear filter
        # weights (8 bits on llvmpipe) between table nodes whose K differs by up to ~1 (0.4 %).
        assert data[j, i, :3] == pytest.approx(expected, rel=0.01, abs=1e-3 * max(expected.max(), 1e-6))
        checked += expected.max() > 0.0
    assert checked >= 3


def _mirror_factor(t0, h, D, d, beta, g):
    """halos.halo_from_table over arrays: phi from float64 inverse tangents, the table's lookup
    (the shader takes neither: its u axis and tail come from lengths, halos.frag.glsl)."""
    phi0, phi1 = np.arctan2(-t0, h), np.arctan2(D - t0, h)
    r1 = np.hypot(D - t0, h)
    near = np.exp(halos.lookup(phi0, beta * h, g) - beta * d)
    far = np.exp(halos.lookup(phi1, beta * h, g) - beta * (D + r1))
    return np.maximum(near - far, 0.0)


def test_gpu_halos_match_the_table_on_every_pixel(renderer):
    # Every pixel of the halo target against the table's numpy mirror, in dense fog (visibility
    # 150 m, 20 optical depths at 1 km) with the fire ahead and a lamp 30 m straight behind the
    # camera, 0.3 m aside: the view rays near screen centre pass close to the lamp's antipode (the
    # near end in the table's tail), the ground beyond the fire puts far ends in the tail, the
    # ground before it and the sky the rest. The shader reaches u and the tail's scaling through
    # lengths where the mirror takes phi = atan2: a slip in either (the u axis, h_eff, the stable
    # form of T) moves whole regions by far more than the 1 % allowed (half-float storage 0.05 %,
    # the texture unit's 8-bit filter weights 0.4 %).
    scene = apply_patch(load_scene("night_fire"), {
        "camera": {"width": 160, "height": 90, "exposure_ev": 2.0},
        "atmosphere": {"visibility": 150.0, "visibility_transition": 0.0},
        "lights": [{"id": "behind", "position": [0.3, -60.0, 3.2], "color": [1.0, 0.9, 0.8],
                    "intensity": 5000.0, "range": 200.0}]})
    renderer.render(scene)
    frame = build_frame(renderer.ctx, scene, None)
    uniforms = halo_uniforms(frame)
    n = uniforms["u_halo_count"]
    pos = np.frombuffer(uniforms["u_halo_pos"], np.float32).reshape(-1, 4)[:n].astype(np.float64)
    col = np.frombuffer(uniforms["u_halo_intensity"], np.float32).reshape(-1, 4)[:n, :3].astype(np.float64)
    assert np.any(pos[:, 1] < 0.0) or n >= 2, "the lamp behind the camera must be drawn"
    post = renderer.graph.passes["post"]
    w, h = post._halo_target[0].size
    data = np.frombuffer(post._halo_target[0].read(), dtype=np.float16).reshape(h, w, 4).astype(np.float64)
    full = np.frombuffer(renderer._targets.distance.read(), dtype=np.float32).reshape(90, 160)
    # the shader's distance: the nearest of each HALO_SCALE x HALO_SCALE block, clamped
    blocks = np.full((h * HALO_SCALE, w * HALO_SCALE), np.inf)
    blocks[:90, :160] = full
    D = blocks.reshape(h, HALO_SCALE, w, HALO_SCALE).min(axis=(1, 3))
    D = np.clip(D, 1e-3, uniforms["u_halo_far"])
    view = frame.view
    left, right, bottom, top = view.tangents
    rot = np.asarray(view.rotation, dtype=np.float64)
    u = (np.arange(w) + 0.5) / w
    v = (np.arange(h) + 0.5) / h
    dirs = (rot[:, 1][None, None] + (left + (right - left) * u)[None, :, None] * rot[:, 0]
            + (bottom + (top - bottom) * v)[:, None, None] * rot[:, 2])
    dirs /= np.linalg.norm(dirs, axis=-1, keepdims=True)
    beta, omega, g = uniforms["u_halo_beta"], uniforms["u_halo_omega"], uniforms["u_halo_g"]
    expected = np.zeros((h, w, 3))
    tails = [0, 0]
    for p, c in zip(pos, col):
        t0 = dirs @ p[:3]
        hh = np.maximum(np.linalg.norm(p[:3] - t0[..., None] * dirs, axis=-1), 0.05)
        expected += c * (omega * beta / hh * _mirror_factor(t0, hh, D, p[3], beta, g))[..., None]
        tails[0] += int(np.sum(np.arctan2(-t0, hh) > halos.PHI_TAIL))
        tails[1] += int(np.sum(np.arctan2(D - t0, hh) > halos.PHI_TAIL))
    expected *= frame.exposure
    assert min(tails) > 0, "both ends of some rays must lie in the table's tail"
    err = np.abs(data[..., :3] - expected)
    assert np.all(err <= 0.01 * expected + 1e-3 * expected.max())


@pytest.mark.parametrize("size", [(101, 57), (160, 90)])
def test_meter_holds_the_block_means_of_the_frame(renderer, size):
    # The exposure meter (post/meter.glsl) reads 2x2 texel groups through one bilinear fetch at their
    # shared corner: each cell must hold the plain mean of its block of the HDR frame, blocks cut by
    # the frame's edge (odd rows and columns: 101x57 in blocks of 4) included.
    scene = apply_patch(load_scene("demo"), {"camera": {"width": size[0], "height": size[1]}})
    renderer.render(scene)
    hdr = np.maximum(renderer.read_hdr()[::-1, :, :3].astype(np.float64), 0.0)  # bottom row first, as GL
    post = renderer.graph.passes["post"]
    cells_w, cells_h = post._meter_tex.size
    block = math.ceil(size[0] / 32)
    meter = np.frombuffer(post._meter_tex.read(), dtype=np.float32).reshape(cells_h, cells_w, 4)[..., :3]
    for j in range(cells_h):
        for i in range(cells_w):
            expected = hdr[j * block:(j + 1) * block, i * block:(i + 1) * block].mean(axis=(0, 1))
            assert meter[j, i] == pytest.approx(expected, rel=2e-3, abs=1e-6)


def test_bound_holds_for_every_surface_distance():
    # halo_radius rests on halo_bound: the factor of any ray at that angle from the light, whatever
    # surface ends it, is never above it.
    for t0, h, D, beta, g in _configurations(300, seed=5):
        d, angle = math.hypot(t0, h), math.atan2(h, t0)
        assert halos.halo_from_table(t0, h, D, beta, g) <= float(halos.halo_bound(angle, d, beta, g)) * (1 + 1e-9)


@pytest.mark.parametrize("d, beta, intensity", [(32.0, 7e-4, 3000.0), (80.0, 7e-4, 1.6e5), (500.0, 5e-3, 2e4)])
def test_radius_bounds_where_a_halo_can_reach_the_threshold(d, beta, intensity):
    omega, g, threshold = 0.93, 0.75, 0.5
    radius = halos.halo_radius(d, beta, omega, g, intensity, threshold)
    angles = np.linspace(1e-4, math.pi, 4001)
    hh = np.maximum(d * np.sin(angles), 0.05)
    radiance = omega * beta * intensity / hh * halos.halo_bound(angles, d, beta, g)
    assert np.all(radiance[angles > radius] < threshold)
    if radius < math.pi:
        assert radiance.max() >= threshold and radius > 0.0


def test_cone_on_screen():
    view = make_view(load_scene("sky_only").camera)
    left, right, bottom, top = view.tangents
    right_edge = math.atan(right)  # rad from the forward direction (the frame is centred)
    rot = np.asarray(view.rotation)

    def towards(yaw):  # a direction in the camera's horizontal plane, yaw rad to the right
        return math.cos(yaw) * rot[:, 1] + math.sin(yaw) * rot[:, 0]

    assert cone_on_screen(view, towards(0.0), 1e-3)
    assert not cone_on_screen(view, towards(right_edge + 0.1), 0.05)
    assert cone_on_screen(view, towards(right_edge + 0.1), 0.15)
    assert not cone_on_screen(view, -rot[:, 1], 0.3)  # behind the camera
    assert cone_on_screen(view, -rot[:, 1], 2.0)  # reaches round to the frame


def test_a_lamp_whose_halo_shows_is_drawn(renderer):
    # The demo's lamp (3000 cd, 32 m from the camera, dusk haze): its halo a fraction of a degree
    # off the lamp is worth several display levels, so it must be drawn. The criterion before stop
    # 21 (one pixel off the light, 1 % of display white) dropped it: up to 6 levels were missing.
    scene = load_scene("demo")
    renderer.render(scene)
    frame = build_frame(renderer.ctx, scene, None)
    lamp = next(l for l in frame.lights if float(np.max(l.color)) == pytest.approx(3000.0))
    uniforms = halo_uniforms(frame)
    pos = np.frombuffer(uniforms["u_halo_pos"], np.float32).reshape(-1, 4)[:uniforms["u_halo_count"], :3]
    rel = frame.view.relative(lamp.position)
    assert np.any(np.all(np.abs(pos - rel) < 1e-3, axis=1)), "the lamp's halo is not drawn"
    haze = frame.resources["haze"]
    beta, d = uniforms["u_halo_beta"], float(np.linalg.norm(rel))
    angle = math.radians(0.3)
    t0, h = d * math.cos(angle), d * math.sin(angle)
    radiance = haze.omega * beta * 3000.0 / h * halos.halo_from_table(t0, h, 1e6, beta, haze.g)
    assert radiance * frame.exposure * DISPLAY_SLOPE > 2.0 / 255.0


def test_an_invisible_halo_is_not_drawn(renderer):
    # A dimmer lamp (300 cd) by day in clear air (visibility 20 km): its halo stays under half a
    # display level everywhere, even in the lamp's own pixel. (The demo's 3000 cd lamp is not so
    # faint by day: its pixel may gain ~2 levels over the dark sea.)
    scene = apply_patch(load_scene("demo"), {"time": {"utc": "2026-06-21T10:00:00Z"}, "effects": [],
                                             "lights": [{"id": "quay_lamp", "position": [-30.0, -110.0, 8.0],
                                                         "color": [1.0, 0.8, 0.55], "intensity": 300.0, "range": 80.0}],
                                             "atmosphere": {"visibility": 20000.0, "visibility_transition": 0.0}})
    renderer.render(scene)
    frame = build_frame(renderer.ctx, scene, None)
    assert frame.lights, "the lamp must be there for this test to mean anything"
    assert halo_uniforms(frame)["u_halo_count"] == 0


def test_rain_glows_with_half_its_extinction(renderer):
    # The harbour fire in 8 mm/h rain (rain_harbour): the air alone sees 20 km; the rain adds
    # beta_p = 0.365 R^0.63 /km (weather.py, extinction efficiency 2). Half of that is diffraction
    # into lambda/D ~ 0.03 deg around each beam (1 mm drops at 0.55 um), inside the light's own
    # pixel: the glow of the fire and the lamp in the rain comes from the air's extinction plus the
    # other half only. Reference: the layer's extinction at the camera with and without the rain
    # (Koschmieder for the air, Marshall-Palmer for the rain); exact up to float rounding.
    from igserver.weather import precipitation_extinction

    def layer_beta(scene):
        frame = build_frame(renderer.ctx, scene, None)
        haze = frame.resources["haze"]
        return float(haze.beta[1] * haze.density(frame.camera_altitude - scene.location.altitude)), frame

    wet = load_scene("rain_harbour")
    dry = apply_patch(wet, {"weather": {"precipitation": {"type": "none"}}})
    rain = precipitation_extinction("rain", 8.0)
    beta_dry, frame_dry = layer_beta(dry)
    beta_wet, frame_wet = layer_beta(wet)
    assert beta_wet - beta_dry == pytest.approx(rain, rel=5e-3)  # the layer's density 4 m up: e^(-4/1200)
    uniforms = halo_uniforms(frame_wet)
    assert uniforms["u_halo_count"] >= 1
    assert uniforms["u_halo_beta"] == pytest.approx(beta_wet - 0.5 * rain, rel=1e-5)
    assert halo_uniforms(frame_dry)["u_halo_beta"] == pytest.approx(beta_dry, rel=1e-6)


def test_radius_kept_per_light_and_fog_follows_intensity_and_threshold_exactly():
    # halo_radius keeps the bound's profile per (distance, fog, pixel angle); the flickering
    # intensity and the exposure's threshold still decide the radius every call, exactly as the
    # profile computed afresh does.
    d, beta, omega, g, pixel = 60.0, 8e-4, 0.93, 0.78, 1e-3
    angles = np.maximum(halos._ANGLES, 0.5 * pixel)
    hh = np.maximum(d * np.sin(angles), 0.05)
    bound = halos.halo_bound(angles, d, beta, g)
    radii = set()
    for intensity in np.geomspace(10.0, 1e6, 25):
        for threshold in (1e-3, 0.05, 2.0):
            radiance = omega * beta * intensity / hh * bound
            above = np.nonzero(radiance >= threshold)[0]
            expected = 0.0 if len(above) == 0 else float(halos._ANGLES[min(above[-1] + 1, len(halos._ANGLES) - 1)])
            got = halos.halo_radius(d, beta, omega, g, float(intensity), threshold, pixel)
            assert got == expected
            radii.add(got)
    assert len(radii) > 5  # the intensity and threshold really move it
    # another distance or fog is another profile
    assert any(halos.halo_radius(d * 3, beta, omega, g, 1e5, t, pixel) != halos.halo_radius(d, beta, omega, g, 1e5, t, pixel)
               for t in np.geomspace(1e-3, 1e2, 11))


@pytest.mark.parametrize("size", [(9, 7), (8, 6)])
def test_nearest_distance_of_a_block(renderer, size):
    # common/nearest_distance.glsl at scale 2 (the halos' and the volumes' reduced passes) takes the
    # block's 2x2 by one gather around its shared corner: it must return the plain minimum of the
    # block, the frame's last row and column (odd sizes) clamped as the fetches of other scales.
    source = (Path(halos.__file__).resolve().parents[1] / "common" / "nearest_distance.glsl").read_text()
    ctx = renderer.ctx
    w, h = size
    values = np.random.default_rng(7).uniform(1.0, 1000.0, (h, w)).astype(np.float32)
    src = ctx.texture((w, h), 1, values.tobytes(), dtype="f4")
    src.filter = (moderngl.NEAREST, moderngl.NEAREST)
    src.repeat_x = src.repeat_y = False
    lw, lh = -(-w // 2), -(-h // 2)
    out = ctx.texture((lw, lh), 2, dtype="f4")
    fbo = ctx.framebuffer([out])
    program = ctx.program(
        vertex_shader="#version 430\nvoid main() { vec2 p = vec2((gl_VertexID << 1) & 2, gl_VertexID & 2);"
                      " gl_Position = vec4(p * 2.0 - 1.0, 0.0, 1.0); }",
        fragment_shader="#version 430\nuniform sampler2D u_d;\nout vec2 o;\n" + source +
                        "void main() { ivec2 q = ivec2(gl_FragCoord.xy); o = vec2(nearest_distance(u_d, q, 2),"
                        " nearest_distance(u_d, q, 3)); }")
    program["u_d"].value = 7
    src.use(7)
    fbo.use()
    ctx.disable(moderngl.DEPTH_TEST | moderngl.BLEND)
    vao = ctx.vertex_array(program, [])
    vao.render(moderngl.TRIANGLES, vertices=3)
    got = np.frombuffer(out.read(), np.float32).reshape(lh, lw, 2)
    padded = np.pad(values, ((0, 2 * lh - h), (0, 2 * lw - w)), mode="edge")
    expected = padded.reshape(lh, 2, lw, 2).min(axis=(1, 3))
    for obj in (vao, program, fbo, out, src):
        obj.release()
    bindings.forget_bindings(ctx)  # unit 7 was bound behind the record's back
    assert np.array_equal(got[..., 0], expected)
    # scale 3 through the clamped fetches covers a 3x3 block: a second, independent path
    p3 = np.pad(values, ((0, 3 * lh - h), (0, 3 * lw - w)), mode="edge")
    assert np.array_equal(got[..., 1], p3[:3 * lh, :3 * lw].reshape(lh, 3, lw, 3).min(axis=(1, 3)))
