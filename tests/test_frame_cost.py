"""A frame's host cost: GL calls counted at moderngl's boundary, world work once per change, the
frame's uniform block laid out as GL reads it, uniform and texture writes skipped when unchanged."""
import numpy as np
import pytest

from helpers import tiny
from igserver.render import bindings, frame_block
from igserver.render.gl_count import GLCallCounter
from igserver.render.precip import particles
from igserver.render.renderer import Renderer
from igserver.render.shaders import ProgramCache, set_uniforms
from igserver.scene import apply_patch, load_scene

# The demo's GL calls a frame; the counted figure on this project's machines is ~345 (draws, the
# sea's instanced groups, material binds, the detail maps' uploads).
DEMO_GL_CALL_BUDGET = 400


@pytest.fixture(scope="module")
def renderer():
    r = Renderer()
    yield r
    r.release()


def _demo(width=64, height=36):
    return apply_patch(load_scene("demo"), {"camera": {"width": width, "height": height}})


def _stream(renderer, scene, frames, t0=None):
    t0 = scene.time.sim_time if t0 is None else t0
    for i in range(frames):
        renderer.render(apply_patch(scene, {"time": {"sim_time": t0 + i / 30.0}}))


def _recomputed(renderer) -> dict:
    """Every pass's memo counts (and the rain's tiles), summed by item."""
    out = {}
    for name, p in renderer.graph.passes.items():
        memo = getattr(p, "memo", None)
        if memo is not None:
            out.update({f"{name}.{k}": v for k, v in memo.computed.items()})
    out.update({f"precip.{k}": v for k, v in particles.TILES.computed.items()})
    return out


def test_demo_frame_gl_calls_within_budget_and_creates_nothing(renderer):
    scene = _demo()
    _stream(renderer, scene, 4)
    with GLCallCounter() as calls:
        renderer.render(apply_patch(scene, {"time": {"sim_time": scene.time.sim_time + 5 / 30.0}}))
    assert calls.total <= DEMO_GL_CALL_BUDGET, calls.by_name.most_common(12)
    assert calls.created() == 0, calls.by_name
    # the per-frame constants reach the programs through the block, not uniform by uniform
    assert not any(name.startswith(("Uniform[u_view_proj]", "Uniform[u_light_pos]", "Uniform[u_exposure]"))
                   for name in calls.by_name)


def test_a_stream_that_only_advances_sim_time_rederives_no_world_item(renderer):
    scene = _demo()
    _stream(renderer, scene, 3)
    before = _recomputed(renderer)
    assert {"surfaces.batches", "water.draw_plan", "volumes.visible_volumes", "precip.level_tiles"} <= set(before)
    _stream(renderer, scene, 6, t0=scene.time.sim_time + 1.0)
    assert _recomputed(renderer) == before


@pytest.mark.parametrize("patch, items", [
    ({"camera": {"heading": 291.0}}, {"surfaces.batches", "water.draw_plan", "volumes.visible_volumes",
                                      "precip.level_tiles"}),
    # the rain's tiles are camera-relative: a camera that moves without turning keeps them
    ({"camera": {"position": [0.5, -120.0, 6.0]}}, {"surfaces.batches", "water.draw_plan",
                                                      "volumes.visible_volumes"}),
    ({"shadows": {"distance": 150.0}}, {"surfaces.batches"}),
    ({"weather": {"wind_speed": 9.0}}, {"volumes.visible_volumes"}),
])
def test_each_input_recomputes_its_items_and_nothing_else(renderer, patch, items):
    scene = _demo()
    _stream(renderer, scene, 2)
    before = _recomputed(renderer)
    changed = apply_patch(scene, patch)
    renderer.render(apply_patch(changed, {"time": {"sim_time": scene.time.sim_time + 2.0}}))
    after = _recomputed(renderer)
    grew = {k for k in after if after[k] != before.get(k)}
    assert items <= grew, (patch, grew)
    # and once more at another time: nothing again
    renderer.render(apply_patch(changed, {"time": {"sim_time": scene.time.sim_time + 2.5}}))
    assert _recomputed(renderer) == after


