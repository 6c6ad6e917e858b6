"""Volume speed-ups and the stripe fix: footprint-limited march steps, reduced-resolution
march with depth-aware upsampling, re-modelling at a capped rate with keyframe blending.

Named to run before test_volumes.py, whose module-scoped second GL context, once released, leaves
no context current for the session renderer."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from igserver.quality.volumes import errors
from igserver.render.bindings import use_texture
from igserver.render.shaders import set_uniforms
from igserver.render.volumes.effects import puffing_frequency, scene_volumes
from igserver.render.volumes.settings import PRESETS, VolumeSettings
from igserver.scene import apply_patch, load_scene

MEDIUM = replace(PRESETS["medium"], lod=False)
EXACT = replace(MEDIUM, scale=1, model_hz=0.0)  # medium without either speed-up


@pytest.fixture
def volumes(renderer):
    vpass = renderer.graph.passes["volumes"]
    yield vpass
    vpass.settings = None


def render_with(renderer, vpass, scene, settings):
    vpass.settings = settings
    rgba = renderer.render(scene).rgba[..., :3].astype(np.float64)
    assert np.isfinite(renderer.read_hdr()).all()
    return rgba


def at_puff_bulge(scene, z: float):
    """The first sim_time at or after the scene's when the pool fire's puffing bulge (its widest
    flame) is at height z (m above the base): the flame's radius there is scaled by
    1 + a sin(phase(t) - k z) (effects.Volume.puff_phase, puff_wavenumber), widest at phase = pi / 2 + k z."""
    vol = next(v for v in scene_volumes(scene) if v.key[1] == "fire")
    t = scene.time.sim_time
    behind = (math.pi / 2.0 + vol.puff_wavenumber * (z - float(vol.base[2])) - vol.puff_phase(t)) % (2.0 * math.pi)
    return t + behind / (2.0 * math.pi * puffing_frequency(vol.effect.diameter))


def inside_plume(width=160, height=90):
    """The issue's view from inside night_fire's plume (camera in the tilted flame's top), at a
    puff's bulge: in a neck the flame's top draws in to the axis and leaves the camera in the clear
    air beside it (measured over a period in twelfths: coverage 0.76-1.0 from the bulge on, below
    0.5 for about half the period; 0.20 at t = 50)."""
    scene = apply_patch(load_scene("night_fire"), {
        "camera": {"position": [3, 0, 8], "pitch": 0, "exposure_ev": 9, "width": width, "height": height},
        "time": {"sim_time": 50}})
    return apply_patch(scene, {"time": {"sim_time": at_puff_bulge(scene, 8.0)}})


def adjacent_difference(rgb: np.ndarray) -> float:
    return float(np.abs(np.diff(rgb / 255.0, axis=1)).mean())


def test_no_stripes_inside_a_smoke_plume(renderer, volumes):
    scene = inside_plume()
    converged = adjacent_difference(render_with(renderer, volumes, scene, VolumeSettings(steps=512, octaves=3, resolution=32)))
    for settings in (EXACT, MEDIUM):
        diff = adjacent_difference(render_with(renderer, volumes, scene, settings))
        # The converged picture's own neighbour differences are the content's; a march that adds
        # a pattern of its own exceeds them (the stripes were 14x the converged value).
        assert diff < 2.0 * converged + 0.002, (settings, diff, converged)


def close_fire(width=128, height=72):
    return apply_patch(load_scene("night_fire"), {
        "camera": {"position": [0, -12, 2.5], "pitch": 12, "exposure_ev": 10, "width": width, "height": height},
        "time": {"sim_time": 100.0},
        "entities": [{"id": "crate", "model": "box", "position": [0.0, -4.0, 0.0], "scale": [1.5, 1.0, 3.0]}]})


def test_half_resolution_march_costs_little_error(renderer, volumes):
    scene = close_fire(256, 144)
    converged = render_with(renderer, volumes, scene, VolumeSettings(steps=256, octaves=4, resolution=64, lod=False))
    empty = render_with(renderer, volumes, scene.model_copy(update={"effects": []}), EXACT)
    covered = np.abs(converged - empty).max(-1) > 2
    assert covered.mean() > 0.03
    _, full = errors(render_with(renderer, volumes, scene, EXACT), converged, covered)
    for scale, allowance in ((2, 4.0), (4, 8.0)):
        _, reduced = errors(render_with(renderer, volumes, scene, replace(EXACT, scale=scale)), converged, covered)
        # Low-passed error (9x9 blur: bias, shifted edges, banding; not the fine noise). All of
        # what a reduced march adds here is the flame's silhouette: the 3 m pool fire is opaque
        # (optical depth ~6 across its base, its fuel's k beta: effect_kinds.FUELS) and its
        # radiance is many times white at EV 10, so a low-resolution texel the edge half covers
        # (alpha 1/2, radiance L/2) still clips white and the bilinear upsampling widens the
        # white flame by up to a march pixel against the night. Measured (half resolution, excess
        # over the full march's 1.3-1.5, at sim times 100, 57, 102.5, 203 and 310 s): 2.9-3.3
        # levels for an unpuffing flame, 3.4-3.7 puffing (the necks and bulges lengthen the
        # silhouette), and -0.3..0.2 either way at EV 13, where the flame is not clipped. 4.0
        # holds the puffing flame with a margin of 0.3 and still fails a march that blurs or
        # shifts the flame itself. A quarter-resolution pixel is 4 px wide here, about the
        # blur's half width, so more: 7.5 at t = 100 (7.0-9.4 over those times).
        assert reduced < full + allowance, (scale, reduced, full)


def test_depth_aware_upsampling_keeps_the_crate_silhouette(renderer, volumes):
    scene = close_fire()
    full = render_with(renderer, volumes, scene, EXACT)
    distance = renderer.read_distance()
    quarter = render_with(renderer, volumes, scene, replace(EXACT, scale=4))
    # The crate stands in front of the fire (4 m from the fire's axis, ~8 m from the camera).
    crate = (distance > 6.0) & (distance < 10.0)
    inner = crate.copy()
    for axis in (0, 1):
        for shift in (-1, 1):
            inner &= np.roll(crate, shift, axis=axis)
    assert inner.sum() > 20
    # Crate pixels take only samples at the crate's distance: the fire behind never bleeds in.
    assert np.abs(quarter - full)[inner].max() <= 3.0


def test_capped_remodelling_models_once_per_keyframe_and_moves_smoothly(renderer, volumes):
    settings = replace(MEDIUM, model_hz=10.0)
    volumes.settings = settings
    scene = close_fire(96, 54)
    frames, modelled = [], []
    for i in range(7):  # 30 Hz frames from t = 100.0; keyframes every 0.1 s (at frames 0, 3, 6)
        renderer.render(apply_patch(scene, {"time": {"sim_time": 100.0 + i / 30.0}}))
        frames.append(renderer.read_hdr()[..., :3].astype(np.float64))
        modelled.append(volumes.stats["modelled"])
    volumes.settings = None
    n_volumes = 2  # the fire and its smoke
    assert modelled[0] == 2 * n_volumes  # first frame: keyframes k and k + 1
    # Then each keyframe once, completed ahead of need: k + 2 is modelled over the frames of the
    # period before it is used (frames 1-2 finish keyframe 1002, needed from frame 3; 3-5 finish 1003).
    assert modelled[1:] == [0, n_volumes, 0, 0, n_volumes, 0]
    # Continuity: crossing a keyframe changes the picture no more than a step within a period.
    steps = [float(np.abs(b - a).mean()) for a, b in zip(frames, frames[1:])]
    assert max(steps[2], steps[3]) < 2.0 * max(steps[0], steps[1], steps[4]) + 1e-3, steps


def test_blended_keyframes_err_less_than_the_motion_they_bridge(renderer, volumes):
    key = apply_patch(close_fire(), {"time": {"sim_time": 100.0}})
    mid = apply_patch(key, {"time": {"sim_time": 100.05}})  # halfway between 10 Hz keys
    next_key = apply_patch(key, {"time": {"sim_time": 100.1}})
    exact = render_with(renderer, volumes, mid, EXACT)
    empty = render_with(renderer, volumes, mid.model_copy(update={"effects": []}), EXACT)
    covered = np.abs(exact - empty).max(-1) > 2
    blended = render_with(renderer, volumes, mid, replace(EXACT, model_hz=10.0))
    motion = errors(render_with(renderer, volumes, next_key, EXACT),
                    render_with(renderer, volumes, key, EXACT), covered)[1]
    error = errors(blended, exact, covered)[1]
    # The blend of two keyframes is wrong by less than the picture moves over one key period
    # (what a capped rate without blending would show as a jump).
    assert error < motion, (error, motion)


def test_march_resolution_change_fades_instead_of_popping(renderer, volumes):
    """A changed march scale in a running stream (auto quality moving a rung) cross-fades over
    SCALE_FADE_FRAMES frames: each step changes the picture by a fraction of the switch, and the
    fade ends on exactly the new scale's picture."""
    from igserver.render.volumes.volumes import SCALE_FADE_FRAMES

    half, full = replace(MEDIUM, scale=2), replace(MEDIUM, scale=1)
    scene = close_fire()
    t0 = scene.time.sim_time
    dt = 1e-4  # a running stream (0 < dt <= 1 s) in which the turbulence has not visibly moved
    at = lambda k: apply_patch(scene, {"time": {"sim_time": t0 + k * dt}})  # noqa: E731
    # The pop: the two scales' pictures of one instant (a re-render shows the new scale at once).
    render_with(renderer, volumes, at(0), half)
    pop_from = render_with(renderer, volumes, at(0), half)
    pop_to = render_with(renderer, volumes, at(0), full)
    pop = np.abs(pop_to - pop_from).mean()
    assert pop > 0.2, "the two scales must differ for this test to mean anything"
    # The same switch in a stream (the re-render at the same instant shows half alone: no fade).
    render_with(renderer, volumes, at(0), half)
    render_with(renderer, volumes, at(1), half)
    frames = [render_with(renderer, volumes, at(2), half)]
    for k in range(SCALE_FADE_FRAMES + 1):
        frames.append(render_with(renderer, volumes, at(3 + k), full))
    steps = [np.abs(b - a).mean() for a, b in zip(frames, frames[1:])]
    # Eight steps share the switch: none may carry more than half of it (a pop carries all of it).
    assert max(steps) < 0.5 * pop, (steps, pop)
    # After the fade: the new scale alone (same picture as a fresh render of that instant, up to the
    # turbulence's motion over dt, far below one level).
    assert np.abs(frames[-1] - render_with(renderer, volumes, at(3 + SCALE_FADE_FRAMES), full)).mean() < 0.05


def test_keyframes_modelled_ahead_in_slices_same_picture_no_spike(renderer, volumes):
    """The keyframe after next is modelled in slices over the frames before it is needed
    (modelling.py model_ahead): the frames of a 30 Hz stream are bit-identical to modelling each
    keyframe whole when it is needed (the same inputs, frozen at its first slice), and no frame
    after the first models more than half a keyframe (on demand, every third frame models a whole
    one: the spike in p99 frame time)."""
    volumes.settings = replace(MEDIUM, model_hz=10.0)
    scene = close_fire(96, 54)

    def stream(ahead: bool):
        volumes.model_ahead = ahead
        frames, voxels = [], []
        for i in range(10):
            renderer.render(apply_patch(scene, {"time": {"sim_time": 200.0 + i / 30.0}}))
            frames.append(renderer.read_hdr())
            voxels.append(volumes.stats["voxels"])
        return frames, voxels

    try:
        spread, spread_voxels = stream(True)
        whole, whole_voxels = stream(False)
    finally:
        volumes.model_ahead = True
        volumes.settings = None
    for a, b in zip(spread, whole):
        np.testing.assert_array_equal(a, b)
    keyframe = max(whole_voxels[1:])  # one keyframe of every volume, modelled in one frame
    assert keyframe > 0 and whole_voxels[1:].count(keyframe) == 3  # frames 3, 6, 9
    # Half a keyframe at most (2 or 3 frames left before each keyframe is needed), plus the
    # rounding of each volume's share up to 4 z slices of 32 x 32.
    fire_smoke_slices_rounding = 2 * 4 * 32 * 32
    assert max(spread_voxels[1:]) <= keyframe / 2 + fire_smoke_slices_rounding, (spread_voxels, keyframe)
    # The same work, each keyframe once: frames 1-8 model keyframes 2002-2004 ahead, which the
    # whole-keyframe stream models in frames 3, 6 and 9 (frame 9 of the spread stream begins 2005).
    assert sum(spread_voxels[1:9]) == sum(whole_voxels[1:]) == 3 * keyframe


def test_march_coarsens_only_where_voxels_are_large_on_screen(renderer, volumes):
    """With the screen-size LOD on, the march falls to quarter resolution where every voxel spans
    several pixels (march.py footprint_scale): inside the plume at 640x360, not 12 m away."""
    lod = replace(PRESETS["medium"], model_hz=0.0)  # lod on (the preset as used)
    scene = inside_plume(640, 360)
    quarter = render_with(renderer, volumes, scene, lod)
    assert volumes.stats["scale"] == 4
    half = render_with(renderer, volumes, scene, replace(lod, lod=False))
    assert volumes.stats["scale"] == 2
    render_with(renderer, volumes, close_fire(640, 360), lod)
    assert volumes.stats["scale"] == 2  # 12 m away: the preset's half resolution
    reference = render_with(renderer, volumes, scene, replace(lod, lod=False, steps=1024, scale=1))
    empty = render_with(renderer, volumes, scene.model_copy(update={"effects": []}), lod)
    covered = np.abs(reference - empty).max(-1) > 2
    assert covered.mean() > 0.5
    _, half_error = errors(half, reference, covered)
    _, quarter_error = errors(quarter, reference, covered)
    # Measured 0.07 -> 0.17 levels of low-passed error; 0.5 levels is where the next closest view
    # (4 m from the fire, 0.96 levels at quarter resolution) would already fail.
    assert quarter_error < half_error + 0.5, (quarter_error, half_error)
    # And no stripes (the converged picture's own neighbour differences, as in the stripe test).
    assert adjacent_difference(quarter) < 2.0 * adjacent_difference(reference) + 0.002


def test_smoke_shadows_modelled_once_per_change_of_their_inputs(renderer, volumes):
    """A smoke keyframe reads its sun and sky transmittance from a texture modelled once per
    change of its inputs (modelling.py _shadows): a stream of keyframes models it once, and after
    the sun moves the picture is the one modelled from scratch (no stale shadows)."""
    volumes.settings = replace(MEDIUM, model_hz=10.0)
    day = {"utc": "2026-06-21T08:00:00Z"}
    scene = apply_patch(close_fire(96, 54), {"time": day, "effects": [
        {"id": "smoke", "type": "smoke", "position": [0, 0, 0], "diameter": 3.0, "seed": 5}]})
    try:
        shadows = 0
        for i in range(7):
            renderer.render(apply_patch(scene, {"time": {"sim_time": 300.0 + i / 30.0}}))
            shadows += volumes.stats.get("shadows", 0)
        assert shadows == 1  # three keyframes modelled, one shadow texture
        # A jump in time (new keyframes, modelled now with the new sun; in a stream a changed sun
        # enters at the next keyframe and blends in, by design).
        moved = apply_patch(scene, {"time": {"utc": "2026-06-21T15:00:00Z", "sim_time": 400.0}})
        renderer.render(moved)
        cached = renderer.read_hdr()
        for slot in volumes._slots.values():
            slot.release()
        volumes._slots.clear()
        renderer.render(moved)
        np.testing.assert_array_equal(cached, renderer.read_hdr())
    finally:
        volumes.settings = None


def upsample_reference(color: np.ndarray, low_d: np.ndarray, full_d: np.ndarray, scale: int, far: float) -> np.ndarray:
    """The depth-aware upsampling rule (volumes/upsample.frag.glsl) in float64: the matching texels of
    the four around a pixel blended bilinearly, renormalised; none matching: the closest texel."""
    h, w = full_d.shape
    lh, lw = low_d.shape
    out = np.zeros((h, w, 4))
    for y in range(h):
        for x in range(w):
            d = min(full_d[y, x], far)
            p = np.array([(x + 0.5) / scale - 0.5, (y + 0.5) / scale - 0.5])
            i0 = np.floor(p).astype(int)
            f = p - i0
            acc, weight, best, best_diff, matches = np.zeros(4), 0.0, None, np.inf, []
            for oy in (0, 1):
                for ox in (0, 1):
                    qx, qy = min(max(i0[0] + ox, 0), lw - 1), min(max(i0[1] + oy, 0), lh - 1)
                    dq = min(low_d[qy, qx], far)
                    diff = abs(dq - d) / max(min(dq, d), 1e-3)
                    wgt = (f[0] if ox else 1 - f[0]) * (f[1] if oy else 1 - f[1])
                    if diff < 0.2:
                        acc += wgt * color[qy, qx]
                        weight += wgt
                        matches.append((ox, oy))
                    if diff < best_diff:
                        best_diff, best = diff, color[qy, qx]
            diagonal = len(matches) == 3 or (len(matches) == 2 and matches[0][0] != matches[1][0]
                                              and matches[0][1] != matches[1][1])
            out[y, x] = acc / weight if weight > 1e-4 and not diagonal else best
    return out


def test_upsampling_with_one_filtered_fetch_blends_the_matching_texels(renderer):
    # The upsample reads four distances with one gather and the colour with one filtered fetch whose
    # point slides to the matching column or row: exactly the renormalised blend of the matching
    # texels when they are all four, one or an adjacent pair, the closest texel for two diagonal or
    # three (the rule above). Checked on random low-resolution distances with edges (a crate's
    # silhouette: 10 m against 200 m) against float64: float16 colour texels and the filter's
    # weights agree within 2e-3 of the colour's range.
    import moderngl

    ctx = renderer.ctx
    vpass = renderer.graph.passes["volumes"]
    rng = np.random.default_rng(4)
    scale, (lw, lh) = 4, (12, 8)
    w, h = lw * scale, lh * scale
    color = rng.uniform(0.0, 1.0, (lh, lw, 4)).astype(np.float16)
    low_d = np.where(rng.uniform(size=(lh, lw)) < 0.5, 10.0, 200.0).astype(np.float32)
    full_d = np.where(rng.uniform(size=(h, w)) < 0.5, 10.5, 190.0).astype(np.float32)
    tex_color = ctx.texture((lw, lh), 4, color.tobytes(), dtype="f2")
    tex_low = ctx.texture((lw, lh), 1, low_d.tobytes(), dtype="f4")
    tex_full = ctx.texture((w, h), 1, full_d.tobytes(), dtype="f4")
    tex_color.filter = (moderngl.LINEAR, moderngl.LINEAR)
    for tex in (tex_low, tex_full):
        tex.filter = (moderngl.NEAREST, moderngl.NEAREST)
    for tex in (tex_color, tex_low, tex_full):
        tex.repeat_x = tex.repeat_y = False
    target = ctx.texture((w, h), 4, dtype="f4")
    fbo = ctx.framebuffer([target])
    try:
        program = vpass.programs.program("common/fullscreen.vert.glsl", "volumes/upsample.frag.glsl")
        # the pass's own program: through set_uniforms and use_texture, which keep what they wrote
        set_uniforms(program, {"u_volume_color": 0, "u_scene_distance": 1, "u_volume_distance": 2, "u_scale": scale,
                               "u_volumes_far": 1000.0})
        use_texture(tex_color, 0)
        use_texture(tex_full, 1)
        use_texture(tex_low, 2)
        fbo.use()
        ctx.disable(moderngl.BLEND | moderngl.DEPTH_TEST)
        vpass.fullscreen(program)
        got = np.frombuffer(target.read(), dtype=np.float32).reshape(h, w, 4)
    finally:
        for obj in (fbo, target, tex_color, tex_low, tex_full):
            obj.release()
    want = upsample_reference(color.astype(np.float64), low_d, full_d, scale, 1000.0)
    assert np.abs(got - want).max() < 2e-3


def test_march_reads_the_frames_aerial_table(renderer):
    # Where the surfaces filled the frame's aerial-perspective table (a frame of at least the table's
    # 115,200 nodes), the march reads it once a pixel instead of evaluating the atmosphere per pixel:
    # night_fire within 1 level of the per-pixel function (the table's own bound on surfaces, docs/quality.md).
    from igserver.render.volumes import volumes as vmod

    scene = apply_patch(load_scene("night_fire"), {"camera": {"width": 480, "height": 270}})
    vpass = renderer.graph.passes["volumes"]
    with_table = renderer.render(scene).rgba
    assert vpass.stats["aerial_table"]
    orig = vmod.VolumesPass._march

    def per_pixel(self, frame, *args, **kwargs):
        held = frame.resources.pop("aerial_table", None)
        try:
            return orig(self, frame, *args, **kwargs)
        finally:
            frame.resources["aerial_table"] = held

    vmod.VolumesPass._march = per_pixel
    try:
        exact = renderer.render(scene).rgba
        assert not vpass.stats["aerial_table"]
    finally:
        vmod.VolumesPass._march = orig
    assert np.abs(with_table.astype(int) - exact.astype(int)).max() <= 1


@pytest.mark.parametrize("kind", ["smoke", "fire"])
def test_slabs_hold_the_bent_container_in_less_than_its_box(kind):
    # Volume.slabs: every point of the wind-bent container (march.frag.glsl to_volume: axis offset
    # lean z² for a plume, lean z for a flame) lies in a slab; the slabs tile its height without
    # overlap, and for a plume bent over by the wind they enclose much less than its one AABB.
    from igserver.render.camera import make_view
    from igserver.render.volumes.effects import MAX_SLABS
    from igserver.render.volumes.volumes import visible_volumes

    scene = load_scene("demo")
    vol = next(v for v in visible_volumes(scene, make_view(scene.camera)) if (v.kind == "smoke") == (kind == "smoke"))
    slabs = vol.slabs()
    assert 1 < len(slabs) <= MAX_SLABS
    rng = np.random.default_rng(3)
    z = rng.uniform(0.0, 1.0, 20000)
    offset = vol.lean[None, :] * (z * z if kind == "smoke" else z)[:, None]
    points = np.column_stack([offset + rng.uniform(-vol.radius, vol.radius, (len(z), 2)), z * vol.height]) + vol.base
    inside = np.zeros(len(z), dtype=int)
    for lo, hi in slabs:
        inside += np.all((points >= lo - 1e-9) & (points <= hi + 1e-9), axis=1)
    assert np.all(inside >= 1)
    tops = [float(hi[2]) for _, hi in slabs]
    bottoms = [float(lo[2]) for lo, _ in slabs]
    assert bottoms[0] == pytest.approx(vol.base[2]) and tops[-1] == pytest.approx(vol.base[2] + vol.height)
    assert np.allclose(bottoms[1:], tops[:-1])
    lo, hi = vol.box
    volume = sum(float(np.prod(h - l)) for l, h in slabs)
    assert volume < (0.6 if kind == "smoke" else 0.9) * float(np.prod(hi - lo))


@pytest.mark.parametrize("view", ["night_fire", "inside"])
def test_slabs_march_as_one_box_does(renderer, volumes, monkeypatch, view):
    # Drawn farthest (in height from the camera) first, the slabs compose as one march through the
    # whole box: the same picture but for each slab's own start jitter (measured: 71 dB outside, 82
    # dB from inside the flame at 320x180). At a fixed exposure: the automatic one meters the
    # flame, so the jitter moving a few of its clipped pixels shifts every pixel of the frame by a
    # level (mean differences 0.01-0.06 at sim times 0-200 s, 0.001-0.006 at EV 10).
    from igserver.render.volumes import effects

    scene = inside_plume() if view == "inside" else apply_patch(load_scene("night_fire"), {
        "camera": {"width": 160, "height": 90, "exposure_ev": 10}})
    slabs = render_with(renderer, volumes, scene, MEDIUM)
    assert volumes.stats["slabs"] > volumes.stats["drawn"]
    monkeypatch.setattr(effects, "MAX_SLABS", 1)
    volumes.memo.clear()  # the pass keeps its march plan (slabs included) while its inputs are unchanged
    one_box = render_with(renderer, volumes, scene, MEDIUM)
    assert volumes.stats["slabs"] == volumes.stats["drawn"]
    monkeypatch.undo()
    volumes.memo.clear()
    d = np.abs(slabs - one_box)
    assert d.mean() < 0.05 and np.percentile(d, 99.9) <= 4.0


def test_far_plume_texture_follows_the_march_resolution(renderer, volumes, monkeypatch):
    """A smoke texture holds about one voxel per 1.5 pixels of the preset's march, with one
    turbulence octave fewer per halving (march.py texture_size, modelling.py model_octaves): sea_harbour_fire's
    plume at 111 m, marched at half resolution, is modelled at 16 x 16 x 25 voxels with 2 octaves
    (32 x 32 x 50 with 3 at full resolution), the flame at the full-resolution rule; the picture of
    the plume stays within 3.5 levels of low-passed error of a 64-voxel full-resolution march
    (measured 2.1 at t = 100 s, 1.7-3.0 over four sim times; 0.9 with the full-resolution rule)."""
    from igserver.render.camera import make_view
    from igserver.render.volumes import volumes as volumes_module
    from igserver.render.volumes.march import texture_size
    from igserver.render.volumes.modelling import model_octaves
    from igserver.render.volumes.volumes import visible_volumes

    scene = apply_patch(load_scene("sea_harbour_fire"), {
        "camera": {"width": 640, "height": 360, "exposure_ev": 6}, "time": {"sim_time": 100.0}})
    view = make_view(scene.camera)
    medium = PRESETS["medium"]
    vols = {v.key[1]: v for v in visible_volumes(scene, view)}
    assert texture_size(vols["smoke"], view, medium) == (16, 16, 25)
    assert model_octaves(vols["smoke"], (16, 16, 25), medium) == 2
    assert texture_size(vols["smoke"], view, replace(medium, scale=1)) == (32, 32, 50)
    assert model_octaves(vols["smoke"], (32, 32, 50), medium) == 3
    assert texture_size(vols["fire"], view, medium) == texture_size(vols["fire"], view, replace(medium, scale=1))
    reference = VolumeSettings(steps=512, octaves=3, resolution=64, lod=False, scale=1, model_hz=0.0)
    converged = render_with(renderer, volumes, scene, reference)
    flame_only = [v for v in visible_volumes(scene, view) if v.key[1] == "fire"]
    with monkeypatch.context() as patch:
        patch.setattr(volumes_module, "visible_volumes", lambda s, v: flame_only)
        volumes.memo.__init__()  # the pass memoises its visible volumes
        no_plume = render_with(renderer, volumes, scene, reference)
    volumes.memo.__init__()
    plume = np.abs(converged - no_plume).max(-1) > 2
    assert plume.sum() > 300
    _, error = errors(render_with(renderer, volumes, scene, medium), converged, plume)
    assert error < 3.5, error
