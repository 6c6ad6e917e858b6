"""Quality-study settings are arguments of the renderer and its passes, never the environment: the
per-pixel atmosphere (Renderer(atmosphere_direct=True)) is the reference the sky-view table is measured
against: every program of that renderer walks the tables, and the sky agrees within the table's error."""

from __future__ import annotations

import numpy as np
import pytest

from igserver.render.renderer import Renderer
from igserver.render.shaders import assemble
from igserver.scene import apply_patch, load_scene

DIRECT = "#define ATMOSPHERE_DIRECT_TABLES 1"


@pytest.mark.gl
def test_atmosphere_direct_is_a_renderer_argument(monkeypatch):
    monkeypatch.setenv("IGSERVER_ATMOSPHERE_DIRECT", "1")  # the environment sets no study knob
    assert DIRECT not in assemble("sky/sky.glsl", "FRAGMENT")
    scene = apply_patch(load_scene("sea_calm_dawn"), {"camera": {"width": 96, "height": 54}})
    # two fresh renderers: neither carries eye adaptation from other tests' frames
    plain, direct = Renderer(), Renderer(atmosphere_direct=True)
    try:
        table = plain.render(scene).rgba[..., :3].astype(int)
        assert "ATMOSPHERE_DIRECT_TABLES" not in plain.programs.context_defines
        assert direct.programs.context_defines["ATMOSPHERE_DIRECT_TABLES"] == 1
        reference = direct.render(scene).rgba[..., :3].astype(int)
        compiled = [defines for *_, defines in direct.programs._programs]
        assert compiled and all(("ATMOSPHERE_DIRECT_TABLES", 1) in defines for defines in compiled)
    finally:
        direct.release()
        plain.release()
    # the low sun's sky through the table and per pixel: a few 8-bit levels apart, not the same pixels
    diff = np.abs(reference - table)
    assert 0.0 < diff.mean() < 5.0 and diff.max() <= 16, (diff.mean(), diff.max())
