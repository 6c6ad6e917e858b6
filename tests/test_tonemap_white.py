"""The display transform's path to white (post/tonemap.glsl display_transform, its numpy mirror
post/exposure.py display_transform): an over-exposed saturated colour runs to white as the light
rises, as film's shoulder, a camera and the eye show it (and ACES's RRT does; Narkowicz's per-channel
fit alone leaves a blackbody's core pure yellow: its blue is ~0). Below the threshold the curve is
the plain per-channel fit, bit for bit; through it no channel steps or falls back."""

from __future__ import annotations

import colorsys

import numpy as np
import pytest

from igserver.render import bindings
from igserver.render.frame import build_frame
from igserver.render.post.exposure import (MAX_OVER_MEAN_EV, WHITE_STOPS, WHITE_THRESHOLD, aces_fit,
                                           display_metered_ev100, display_transform, displayed, displayed_rgb,
                                           exposure_of_ev100, key_of, linear_to_srgb)
from igserver.render.shaders import ProgramCache, set_uniforms
from igserver.scene import apply_patch, load_scene

# Saturated colours (linear sRGB, brightest channel 1): a 1900 K blackbody (the fire's core colour),
# orange, the primaries, a sodium lamp's yellow, a deep sky blue.
COLOURS = np.array([[1.0, 0.135, 0.0], [1.0, 0.35, 0.02], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0],
                    [0.0, 0.0, 1.0], [1.0, 0.8, 0.05], [0.1, 0.3, 1.0]])
RAMP = np.geomspace(1e-3, 2.0 ** 14, 4000)  # scale of the brightest channel: 10 stops under to 14 over


def _ramp(colour):
    return RAMP[:, None] * colour[None, :]


@pytest.mark.parametrize("colour", COLOURS, ids=lambda c: "-".join(f"{v:g}" for v in c))
def test_a_saturated_ramp_is_monotone_continuous_and_ends_white(colour):
    shown = displayed_rgb(_ramp(colour))
    # Monotone: no channel ever falls while the light rises (a fall would show as a dark ring).
    assert np.all(np.diff(shown, axis=0) >= -1e-12)
    # Continuous: ramp steps are 0.35 % of the light; no channel jumps more than half an 8-bit level
    # anywhere, the threshold included (a smoothstep weight: no step and no kink in the slope).
    assert np.max(np.abs(np.diff(shown, axis=0))) < 0.5 / 255.0
    below = RAMP <= WHITE_THRESHOLD
    plain = aces_fit(_ramp(colour))
    # Below the threshold the plain per-channel curve, exactly (most of every picture is unchanged).
    assert np.array_equal(display_transform(_ramp(colour))[below], plain[below])
    # The hue (HSV) is kept all the way: the colour only runs toward white.
    mixed = display_transform(_ramp(colour))
    for k in np.flatnonzero(~below)[::97]:
        if np.ptp(mixed[k]) > 1e-3:
            assert colorsys.rgb_to_hsv(*mixed[k])[0] == pytest.approx(colorsys.rgb_to_hsv(*plain[k])[0], abs=1e-9)
    # White at the top: 2^WHITE_STOPS times the threshold and above.
    top = RAMP >= WHITE_THRESHOLD * 2.0 ** WHITE_STOPS
    assert top.any() and np.all(shown[top] > 254.5 / 255.0)
    # ... and not before the light is well past the threshold: one stop over it keeps its colour
    # (the channels under the brightest rise by under 3 % of the range).
    one_stop = np.searchsorted(RAMP, 2.0 * WHITE_THRESHOLD)
    assert np.max(mixed[one_stop] - plain[one_stop]) < 0.03