def test_an_entity_moving_recomputes_the_batches(renderer):
    scene = _demo()
    _stream(renderer, scene, 2)
    before = _recomputed(renderer)["surfaces.batches"]
    entities = [e.model_dump(mode="json") for e in scene.entities]
    entities[0]["position"] = [entities[0]["position"][0] + 0.25, *entities[0]["position"][1:]]
    renderer.render(apply_patch(scene, {"entities": entities}))
    assert _recomputed(renderer)["surfaces.batches"] == before + 1


def test_frame_block_layout_is_what_glsl_reads(renderer):
    """A compute shader copies every field of the block as GL lays it out into a storage buffer: the
    values packed by frame_block.pack come back in order, so the two std140 layouts agree."""
    ctx = renderer.ctx
    rng = np.random.default_rng(5)
    values, expected = {}, []
    for f in frame_block.FIELDS:
        n = max(f.count, 1) * f.components
        if f.glsl == "int":
            v = int(rng.integers(0, 64))
            values[f.name], flat = v, [float(v)]
        else:
            flat = rng.uniform(-10, 10, n).astype(np.float32)
            values[f.name] = flat.tobytes() if (f.count or f.glsl == "mat4") else tuple(float(x) for x in flat)
            flat = list(flat)
        expected.extend(flat)
    lines = []
    at = 0
    for f in frame_block.FIELDS:
        comps = f.components
        for i in range(max(f.count, 1)):
            ref = f"{f.name}[{i}]" if f.count else f.name
            if f.glsl == "mat4":
                for c in range(4):
                    for r in range(4):
                        lines.append(f"out_values[{at}] = {ref}[{c}][{r}];")
                        at += 1
            elif comps == 1:
                lines.append(f"out_values[{at}] = float({ref});")
                at += 1
            else:
                for c in range(comps):
                    lines.append(f"out_values[{at}] = {ref}[{c}];")
                    at += 1
    source = ("#version 450 core\n#define FRAME_BLOCK 1\n" + frame_block.glsl().replace(
        '#include "generated/bindings.glsl"\n', bindings.glsl()) +
              "layout(local_size_x = 1) in;\nlayout(std430, binding = 0) buffer Out { float out_values[]; };\n"
              "void main() {\n" + "\n".join(lines) + "\n}\n")
    program = ctx.compute_shader(source)
    out = ctx.buffer(reserve=4 * at)
    block = ctx.buffer(frame_block.pack(values))
    block.bind_to_uniform_block(bindings.BLOCKS["FRAME"])
    out.bind_to_storage_buffer(0)
    program.run(1)
    got = np.frombuffer(out.read(), np.float32)
    np.testing.assert_array_equal(got, np.asarray(expected, np.float32))
    program.release(), out.release(), block.release()  # the renderer binds its own block again next frame


def test_the_block_packed_field_by_field_equals_a_whole_pack():
    """FrameBlock packs only the fields whose value changed since its last frame: after any sequence
    of changes (one field, several, a zero's sign, an array value, the same value again) its bytes
    are those of a pack from nothing."""
    rng = np.random.default_rng(9)

    def value(f):
        n = max(f.count, 1) * f.components
        if f.glsl == "int":
            return int(rng.integers(0, 64))
        flat = rng.uniform(-10, 10, n).astype(np.float32)
        if f.count or f.glsl == "mat4":
            return flat.tobytes()
        return float(flat[0]) if n == 1 else tuple(float(x) for x in flat)

    values = {f.name: value(f) for f in frame_block.FIELDS}
    packer = frame_block.Packer()
    scalars = [f.name for f in frame_block.FIELDS if f.glsl == "float" and not f.count]
    vectors = [f.name for f in frame_block.FIELDS if f.glsl.startswith("vec") and not f.count]
    for step in range(40):
        for f in rng.choice(frame_block.FIELDS, size=int(rng.integers(0, 4)), replace=False):
            values[f.name] = value(f)
        if step % 5 == 1:  # 0.0 -> -0.0: equal as numbers, other bits
            name = scalars[0]
            values[name] = 0.0 if step % 10 == 1 else -0.0
            vec = vectors[0]
            values[vec] = (0.0, 1.0, 2.0) if step % 10 == 1 else (-0.0, 1.0, 2.0)
        if step % 7 == 3:  # an array value, as numpy
            name = vectors[step % len(vectors)]
            values[name] = rng.uniform(-1, 1, next(f.components for f in frame_block.FIELDS if f.name == name))
        assert packer.pack(values) == frame_block.pack(values), step


