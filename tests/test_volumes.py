"""Volumetric fire and smoke: pass planning, fade, depth clipping, camera inside, stability, many
effects, picture checks. Tiny frames (96x54) on the session's renderer."""

from __future__ import annotations

import numpy as np
import pytest

from igserver.photometry import LUMA
from igserver.render import lights as lights_module
from igserver.render import presets
from igserver.render.graph import plan_passes
from igserver.render.volumes.effects import NOISE_PERIOD, effect_volumes, fade_level
from igserver.scene import Scene, apply_patch

from helpers import GLWork

W, H = 96, 54
NIGHT = "2026-01-15T22:00:00Z"


def fire_scene(effects=None, camera=None, sim_time=100.0, **extra) -> Scene:
    cam = {"position": [0.0, -14.0, 3.0], "pitch": 5.0, "width": W, "height": H, "exposure_ev": 10.0}
    cam.update(camera or {})
    data = {
        "camera": cam,
        "time": {"utc": NIGHT, "sim_time": sim_time},
        "weather": {"wind_speed": 0.0},
        "effects": effects if effects is not None else [{"id": "f", "type": "fire", "diameter": 2.0}],
    }
    data.update(extra)
    return Scene.model_validate(data)


@pytest.fixture
def no_fire_lights(monkeypatch):
    """Only the volume's own radiance changes between renders (the fire's light also lights the box)."""
    monkeypatch.setattr(lights_module, "LIGHT_SOURCES", [lights_module.host_lights])


def render_hdr(renderer, scene):
    result = renderer.render(scene)
    return result, renderer.read_hdr()[..., :3]


# -- planning (no GL) ----------------------------------------------------------------------------

def test_pass_absent_without_visible_effects():
    assert "volumes" not in plan_passes(fire_scene(effects=[]))
    assert "depth_copy" not in plan_passes(fire_scene(effects=[]))
    assert plan_passes(fire_scene())[-3:] == ["depth_copy", "volumes", "post"]
    # inactive forever, fully faded out, zero size, behind the camera
    cases = [
        {"id": "f", "active": False},
        {"id": "f", "active": False, "changed_at": 10.0, "fade": 3.0},
        {"id": "f", "diameter": 0.0},
        {"id": "f", "position": [0.0, -60.0, 0.0]},
        {"id": "f", "intensity": 0.0},
    ]
    for effect in cases:
        names = plan_passes(fire_scene(effects=[effect]))
        assert "volumes" not in names and "depth_copy" not in names, effect
    # still fading out: present
    assert "volumes" in plan_passes(fire_scene(effects=[{"id": "f", "active": False, "changed_at": 99.0}]))


def test_pass_absent_costs_nothing(renderer):
    """An effect that cannot show costs no GL work: measured by the commands submitted (helpers.GLWork,
    counted at moderngl's boundary), not by the pass names the renderer reports. Guards against the
    renderer running depth_copy + volumes when the plan left them out without reporting them."""
    empty = fire_scene(effects=[])
    renderer.render(empty)  # warm: programs compiled, targets allocated, tables resident
    with GLWork() as base:
        renderer.render(empty)
    for effect in ({"id": "f", "active": False}, {"id": "f", "position": [0.0, -60.0, 0.0]},
                   {"id": "f", "intensity": 0.0}, {"id": "f", "diameter": 0.0}):
        with GLWork() as work:
            result = renderer.render(fire_scene(effects=[effect]))
        assert "volumes" not in result.passes
        assert work.calls == base.calls, (effect, work.counts, base.counts)
    # The counter does see the volume work when the fire shows: one depth copy, one draw per container
    # (and, for a reduced-resolution march, its downsample and upsample draws), and the fire light's
    # fog halo, when it shows, its own draw.
    with GLWork() as fire:
        result = renderer.render(fire_scene())
    assert "volumes" in result.passes
    assert fire.counts["blit"] == base.counts["blit"] + 1
    reduced = 2 if presets.knobs("volumes", fire_scene().quality.preset).scale > 1 else 0
    halo = 1 if renderer.graph.passes["post"].stats["halos"] else 0
    assert fire.counts["draw"] == base.counts["draw"] + renderer.graph.passes["volumes"].stats["drawn"] + reduced + halo
    assert renderer.graph.passes["volumes"].stats["drawn"] == 1


