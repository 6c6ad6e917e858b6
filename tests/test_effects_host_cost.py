"""Host cost of fire, smoke and precipitation: what the volumes and precipitation passes derive from
the world is made once per change of its inputs (each item keyed on all of them, its recomputations
counted), the march's per-volume constants reach the GPU as one uniform block (one instanced draw a
volume), the rain's levels as one table (one light dispatch, one indirect draw); the block's std140
layout as GLSL reads it; the particles' motion of every level at once as particles.py's formula."""

import math

import numpy as np
import pytest

from helpers import tiny
from igserver.render import bindings
from igserver.render.camera import make_view
from igserver.render.gl_count import GLCallCounter
from igserver.render.precip import particles
from igserver.render.precip.particles import PRESETS, ParticlePool, diameters, particle_layout
from igserver.render.renderer import Renderer
from igserver.render.volumes import fire_lights, march_block
from igserver.scene import apply_patch, load_scene
from igserver.weather import fall_speed, wind_vector


@pytest.fixture(scope="module")
def renderer():
    r = Renderer()
    yield r
    r.release()


def _demo():
    return apply_patch(load_scene("demo"), {"camera": {"width": 64, "height": 36}})


def _stream(renderer, scene, frames, t0=None):
    t0 = scene.time.sim_time if t0 is None else t0
    for i in range(frames):
        renderer.render(apply_patch(scene, {"time": {"sim_time": t0 + i / 30.0}}))


def _counts(renderer) -> dict:
    memo = renderer.graph.passes["volumes"].memo.computed
    return {"visible_volumes": memo["visible_volumes"], "march_plan": memo["march_plan"],
            "flames": fire_lights.FLAMES.computed, "particle_layout": particles.TILES.computed["particle_layout"]}


def test_a_sim_time_stream_rederives_no_volume_or_particle_item(renderer):
    scene = _demo()
    _stream(renderer, scene, 3)
    before = _counts(renderer)
    assert all(before.values()), before
    _stream(renderer, scene, 8, t0=scene.time.sim_time + 1.0)
    assert _counts(renderer) == before


def _fire(**changes):
    fire = _demo().effects[0].model_dump(mode="json")
    return {"effects": [{**fire, **changes}]}


@pytest.mark.parametrize("patch, items", [
    ({"camera": {"heading": 291.0}}, {"visible_volumes", "march_plan", "particle_layout"}),
    # the rain's tiles are camera-relative: a camera that moves without turning keeps them
    ({"camera": {"position": [0.5, -120.0, 6.0]}}, {"visible_volumes", "march_plan"}),
    ({"weather": {"wind_speed": 9.0}}, {"visible_volumes", "march_plan", "flames", "particle_layout"}),
    ({"weather": {"precipitation": {"rate": 4.0}}}, {"particle_layout"}),
    ({"weather": {"precipitation": {"streak_time": 0.02}}}, {"particle_layout"}),
    ({"quality": {"preset": "high"}}, {"march_plan", "particle_layout"}),
    (_fire(intensity=0.5), {"visible_volumes", "march_plan", "flames"}),
    (_fire(fuel="methanol"), {"visible_volumes", "march_plan", "flames"}),
    (_fire(seed=8), {"visible_volumes", "march_plan", "flames"}),
])
def test_each_input_rederives_its_items_and_only_those(renderer, patch, items):
    scene = _demo()
    _stream(renderer, scene, 2)
    before = _counts(renderer)
    changed = apply_patch(scene, patch)
    renderer.render(apply_patch(changed, {"time": {"sim_time": scene.time.sim_time + 2.0}}))
    after = _counts(renderer)
    assert {k for k in after if after[k] != before[k]} == items, patch
    assert all(after[k] == before[k] + 1 for k in items)
    renderer.render(apply_patch(changed, {"time": {"sim_time": scene.time.sim_time + 2.5}}))
    assert _counts(renderer) == after  # the same inputs at another time: nothing again


def test_a_fading_fire_rederives_its_flame_every_frame_and_a_burning_one_not():
    """The fade level is an input of the fire's light (its size, opacity and colour): while it changes
    the Flame is made again each frame; once burning steadily, never."""
    scene = tiny({"effects": [{"id": "f", "type": "fire", "diameter": 2.0, "changed_at": 10.0, "fade": 2.0}]})
    computed = fire_lights.FLAMES.computed
    lights = [fire_lights.fire_light(scene.effects[0], apply_patch(scene, {"time": {"sim_time": t}}))
              for t in (10.5, 11.0, 11.5)]
    assert fire_lights.FLAMES.computed == computed + 3
    assert lights[0].color.max() < lights[1].color.max() < lights[2].color.max()
    computed = fire_lights.FLAMES.computed
    for t in (20.0, 21.0, 22.0):
        fire_lights.fire_light(scene.effects[0], apply_patch(scene, {"time": {"sim_time": t}}))
    assert fire_lights.FLAMES.computed == computed + 1


