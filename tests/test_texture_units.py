"""Texture units: the frame-wide tables (haze, sky view, atmosphere) sit on fixed units that every
pass's shaders read through common/atmosphere.glsl, so no pass may bind anything else there.

A collision is silent on llvmpipe: a shadow map bound on the sky-view unit made the surfaces'
aerial perspective (and every later pass) read depth values as in-scattered light."""
import re
from pathlib import Path

from igserver.render.common import aerial_table
from igserver.render.post import post
from igserver.render.sky import frame_sky, sky, sky_view, tables
from igserver.render.surfaces import gpu_models, surfaces
from igserver.render.water import water

RENDER = Path(__file__).resolve().parents[1] / "igserver" / "render"


def frame_wide_units() -> set[int]:
    return {frame_sky.HAZE_TABLE_UNIT, *sky_view.SKY_VIEW_UNITS.values(), *tables.TABLE_UNITS.values(),
            *aerial_table.AERIAL_UNITS.values()}


def test_frame_wide_units_are_distinct():
    units = [frame_sky.HAZE_TABLE_UNIT, *sky_view.SKY_VIEW_UNITS.values(), *tables.TABLE_UNITS.values(),
             *aerial_table.AERIAL_UNITS.values()]
    assert len(units) == len(set(units))


def test_pass_units_avoid_the_frame_wide_units():
    pass_units = {
        "surfaces shadow (key)": surfaces.SHADOW_UNIT_KEY,
        "surfaces shadow (spot)": surfaces.SHADOW_UNIT_SPOT,
        **{f"material {k}": v for k, v in gpu_models.SAMPLER_UNITS.items()},
        "water field": water.FIELD_UNIT, "water field scalar": water.FIELD_SCALAR_UNIT,
        "water sky reflection": water.SKY_REFLECT_UNIT, "water air T": water.AIR_T_UNIT,
        "water air S": water.AIR_S_UNIT, "water foam noise": water.FOAM_NOISE_UNIT,
        "post halo table": post.HALO_TABLE_UNIT, "sky cirrus table": sky.CIRRUS_TABLE_UNIT,
        "sky cirrus hide": sky.CIRRUS_HIDE_UNIT,
        "sky hazy table": sky.SKY_HAZY_UNIT, "sky hazy moon": sky.SKY_HAZY_MOON_UNIT,
    }
    clash = {name: unit for name, unit in pass_units.items() if unit in frame_wide_units()}
    assert not clash, clash


def test_shader_bindings_of_frame_wide_tables_match_python():
    # The GLSL side declares the frame-wide samplers with explicit bindings; they must be the
    # units the Python side binds, and no other sampler in any shader may claim those units.
    text = (RENDER / "common" / "atmosphere.glsl").read_text() + (RENDER / "common" / "aerial_table.glsl").read_text()
    declared = {m.group(2): int(m.group(1))
                for m in re.finditer(r"layout\(binding\s*=\s*(\d+)\)\s*uniform\s+\w+\s+(\w+);", text)}
    expected = {"u_haze_table": frame_sky.HAZE_TABLE_UNIT, **sky_view.SKY_VIEW_UNITS, **tables.TABLE_UNITS,
                **aerial_table.AERIAL_UNITS}
    assert {k: declared.get(k) for k in expected} == expected
    for path in RENDER.rglob("*.glsl"):
        if path.name in ("atmosphere.glsl", "aerial_table.glsl", "precompute.glsl"):  # precompute runs on its own, before any frame
            continue
        for m in re.finditer(r"layout\(binding\s*=\s*(\d+)\)\s*uniform\s+sampler\w*\s+(\w+);", path.read_text()):
            assert int(m.group(1)) not in frame_wide_units(), (path.name, m.group(2))
