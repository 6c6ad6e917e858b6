"""One registry of texture units and uniform-block binding points, and the one way to bind them.

Units 8 and up are **frame-wide**: the tables every lit pass reads (haze, sky view, atmosphere,
shadow maps, aerial perspective) sit there for the whole frame, so no pass may bind anything else
on them. Units 0-7 are **pass-local**: each pass binds what it reads there just before it draws.
The shaders read the same numbers: ``glsl()`` makes ``#define UNIT_<NAME>`` and ``BLOCK_<NAME>``
lines from these tables, included as ``generated/bindings.glsl``, and a shader declares
``layout(binding = UNIT_TRANSMITTANCE) uniform sampler2D ...``, so a number is written once.

A texture bound to a unit stays bound until something else is bound there. ``use_texture`` keeps,
per context, which texture object each unit holds and skips a bind that would change nothing: the
frame-wide tables are then bound once, not once per pass, and consecutive draws of one material
bind nothing. moderngl's own uploads and mipmap builds use its default unit (the context's last),
which no entry here names, so they never disturb this record.
"""

from __future__ import annotations

# Frame-wide units (read through common/atmosphere.glsl, common/aerial_table.glsl, common/shadows.glsl,
# common/lights.glsl).
FRAME_UNITS = {
    "HAZE_TABLE": 8,          # the fog layer's in-scattering table (sky/frame_sky.py)
    "SKY_VIEW_RADIANCE": 9,   # the per-frame sky-view table (sky/sky_view.py)
    "SKY_VIEW_INSCATTER": 10,
    "SKY_VIEW_TAU": 11,
    "TRANSMITTANCE": 12,      # the precomputed atmosphere (sky/tables.py)
    "IRRADIANCE": 13,
    "SCATTERING": 14,
    "SINGLE_MIE": 15,
    "SHADOW_KEY": 16,         # the sun's or moon's shadow map (surfaces/surfaces.py)
    "SHADOW_SPOT": 17,        # the spot light's shadow map
    "AERIAL_TAU": 18,         # the camera-frustum aerial-perspective table (common/aerial_table.py)
    "AERIAL_SOURCE": 19,
    "FOAM_NOISE": 20,         # the sea's foam noise (water), constant for the process's life
    "HAZE_LOBE": 21,          # the fog layer's phase-weighted sky light (sky/haze_lobe.py)
    "LIGHT_TILES": 22,        # the view's screen-tile light masks (light_tiles.py)
}

# Pass-local units: bound by the pass that reads them, reused by the next pass.
PASS_UNITS = {
    # glTF materials (surfaces/gpu_models.py)
    "BASE_TEX": 0, "MR_TEX": 1, "NORMAL_TEX": 2, "OCCLUSION_TEX": 3, "EMISSIVE_TEX": 4,
    # the sea (render/water): detail normal maps on 1..3, the wave field, its reflection and air tables
    "SEA_AIR_S": 0, "SEA_DETAIL0": 1, "SEA_FIELD": 4, "SEA_FIELD_SCALAR": 5, "SEA_SKY_REFLECT": 6, "SEA_AIR_T": 7,
    # the sky pass (render/sky/sky.py)
    "SKY_HAZY_MOON": 4, "SKY_HAZY": 5, "CIRRUS_HIDE": 6, "CIRRUS_TABLE": 7,
    # post processing (render/post)
    "HDR": 0, "DISTANCE": 1, "HALOS": 2, "HALO_TABLE": 3,
}

# Uniform-block binding points (std140 blocks shared by every program that declares them).
BLOCKS = {
    "FRAME": 0,  # per-frame and per-view constants (render/frame_block.py)
    "VOLUME": 1,  # one fire or smoke volume's march constants (render/volumes/march_block.py)
}

# Shader-storage binding points of compute shaders. Pass-local like units 0-7: a pass binds its
# buffers there just before it dispatches (GL guarantees 8 points to a compute shader).
STORAGE = {
    # the sea's detail-map synthesis (render/water/detail_synth.py)
    "SEA_DETAIL_WAVES": 0, "SEA_DETAIL_GRID": 1, "SEA_DETAIL_BINS": 2, "SEA_DETAIL_ENTRIES": 3,
    "SEA_DETAIL_ROWS": 4, "SEA_DETAIL_LEVELS": 5, "SEA_DETAIL_PAIRS": 6, "SEA_DETAIL_TEXELS": 7,
    # the bench's GPU head start (bench_gpu.py), dispatched between frames
    "GPU_HEAD_START": 0,
}


def shader_defines() -> dict[str, int]:
    """``UNIT_<NAME>``, ``BLOCK_<NAME>`` and ``STORAGE_<NAME>``: the registry as the shaders see it."""
    return {**{f"UNIT_{k}": v for k, v in {**FRAME_UNITS, **PASS_UNITS}.items()},
            **{f"BLOCK_{k}": v for k, v in BLOCKS.items()},
            **{f"STORAGE_{k}": v for k, v in STORAGE.items()}}


def glsl() -> str:
    """The registry as GLSL ``#define`` lines (once per program however often it is included)."""
    lines = [f"#define {name} {value}" for name, value in shader_defines().items()]
    return "#ifndef IGSERVER_BINDINGS\n#define IGSERVER_BINDINGS\n" + "\n".join(lines) + "\n#endif\n"


def use_texture(texture, unit: int) -> None:
    """Bind ``texture`` (a moderngl texture of any kind) to ``unit`` unless it is bound there already."""
    bound = _bound(texture.ctx)
    if bound.get(unit) is not texture:
        texture.use(unit)
        bound[unit] = texture


def use_textures(textures, first_unit: int = 0) -> None:
    """use_texture for each of ``textures`` (of one context) on consecutive units from ``first_unit``."""
    if not textures:
        return
    bound = _bound(textures[0].ctx)
    for unit, texture in enumerate(textures, first_unit):
        if bound.get(unit) is not texture:
            texture.use(unit)
            bound[unit] = texture


def forget_bindings(ctx) -> None:
    """After binding textures some other way (moderngl's ``use`` directly, a sampler object's
    state changed): bind every unit again on next use."""
    _bound(ctx).clear()


def _bound(ctx) -> dict:
    # Kept on the context object: it lives and dies with the GL context whose state it mirrors.
    # The textures are held (not their ids), so a released texture's reused id cannot fool it.
    try:
        return ctx._igserver_bound_units
    except AttributeError:
        ctx._igserver_bound_units = {}
        return ctx._igserver_bound_units


def write_buffer(buffer, data: bytes) -> bool:
    """Write ``data`` to the start of ``buffer`` unless it already holds exactly that (the last
    bytes written are kept on the buffer object). Instance data that did not change (a still
    camera, still entities) then costs a comparison, not an upload. Returns whether it wrote."""
    if getattr(buffer, "_igserver_content", None) == data:
        return False
    buffer.write(data)
    buffer._igserver_content = data
    return True