def test_the_shader_shows_what_the_mirror_computes(renderer):
    # Ramps of every colour through the post pass's own shader (exposure correction 1, no mesopic
    # vision), against the numpy mirror with the same dither: within one 8-bit level everywhere.
    ctx = renderer.ctx
    renderer.render(apply_patch(load_scene("demo"), {"camera": {"width": 64, "height": 36}}))  # context, frame block
    width = 512
    ramp = np.geomspace(1e-3, 2.0 ** 13, width)
    # Rows: every colour unmarked (alpha 1, the sky's), then a reddened low sun's colour with the sky
    # pass's disk mark (alpha 1 + hue weight: 1 and 0.5), which keeps its hue instead.
    sun = np.array([1.0, 0.25, 0.03])
    colours = np.vstack([COLOURS, sun, sun])
    hue_weight = np.r_[np.zeros(len(COLOURS)), 1.0, 0.5]
    hdr = np.stack([ramp[:, None] * c[None, :] for c in colours]).astype(np.float32)  # (rows, width, 3)
    rows = hdr.shape[0]
    alpha = np.broadcast_to(1.0 + hue_weight[:, None, None], (rows, width, 1)).astype(np.float32)
    tex = ctx.texture((width, rows), 4, np.concatenate([hdr, alpha], axis=-1).tobytes(), dtype="f4")
    out = ctx.texture((width, rows), 4)
    fbo = ctx.framebuffer([out])
    program = ProgramCache(ctx).program("common/fullscreen.vert.glsl", "post/tonemap.glsl")
    vao = ctx.vertex_array(program, [])
    try:
        set_uniforms(program, {"u_hdr": 0, "u_exposure_correction": 1.0, "u_rod_fraction": 0.0})
        tex.use(0)
        fbo.use()
        ctx.viewport = (0, 0, width, rows)
        vao.render(vertices=3)
        got = np.frombuffer(fbo.read(components=4), np.uint8).reshape(rows, width, 4)[..., :3].astype(np.float64)
    finally:
        vao.release(), fbo.release(), out.release(), tex.release()
        bindings.forget_bindings(ctx)  # unit 0 held this texture behind the renderer's binding cache
    y, x = np.mgrid[0:rows, 0:width] + 0.5  # gl_FragCoord: pixel centres
    noise = np.modf(52.9829189 * np.modf(x * 0.06711056 + y * 0.00583715)[0])[0]
    shown = displayed_rgb(hdr.astype(np.float64), hue_weight[:, None, None])
    expected = np.clip(shown + (noise[..., None] - 0.5) / 255.0, 0.0, 1.0) * 255.0
    assert np.max(np.abs(got - expected)) <= 1.0
    # The shader's own ramp runs to white too (the mirror's test holds it monotone) ...
    assert np.all(got[:len(COLOURS), -1] >= 254)
    # ... but a marked sun's disk keeps its hue: red-orange (sRGB green 0.54 of red), however bright.
    assert got[len(COLOURS), -1, 1] < 0.6 * got[len(COLOURS), -1, 0]


@pytest.fixture(scope="module")
def harbour_night(renderer):
    scene = apply_patch(load_scene("harbour_night"), {"camera": {"width": 480, "height": 270}})
    result = renderer.render(scene)
    frame = build_frame(renderer.ctx, scene, None)
    exposed = renderer.read_hdr()[..., :3].astype(np.float64) * exposure_of_ev100(result.ev100) / frame.exposure
    return exposed, result.rgba[..., :3].astype(np.float64)


def test_the_fire_core_in_harbour_night_is_yellow_white(harbour_night):
    # Narkowicz's per-channel fit showed the over-exposed core (~(460, 63, 0) after exposure, a Planck
    # colour) as (255, 255, 0) and its reflection on the deck likewise. A photograph of a fire at night
    # shows its over-exposed core yellow-white: blue >= 180 of 255 where red and green are saturated and
    # the light is 7 stops or more over the threshold; still warm (blue below red and green).
    exposed, rgb = harbour_night
    m = exposed.max(axis=-1)
    core = m >= 128.0 * WHITE_THRESHOLD
    assert core.sum() >= 50, "the fire's core must be on screen for this test to mean anything"
    r, g, b = (np.median(rgb[core][:, i]) for i in range(3))
    assert r >= 250 and g >= 245
    assert 180 <= b <= 252  # yellow-white, not pure yellow and not a cold white
    assert np.percentile(rgb[core][:, 2], 10) >= 170


def test_the_fire_edges_in_harbour_night_stay_orange(harbour_night):
    # The flame's edges and the light it casts around, at most one stop over the threshold with a
    # blackbody's colour (green under half of red), keep their colour: orange, blue well under red.
    exposed, rgb = harbour_night
    m = exposed.max(axis=-1)
    edge = (m > WHITE_THRESHOLD) & (m < 2.0 * WHITE_THRESHOLD) & (exposed[..., 1] < 0.5 * exposed[..., 0])
    assert edge.sum() >= 50
    r, g, b = (np.median(rgb[edge][:, i]) for i in range(3))
    assert r >= 230 and r - g >= 40 and b <= 0.4 * r


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_the_meter_sees_what_the_screen_shows(seed):
    # The meter's solve (display_metered_ev100: the path to white applied only to the cells past the
    # threshold, their stops over it taken once) must land where the mirror's full transform of the
    # samples has the mean displayed value it aims at: D(k(M)) of a uniform field of the same mean.
    rng = np.random.default_rng(seed)
    cells = rng.lognormal(0.0, 1.0, (576, 3)) * 300.0  # cd/m^2, a day view
    cells[:3] *= np.array([1.0, 0.13, 0.0]) * 1e3  # a few cells of an over-exposed fire
    ev, m = display_metered_ev100(cells)
    exposure = exposure_of_ev100(ev)
    assert exposure < key_of(m) / m * 2.0 ** MAX_OVER_MEAN_EV * 0.99  # the solve, not its limit, chose it
    shown = displayed_rgb(cells * exposure)
    assert (cells * exposure).max() > 16.0 * WHITE_THRESHOLD  # the path to white is in play
    assert np.mean(shown) == pytest.approx(float(displayed(key_of(m))), abs=2e-4)
    # ... and the same samples metered through the plain per-channel curve would sit elsewhere.
    plain = linear_to_srgb(aces_fit(cells * exposure))
    assert abs(np.mean(plain) - np.mean(shown)) > 1e-3