def _pass_calls(renderer, scene, name) -> GLCallCounter:
    """The GL calls of one pass's execute in the next frame of a stream."""
    p = renderer.graph.passes[name]
    original, counter = p.execute, GLCallCounter()

    def counted(*args, **kwargs):
        with counter:
            return original(*args, **kwargs)

    p.execute = counted
    try:
        renderer.render(apply_patch(scene, {"time": {"sim_time": scene.time.sim_time + 5 / 30.0}}))
    finally:
        p.execute = original
    return counter


def test_volumes_draw_each_volume_once_from_its_block_record(renderer):
    """Demo (a fire and its plume, 8 slabs in all, half-resolution march): one instanced draw per
    volume plus the downsample and the upsample, no uniform written per slab or per volume (the
    keyframe blend and the jitter's shift are the records' per-frame lanes); 68 GL calls a frame
    before the block, 44 with it."""
    scene = _demo()
    _stream(renderer, scene, 5)
    calls = _pass_calls(renderer, scene, "volumes")
    stats = renderer.graph.passes["volumes"].stats
    assert stats["drawn"] == 2 and stats["slabs"] > stats["drawn"] and stats["scale"] == 2
    assert calls.by_name["VertexArray.render"] == stats["drawn"] + 2
    assert calls.by_name["Buffer.bind_to_uniform_block"] == stats["drawn"]
    assert calls.by_name["Buffer.write"] == 1  # the records with the frame's blend, jitter and glow
    per_volume = {"u_base", "u_extent", "u_lean", "u_step", "u_voxel", "u_sigma", "u_glow_pos", "u_glow_intensity",
                  "u_box_min", "u_box_max", "u_emission", "u_albedo_scale", "u_blend", "u_jitter_offset"}
    assert not [k for k in calls.by_name if k.startswith("Uniform[") and k[8:-7] in per_volume], calls.by_name
    assert calls.total <= 46, calls.by_name.most_common()
    assert calls.created() == 0


@pytest.mark.parametrize("name", ["demo", "snow"])
def test_precipitation_is_one_dispatch_and_one_indirect_draw(renderer, name):
    """Every level's streaks lit in one dispatch and drawn by one indirect draw (a command per
    level); in a stream only the particles' positions are uploaded (48-60 GL calls a frame before,
    13 with it)."""
    scene = apply_patch(load_scene(name), {"camera": {"width": 64, "height": 36}})
    _stream(renderer, scene, 3)
    calls = _pass_calls(renderer, scene, "precip")
    assert len(renderer.graph.passes["precip"]._layout.levels) >= 3
    assert calls.by_name["ComputeShader.run"] == 1
    assert calls.by_name["VertexArray.render_indirect"] == 1 and calls.by_name["VertexArray.render"] == 0
    assert calls.by_name["Buffer.write"] == 1
    assert not [k for k in calls.by_name if k.startswith("Uniform[")], calls.by_name
    assert calls.total <= 14, calls.by_name.most_common()
    assert calls.created() == 0