def test_fade_level_monotone():
    effect = {"id": "f", "changed_at": 10.0, "fade": 4.0}
    times = np.linspace(5.0, 20.0, 61)
    up = [fade_level(fire_scene(effects=[dict(effect, active=True)]).effects[0], t) for t in times]
    down = [fade_level(fire_scene(effects=[dict(effect, active=False)]).effects[0], t) for t in times]
    assert np.all(np.diff(up) >= 0.0) and up[0] == 0.0 and up[-1] == 1.0
    assert np.all(np.diff(down) <= 0.0) and down[0] == 1.0 and down[-1] == 0.0
    zero = fire_scene(effects=[dict(effect, fade=0.0)]).effects[0]
    assert fade_level(zero, 9.9) == 0.0 and fade_level(zero, 10.0) == 1.0


def test_fade_drives_size_and_opacity_from_zero_to_full():
    """The paper animates both the container size and the profile opacity with the fade: at the switch
    the fire has zero opacity (it cannot pop in), at the end it is the fire that burned all along."""
    for active in (True, False):
        effect = {"id": "f", "diameter": 2.0, "active": active, "changed_at": 10.0, "fade": 4.0}
        steady = fire_scene(effects=[{"id": "f", "diameter": 2.0, "active": True}], sim_time=50.0)
        full = effect_volumes(steady.effects[0], steady)[0]
        sizes, opacities = [], []
        for t in 10.0 + 4.0 * np.linspace(0.0, 1.0, 41):
            scene = fire_scene(effects=[effect], sim_time=float(t))
            vols = effect_volumes(scene.effects[0], scene)
            level = fade_level(scene.effects[0], float(t))
            if level == 0.0:
                assert vols == []  # nothing of a fire at zero level: no container at all
                sizes.append((0.0, 0.0))
                opacities.append(0.0)
                continue
            vol = vols[0]
            assert vol.opacity == pytest.approx(level) and vol.level == pytest.approx(level)
            sizes.append((vol.radius, vol.height))
            opacities.append(vol.opacity)
        sign = 1.0 if active else -1.0
        for series in (np.array(sizes), np.array(opacities)):
            assert np.all(sign * np.diff(series, axis=0) >= 0.0), (active, series)
        burning = -1 if active else 0
        assert opacities[burning] == 1.0 and sizes[burning] == pytest.approx((full.radius, full.height))
        assert opacities[-1 - burning] == 0.0


def test_fade_in_and_out_rendered_from_zero_to_full(renderer, no_fire_lights):
    """Rendered energy over the background: exactly 0 at the zero end, negligible next to it, strictly
    monotone, and at the full end the same picture as a fire that has burned all along."""
    _, background = render_hdr(renderer, fire_scene(effects=[]))

    def energy(effect, sim_time):
        _, hdr = render_hdr(renderer, fire_scene(effects=[effect], sim_time=sim_time))
        return float(np.sum(np.abs(hdr - background)))

    for active in (True, False):
        effect = {"id": "f", "diameter": 2.0, "active": active, "changed_at": 100.0, "fade": 4.0}
        # from the zero end to the full end of the fade
        steps = (0.0, 2.5e-4, 0.25, 0.5, 0.75, 1.0) if active else (1.0, 1.0 - 2.5e-4, 0.75, 0.5, 0.25, 0.0)
        times = [100.0 + 4.0 * s for s in steps]
        full = energy({"id": "f", "diameter": 2.0}, times[-1])  # burning all along, same sim_time (noise)
        energies = [energy(effect, t) / full for t in times]
        # At the zero end the fire is absent: the frame equals the background exactly.
        assert energies[0] == 0.0, (active, energies)
        # 2.5e-4 of the fade from the zero end the smoothstep level is 1.9e-7, and the energy scales with
        # opacity x projected size: anything above 1e-3 of the full fire popped in without the fade.
        assert energies[1] < 1e-3, (active, energies)
        steps_up = np.diff(energies)  # the first may be 0: 1.9e-7 of the fire is below float16 resolution
        assert steps_up[0] >= 0.0 and np.all(steps_up[1:] > 0.0), (active, energies)
        # The full end is the steady fire: same volume, same noise; 1e-3 allows float16 rounding only.
        assert abs(energies[-1] - 1.0) < 1e-3, (active, energies)


# -- pictures ------------------------------------------------------------------------------------