def test_unchanged_uniforms_and_bindings_are_not_written_again(renderer):
    ctx = renderer.ctx
    programs = ProgramCache(ctx)
    program = programs.program("common/fullscreen.vert.glsl", "post/tonemap.glsl")
    with GLCallCounter() as calls:
        set_uniforms(program, {"u_hdr": 0, "u_exposure_correction": 1.5})
        set_uniforms(program, {"u_hdr": 0, "u_exposure_correction": 1.5})
        set_uniforms(program, {"u_hdr": 0, "u_exposure_correction": 2.0})
    assert calls.by_name["Uniform[u_exposure_correction].write"] == 2
    assert calls.by_name["Uniform[u_hdr].write"] <= 1
    tex = ctx.texture((2, 2), 4)
    with GLCallCounter() as calls:
        for _ in range(3):
            bindings.use_texture(tex, 5)
    assert calls.by_name["Texture.use"] == 1
    other = ctx.texture((2, 2), 4)
    with GLCallCounter() as calls:  # a material's five units: only the ones whose texture changes
        bindings.use_textures((tex, other, tex, tex, other), 4)
        bindings.use_textures((tex, other, other, tex, other), 4)
    assert calls.by_name["Texture.use"] == 5 + 1  # five units first, then the one that changed
    assert [bindings._bound(ctx)[u] for u in range(4, 9)] == [tex, other, other, tex, other]
    bindings.forget_bindings(ctx)
    tex.release(), other.release()


def test_frame_block_bytes_follow_the_frame_and_only_it(renderer):
    scene = tiny({"time": {"utc": "2026-06-21T10:00:00Z"}})
    renderer.render(scene)
    block = frame_block.FrameBlock.get(renderer.ctx)
    writes = block.writes
    renderer.render(scene)  # the same frame: the same bytes, no upload
    assert block.writes == writes
    renderer.render(apply_patch(scene, {"camera": {"heading": 10.0}}))
    assert block.writes == writes + 1


@pytest.mark.parametrize("name", ["demo", "night_fire"])
def test_a_stream_creates_no_gl_object(renderer, name):
    """Across volume keyframes (modelled at a capped rate: a new 3D texture's worth of work a few
    times a second) the textures are reused, not made."""
    scene = apply_patch(load_scene(name), {"camera": {"width": 64, "height": 36}})
    _stream(renderer, scene, 6)
    with GLCallCounter() as calls:
        _stream(renderer, scene, 24, t0=scene.time.sim_time + 0.2)
    assert calls.created() == 0, {k: v for k, v in calls.by_name.items() if k.startswith("Context.")}


def test_every_uniform_write_goes_through_set_uniforms():
    """set_uniforms skips a value the program already holds; a write behind its back
    (``program["u_x"].value = ...``) would make it skip the next real change."""
    import re
    from pathlib import Path

    root = Path(__file__).resolve().parents[1] / "igserver"
    direct = [f"{p.relative_to(root)}:{n}: {line.strip()}" for p in root.rglob("*.py") if p.name != "gl_count.py"
              for n, line in enumerate(p.read_text().splitlines(), 1)
              if re.search(r"\[[^\]]+\]\.(value\s*=[^=]|write\()", line) and "u_" in line]
    assert not direct, direct
