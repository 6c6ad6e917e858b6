"""Texture units and block bindings: one registry (igserver/render/bindings.py) that the Python side
binds from and the shaders read as ``UNIT_<NAME>`` defines.

The frame-wide tables (haze, sky view, atmosphere, shadow maps, aerial table, foam noise) sit on
fixed units for the whole frame, so no pass may bind anything else there. A collision is silent on
llvmpipe: a shadow map bound on the sky-view unit made the surfaces' aerial perspective (and every
later pass) read depth values as in-scattered light."""
import re
from pathlib import Path

from igserver.render import bindings
from igserver.render.common import aerial_table
from igserver.render.post import post
from igserver.render.sky import frame_sky, sky, sky_view, tables
from igserver.render.surfaces import gpu_models, surfaces
from igserver.render.water import sea_inputs, sea_tables, water

RENDER = Path(__file__).resolve().parents[1] / "igserver" / "render"


def test_frame_wide_units_are_distinct_and_clear_of_the_pass_units():
    frame_wide = list(bindings.FRAME_UNITS.values())
    assert len(frame_wide) == len(set(frame_wide))
    assert not set(frame_wide) & set(bindings.PASS_UNITS.values())


def test_python_side_binds_the_registry_units():
    assert frame_sky.HAZE_TABLE_UNIT == bindings.FRAME_UNITS["HAZE_TABLE"]
    assert set(sky_view.SKY_VIEW_UNITS.values()) | set(tables.TABLE_UNITS.values()) | set(
        aerial_table.AERIAL_UNITS.values()) <= set(bindings.FRAME_UNITS.values())
    pass_units = {
        **gpu_models.SAMPLER_UNITS,
        "water detail": water.DETAIL_UNIT0, "water field": sea_inputs.FIELD_UNIT,
        "water field scalar": sea_inputs.FIELD_SCALAR_UNIT, "water sky reflection": sea_tables.SKY_REFLECT_UNIT,
        "water air T": sea_tables.AIR_T_UNIT, "water air S": sea_tables.AIR_S_UNIT,
        "post halo table": post.HALO_TABLE_UNIT, "sky cirrus table": sky.CIRRUS_TABLE_UNIT,
        "sky cirrus hide": sky.CIRRUS_HIDE_UNIT, "sky hazy table": sky.SKY_HAZY_UNIT,
        "sky hazy moon": sky.SKY_HAZY_MOON_UNIT,
    }
    assert set(pass_units.values()) <= set(bindings.PASS_UNITS.values()), pass_units
    assert water.DETAIL_UNIT0 + 2 not in bindings.FRAME_UNITS.values()  # the three detail maps
    assert {surfaces.SHADOW_UNIT_KEY, surfaces.SHADOW_UNIT_SPOT, water.FOAM_NOISE_UNIT} <= set(bindings.FRAME_UNITS.values())


def test_shaders_name_units_only_through_the_registry():
    # Every sampler a frame's shader binds explicitly uses a UNIT_ define (numbers only in the
    # table precompute, which runs on its own before any frame), and every UNIT_ it names exists.
    defines = bindings.shader_defines()
    for path in RENDER.rglob("*.glsl"):
        text = path.read_text()
        for m in re.finditer(r"layout\(binding\s*=\s*(\w+)\)\s*uniform\s+sampler\w*\s+(\w+);", text):
            if path.name == "precompute.glsl":
                continue
            assert m.group(1) in defines, (path.name, m.group(2), m.group(1))
    glsl = bindings.glsl()
    for name, value in defines.items():
        assert f"#define {name} {value}" in glsl


def test_every_texture_bind_goes_through_the_binding_record():
    # use_texture skips a bind its record says is done already: a texture bound behind its back
    # (``tex.use(unit)``) would leave the record stale and a later pass reading the wrong table.
    direct = []
    for path in list(RENDER.rglob("*.py")) + list((RENDER.parent / "quality").rglob("*.py")):
        if path.name == "bindings.py":
            continue
        for number, line in enumerate(path.read_text().splitlines(), 1):
            if re.search(r"\.use\((location\s*=\s*)?\w", line) and "sampler" not in line and "_halo_table" not in line \
                    and "matplotlib" not in line:
                direct.append(f"{path.name}:{number}: {line.strip()}")
    assert not direct, direct