def test_night_fire_bright_and_warm(renderer, no_fire_lights):
    _, background = render_hdr(renderer, fire_scene(effects=[]))
    result, hdr = render_hdr(renderer, fire_scene())
    assert result.passes[-3:] == ["depth_copy", "volumes", "post"]
    assert np.all(np.isfinite(hdr))
    covered = np.abs(hdr - background).sum(-1) > 1e-2
    assert 0.01 < covered.mean() < 0.5
    rgb = hdr[covered]
    assert rgb[:, 0].mean() > 1.5 * rgb[:, 2].mean()  # warm: red over blue
    assert rgb.mean() > 3.0 * background[covered].mean() + 0.01
    # the 8-bit output is warm too
    out = result.rgba[covered].astype(float)
    assert out[:, 0].mean() > out[:, 2].mean() + 30


def test_fire_light_lights_the_ground(renderer):
    _, dark = render_hdr(renderer, fire_scene(effects=[]))
    _, lit = render_hdr(renderer, fire_scene())
    ground = slice(H - 8, H)  # bottom rows: ground in front of the fire
    assert lit[ground].mean() > 5.0 * dark[ground].mean() + 1e-3
    assert lit[ground][..., 0].mean() > lit[ground][..., 2].mean()


def test_smoke_lit_by_day_darker_at_night(renderer):
    smoke = [{"id": "s", "type": "smoke", "position": [0.0, 10.0, 0.0], "diameter": 3.0}]
    day_utc, night_utc = "2026-06-21T10:00:00Z", NIGHT
    cam = {"exposure_ev": 12.0}
    means, covered = {}, None
    for name, utc in (("day", day_utc), ("night", night_utc)):
        _, bg = render_hdr(renderer, apply_patch(fire_scene(effects=[], camera=cam), {"time": {"utc": utc}}))
        _, hdr = render_hdr(renderer, apply_patch(fire_scene(effects=smoke, camera=cam), {"time": {"utc": utc}}))
        assert np.all(np.isfinite(hdr))
        if covered is None:  # where the smoke changes the day picture
            covered = np.abs(hdr - bg).sum(-1) > 1e-3
            assert covered.mean() > 0.01
            # lit smoke is greyer than the blue sky behind it
            def saturation(x):
                return float(np.mean((x.max(-1) - x.min(-1)) / (x.max(-1) + 1e-6)))
            assert saturation(hdr[covered]) < saturation(bg[covered])
        means[name] = float(hdr[covered].mean())
    assert means["day"] > 20.0 * means["night"]