def test_volume_block_layout_is_what_glsl_reads(renderer):
    """A compute shader copies every member of two records (the second bound at its stride's
    offset, as the pass binds it) into a storage buffer: the values march_block.record packed come
    back, so the Python rows and the std140 block agree."""
    ctx = renderer.ctx
    rng = np.random.default_rng(11)

    def values():
        slabs = [(rng.uniform(-9, 9, 3), rng.uniform(-9, 9, 3)) for _ in range(5)]
        scalars = rng.uniform(0.1, 5.0, 5)
        return dict(slabs=slabs, base=rng.uniform(-9, 9, 3), step=scalars[0], extent=rng.uniform(1, 9, 3),
                    voxel=scalars[1], lean=rng.uniform(-3, 3, 2), sigma=scalars[2], hg_g=scalars[3],
                    glow_pos=rng.uniform(-9, 9, 3), albedo_scale=scalars[4], emission=rng.uniform(0, 9e3, 3))

    records = [values(), values()]
    stride = march_block.stride(ctx.info["GL_UNIFORM_BUFFER_OFFSET_ALIGNMENT"])
    data = np.zeros((2, stride // 4), np.float32)
    for i, r in enumerate(records):
        data[i, :march_block.ROWS * 4] = march_block.record(**r).ravel()
    data[1, march_block.GLOW:march_block.GLOW + 3] = (1.0, 2.0, 3.0)  # the per-frame lanes
    data[1, march_block.BLEND], data[1, march_block.JITTER] = 0.25, 0.625
    members = ["u_slab_min[0].xyz", "u_slab_max[0].xyz", "u_slab_min[4].xyz", "u_slab_max[4].xyz", "u_base",
               "vec3(u_step, u_voxel, u_sigma)", "u_extent", "vec3(u_lean, u_hg_g)", "u_glow_pos",
               "vec3(u_albedo_scale, u_blend, u_jitter_offset)", "u_glow_intensity", "u_emission"]
    lines = [f"out_values[{i}] = vec4({m}, 0.0);" for i, m in enumerate(members)]
    with open(march_block.__file__.replace(".py", ".glsl")) as fh:
        block = fh.read()
    source = ("#version 450 core\n" + bindings.glsl() + block +
              "layout(local_size_x = 1) in;\nlayout(std430, binding = 0) buffer Out { vec4 out_values[]; };\n"
              "void main() {\n" + "\n".join(lines) + "\n}\n")
    program = ctx.compute_shader(source)
    buffer = ctx.buffer(data.tobytes())
    out = ctx.buffer(reserve=16 * len(members))
    buffer.bind_to_uniform_block(bindings.BLOCKS["VOLUME"], offset=stride, size=march_block.RECORD_BYTES)
    out.bind_to_storage_buffer(0)
    program.run(1)
    got = np.frombuffer(out.read(), np.float32).reshape(-1, 4)[:, :3]
    r = records[1]
    expected = [r["slabs"][0][0], r["slabs"][0][1], r["slabs"][4][0], r["slabs"][4][1], r["base"],
                (r["step"], r["voxel"], r["sigma"]), r["extent"], (*r["lean"], r["hg_g"]), r["glow_pos"],
                (r["albedo_scale"], 0.25, 0.625), (1.0, 2.0, 3.0), r["emission"]]
    np.testing.assert_array_equal(got, np.asarray(expected, np.float64).astype(np.float32))
    program.release(), buffer.release(), out.release()


@pytest.mark.parametrize("kind", ["rain", "snow"])
def test_particles_of_every_level_move_by_the_formula(kind):
    """particles.py: p_i(t) = p0_i + (w + (0, 0, -v_i)) t + f_i(t), camera-relative and wrapped into
    its level's cube, q_i = (p_i(t) - c) mod L (each term reduced first); streak s_i = p_i(t) -
    p_i(t - T). Written out here per level, at t = 1e6 s and a camera 1e5 m out, against the layout's
    one pass over every level."""
    scene = tiny({"camera": {"position": [1e5 + 0.3, -2.7, 10.0]},
                  "weather": {"wind_speed": 7.0, "wind_direction": 230.0,
                              "precipitation": {"type": kind, "rate": 3.0, "streak_time": 0.04}}})
    view, settings, pool = make_view(scene.camera), PRESETS["medium"], ParticlePool()
    layout = particle_layout(scene, view, settings, pool)
    assert len({level.tile_size for level in layout.levels}) >= 2
    t, T = 1e6 + 0.123, 0.04
    q, streaks = layout.motion(t, view.position)
    wind = wind_vector(scene)
    for level in layout.levels:
        c = pool.get(kind, level.tile_size, level.particles, level.index)
        d = diameters(kind, 3.0, c["u_size"])
        velocity = wind[None, :] - np.outer(fall_speed(kind, d) * c["speed_factor"], [0.0, 0.0, 1.0])

        def flutter(time):
            a = 2.0 * math.pi * np.fmod(c["flutter_hz"] * time + c["flutter_phase"], 1.0)
            return np.column_stack([c["flutter_radius"] * np.cos(a), c["flutter_radius"] * np.sin(a), np.zeros_like(a)])

        L = level.tile_size
        expected = np.mod(c["p0"] + np.fmod(velocity * t, L) + flutter(t) - np.fmod(view.position, L), L)
        at = slice(level.first_particle, level.first_particle + level.particles)
        assert np.all((q[at] >= 0.0) & (q[at] < L))
        wrapped = np.abs(q[at] - expected)
        np.testing.assert_allclose(np.minimum(wrapped, L - wrapped), 0.0, atol=1e-9)
        # T earlier: the phase reduced at t first, then T of it taken off
        a_then = 2.0 * math.pi * (np.fmod(c["flutter_hz"] * t + c["flutter_phase"], 1.0) - c["flutter_hz"] * T)
        flutter_then = np.column_stack([c["flutter_radius"] * np.cos(a_then), c["flutter_radius"] * np.sin(a_then),
                                        np.zeros_like(a_then)])
        np.testing.assert_allclose(streaks[at], velocity * T + flutter(t) - flutter_then, atol=1e-12)
        if kind == "snow":
            assert np.abs(streaks[at] - velocity * T).max() > 1e-3  # the flakes flutter