def test_depth_clipping_against_an_entity(renderer, no_fire_lights):
    """A box in front of the fire hides it; a box inside it hides the part behind its face."""
    box = {"id": "b", "model": "box", "scale": [1.0, 1.0, 1.0], "color": [0.5, 0.5, 0.5]}
    centre = (slice(H // 2 - 2, H // 2 + 2), slice(W // 2 - 1, W // 2 + 2))
    cam = {"position": [0.0, -14.0, 1.5], "pitch": 0.0}

    def fire_part(box_y):
        entities = [dict(box, position=[0.0, box_y, 1.0])] if box_y is not None else []
        _, without = render_hdr(renderer, fire_scene(effects=[], camera=cam, entities=entities))
        _, with_fire = render_hdr(renderer, fire_scene(camera=cam, entities=entities))
        return float((with_fire - without)[centre].sum())

    free = fire_part(None)
    inside = fire_part(0.0)   # box face at y = -0.5, inside the container (radius 1.1 m)
    in_front = fire_part(-6.0)  # box between the camera and the fire
    assert free > 0.0
    assert 0.02 * free < inside < 0.8 * free
    assert abs(in_front) < 1e-3 * free


def test_camera_inside_the_container(renderer):
    for position in ([0.2, 0.1, 1.0], [0.0, 0.0, 0.0]):
        result, hdr = render_hdr(renderer, fire_scene(camera={"position": position, "pitch": 30.0, "exposure_ev": 12.0}))
        assert "volumes" in result.passes
        assert np.all(np.isfinite(hdr))
        assert result.rgba[..., :3].mean() > 30  # not black
        assert hdr.max() < 6.0e4


def test_long_sim_time_stable(renderer, no_fire_lights):
    """sim_time 1e6 and 1e9 s look statistically like 100 s: the noise scroll is reduced in float64."""
    stats = {}
    for t in (100.0, 100.5, 1e6, 1e9):
        scene = fire_scene(sim_time=t)
        vol = effect_volumes(scene.effects[0], scene)[0]
        assert 0.0 <= vol.noise_offset(t) < NOISE_PERIOD
        _, hdr = render_hdr(renderer, scene)
        assert np.all(np.isfinite(hdr))
        lum = hdr @ LUMA
        stats[t] = (lum.mean(), lum.std(), (lum > 0.05).mean())
    ref = stats[100.0]
    for t in (100.5, 1e6, 1e9):
        for a, b in zip(stats[t], ref):
            assert abs(a - b) < 0.25 * abs(b), (t, stats[t], ref)
    # it animates: different times give different pictures
    _, a = render_hdr(renderer, fire_scene(sim_time=1e6))
    _, b = render_hdr(renderer, fire_scene(sim_time=1e6 + 0.2))
    assert np.abs(a - b).mean() > 1e-4


def test_sixteen_effects(renderer):
    effects = []
    for i in range(16):
        kind = ("fire", "fire", "gas_burner", "smoke")[i % 4]
        effects.append({"id": f"e{i}", "type": kind, "diameter": 1.0 + 0.2 * (i % 3), "seed": i,
                        "emits_smoke": i % 8 == 0, "position": [(i % 4 - 1.5) * 6.0, 10.0 + (i // 4) * 6.0, 0.0]})
    scene = fire_scene(effects=effects, camera={"position": [0.0, -20.0, 8.0], "pitch": -5.0})
    result, hdr = render_hdr(renderer, scene)
    stats = renderer.graph.passes["volumes"].stats
    assert "volumes" in result.passes
    assert stats["drawn"] == 18  # 16 containers + the smoke of the two smoking fires
    assert np.all(np.isfinite(hdr))
    # modelled once; the same state again only marches
    renderer.render(scene)
    assert renderer.graph.passes["volumes"].stats["modelled"] == 0
    renderer.render(apply_patch(scene, {"time": {"sim_time": 100.1}}))
    assert renderer.graph.passes["volumes"].stats["modelled"] == 18


def test_profile_image_accepted(renderer, tmp_path, no_fire_lights, monkeypatch):
    from PIL import Image

    img = np.zeros((64, 32, 4), np.uint8)
    img[16:, 8:24] = (255, 80, 10, 255)  # a block of orange from the bottom to 3/4 height
    (tmp_path / "profiles").mkdir()
    Image.fromarray(img).save(tmp_path / "profiles" / "block.png")
    monkeypatch.setenv("IGSERVER_ASSETS", str(tmp_path))  # profiles are named assets (no paths on the wire)
    _, bg = render_hdr(renderer, fire_scene(effects=[]))
    _, hdr = render_hdr(renderer, fire_scene(effects=[{"id": "p", "diameter": 2.0, "profile": "block"}]))
    covered = np.abs(hdr - bg).sum(-1) > 1e-2
    assert covered.mean() > 0.01 and np.all(np.isfinite(hdr))
    assert hdr[covered][:, 0].mean() > 2.0 * hdr[covered][:, 2].mean()


# -- noise ---------------------------------------------------------------------------------------

NOISE_PROBE = """
#include "common/noise.glsl"
layout(local_size_x = 64) in;
layout(std430, binding = 0) readonly buffer Points { vec4 points[]; };
layout(std430, binding = 1) writeonly buffer Values { float values[]; };
uniform vec3 u_period;
void main() {
    uint i = gl_GlobalInvocationID.x;
    values[i] = simplex3(points[i].xyz, u_period, 11u);
}
"""


def _noise(renderer, points: np.ndarray, period=(0.0, 0.0, 0.0)) -> np.ndarray:
    from igserver.render import shaders

    if not hasattr(renderer, "_noise_probe"):
        src = shaders._INCLUDE.sub(lambda m: shaders.expand(m.group(1)), NOISE_PROBE)
        renderer._noise_probe = renderer.ctx.compute_shader(shaders.GLSL_VERSION + "\n" + src)
    n = len(points)
    data = np.zeros((n, 4), np.float32)
    data[:, :3] = points
    src_buf, dst_buf = renderer.ctx.buffer(data.tobytes()), renderer.ctx.buffer(reserve=n * 4)
    src_buf.bind_to_storage_buffer(0)
    dst_buf.bind_to_storage_buffer(1)
    renderer._noise_probe["u_period"].value = period
    renderer._noise_probe.run((n + 63) // 64)
    out = np.frombuffer(dst_buf.read(), np.float32).copy()
    src_buf.release()
    dst_buf.release()
    return out


def test_noise_range_continuity_and_period(renderer):
    rng = np.random.default_rng(0)
    values = _noise(renderer, rng.uniform(-40.0, 40.0, (50_000, 3)))
    assert 0.85 < np.abs(values).max() <= 1.2 and abs(values.mean()) < 0.01
    # no seams: along random lines the steps stay at the size the smooth slope allows
    d = rng.normal(size=(200, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    s = np.linspace(0.0, 2.0, 1001)
    pts = (rng.uniform(-20, 20, (200, 1, 3)) + s[None, :, None] * d[:, None, :]).reshape(-1, 3)
    steps = np.abs(np.diff(_noise(renderer, pts).reshape(200, 1001), axis=1))
    assert steps.max() < 8.0 * np.median(steps) + 1e-3
    # periodic along z: the scroll can wrap without a jump
    p = rng.uniform(-10.0, 10.0, (5000, 3))
    a = _noise(renderer, p, (0.0, 0.0, NOISE_PERIOD))
    b = _noise(renderer, p + [0.0, 0.0, NOISE_PERIOD], (0.0, 0.0, NOISE_PERIOD))
    assert np.abs(a - b).max() < 1e-4
    # no streaks: the correlation along the diagonal equals that along an axis
    base = rng.uniform(-30.0, 30.0, (20_000, 3))
    v0 = _noise(renderer, base)
    axis = np.corrcoef(v0, _noise(renderer, base + [0.3, 0.0, 0.0]))[0, 1]
    diag = np.corrcoef(v0, _noise(renderer, base + np.array([0.3, 0.3, 0.3]) / np.sqrt(3.0)))[0, 1]
    assert abs(axis - diag) < 0.03


def test_pool_fire_base_is_opaque(renderer, no_fire_lights):
    # A 3 m pool fire by day seen from 8 m (no wind, fire lights off): what the flame's base lets
    # through of the ground behind it, from two renders that differ only in the ground's colour,
    # T = (flame over bright - flame over dark) / (bright - dark), on the axis 1 m up. Reference: a
    # pool fire's soot makes its luminous zone optically thick; its absorption coefficient is a
    # property of the fuel per metre (Babrauskas, SFPE Handbook: k = 1.7-3.5 /m for gasoline,
    # kerosene, fuel oils), so across a 3 m base k D ~ 6 and T ~ e^-6 = 0.0025. Bound 0.1: the
    # profile's soft density and the turbulence thin the flame along some rays.
    from igserver.render.camera import make_view

    def scene(ground, fire=True):
        return fire_scene(effects=[{"id": "f", "type": "fire", "diameter": 3.0}] if fire else [],
                          camera={"position": [0.0, -8.0, 1.7], "pitch": 5.0, "exposure_ev": 14.0},
                          time={"utc": "2026-09-15T10:00:00Z", "sim_time": 100.0},
                          ground={"enabled": True, "level": 0.0, "color": ground})
    s = scene([0.8, 0.8, 0.8])
    view = make_view(s.camera)
    clip = view.view_proj @ np.append(view.relative([0.0, 0.0, 1.0]), 1.0)
    col, row = int((clip[0] / clip[3] * 0.5 + 0.5) * W), int((0.5 - clip[1] / clip[3] * 0.5) * H)
    patch = (slice(row - 1, row + 2), slice(col - 1, col + 2))

    def lum(sc):
        return float((render_hdr(renderer, sc)[1][patch] @ np.array([0.2126, 0.7152, 0.0722])).mean())
    bright, dark = lum(scene([0.8, 0.8, 0.8])), lum(scene([0.05, 0.05, 0.05]))
    bg_bright, bg_dark = lum(scene([0.8, 0.8, 0.8], False)), lum(scene([0.05, 0.05, 0.05], False))
    transmittance = (bright - dark) / (bg_bright - bg_dark)
    assert transmittance < 0.1, (transmittance, bright, dark, bg_bright, bg_dark)


def test_fire_plume_widens_like_a_buoyant_plume_and_is_sooty(renderer, no_fire_lights):
    # A 3 m oil fire's plume by day in calm air, seen from the side 40 m away (0.23 m a pixel),
    # averaged over 6 instants 1.7 s apart (the turbulence moves the edge). Where the smoke hides
    # at least half of the sky behind it, its width at 10 m and 18 m above the pool gives the
    # plume's visible half-angle. Reference: buoyant plumes' visible edges open at 6-8 deg (the
    # issue's figure; Morton-Taylor-Turner entrainment, b = 0.12-0.15 z for the top-hat radius);
    # bounds 6-9 deg: a pixel of width at each height is 0.8 deg. The smoke of a sooty fuel is
    # dense: its soot (yield 0.06 g/g, 8.7 m^2/g: effects.plume_soot_extinction) makes the plume's
    # optical depth across ~10 near its base, so on the axis at 14 m it hides > 80 % of the sky.
    import math
    from igserver.render.camera import make_view

    def scene(fire=True, t=100.0):
        return fire_scene(effects=[{"id": "f", "type": "fire", "diameter": 3.0, "emits_smoke": True, "seed": 3}]
                          if fire else [], sim_time=t,
                          camera={"position": [0.0, -40.0, 2.0], "pitch": 15.0, "fov_y": 30.0, "exposure_ev": 14.0,
                                  "width": 160, "height": 90},
                          time={"utc": "2026-09-15T10:00:00Z", "sim_time": t}, location={"lat": 59.93, "lon": 30.31})
    luma = np.array([0.2126, 0.7152, 0.0722])
    fire = np.mean([render_hdr(renderer, scene(True, 100.0 + 1.7 * k))[1] @ luma for k in range(6)], axis=0)
    sky = render_hdr(renderer, scene(False))[1] @ luma
    hidden = (sky - fire) / sky
    view = make_view(scene().camera)

    def row(z):
        clip = view.view_proj @ np.append(view.relative([0.0, 0.0, z]), 1.0)
        return int((0.5 - clip[1] / clip[3] * 0.5) * 90)
    metres_per_pixel = 40.0 * math.radians(30.0) / 90

    def width(z):
        cols = np.nonzero(hidden[row(z) - 1:row(z) + 2].mean(axis=0) > 0.5)[0]
        return (cols.max() - cols.min() + 1) * metres_per_pixel if len(cols) else 0.0
    low, high = width(10.0), width(18.0)
    half_angle = math.degrees(math.atan((high - low) / 2.0 / 8.0))
    assert 6.0 < half_angle < 9.0, (low, high, half_angle)
    assert hidden[row(14.0) - 1:row(14.0) + 2, 78:82].mean() > 0.8


@pytest.mark.parametrize("diameter", [1.0, 4.0])
def test_pool_fire_puffs_at_its_measured_frequency(renderer, no_fire_lights, diameter):
    """A pool fire's flame necks and puffs at f = 1.5 / sqrt(D) Hz, D in m (Cetegen & Ahmed,
    "Experiments on the periodic instability of buoyant plumes and pool fires", Combust. Flame 93,
    1993: f = 1.5 D^-1/2 over pools from centimetres to tens of metres; Pagni, "Pool fire vortex
    shedding frequencies", Appl. Mech. Rev. 43, 1990). The flame alone (no plume, its light off) at night in calm air, framed whole, its
    emitted flux (the frame's summed HDR luminance) sampled at 10 Hz over 12.8 s: the Hann-windowed
    spectrum's highest peak (interpolated by 8x zero padding) must lie within 15 % of f. Measured
    1.504 Hz (f 1.5) and 0.752 Hz (f 0.75); without the puffing the turbulence alone peaked at
    3.43 and 0.17 Hz."""
    import math

    from igserver.render.volumes.effects import heskestad_height, puffing_frequency

    height = 1.4 * heskestad_height(diameter, 1.0)  # the flame's container
    distance = 2.2 * height + 2.0
    count, dt = 128, 0.1
    flux = []
    for k in range(count):
        scene = fire_scene(effects=[{"id": "f", "type": "fire", "diameter": diameter, "seed": 5}],
                           sim_time=100.0 + dt * k,
                           camera={"width": 48, "height": 27, "pitch": 0.0, "position": [0.0, -distance, 0.5 * height]})
        flux.append(float((render_hdr(renderer, scene)[1] @ np.asarray(LUMA)).sum()))
    flux = np.asarray(flux)
    spectrum = np.abs(np.fft.rfft((flux - flux.mean()) * np.hanning(count), 8 * count))
    freqs = np.fft.rfftfreq(8 * count, dt)
    above = freqs > 1.0 / (count * dt)  # past the window's own low-frequency lobe
    peak = float(freqs[above][np.argmax(spectrum[above])])
    expected = puffing_frequency(diameter)
    assert expected == pytest.approx(1.5 / math.sqrt(diameter))
    assert abs(peak / expected - 1.0) <= 0.15, (diameter, peak, expected)
