"""Compile-time light terms (render/frame.py light_defines, common/lights.glsl): a frame's shaders
leave out the code of the lights it does not have — the result must be the same picture, and the
terms a frame does have must still be compiled in."""

from __future__ import annotations

import numpy as np

from helpers import forcing_defines

from igserver.render.frame import local_light_defines
from igserver.render.lights import PointLight
from igserver.scene import apply_patch, load_scene


def _point() -> PointLight:
    return PointLight(np.zeros(3), np.ones(3), 10.0)


def _spot() -> PointLight:
    return PointLight(np.zeros(3), np.ones(3), 10.0, np.array([0.0, 0.0, -1.0]), 0.9, 0.8)


def test_local_light_defines():
    assert local_light_defines([]) == {"LOCAL_LIGHTS": 0, "SPOT_LIGHTS": 0, "LIGHT_TILES": 0}
    assert local_light_defines([_point()]) == {"LOCAL_LIGHTS": 1, "SPOT_LIGHTS": 0, "LIGHT_TILES": 0}
    assert local_light_defines([_point(), _spot()]) == {"LOCAL_LIGHTS": 1, "SPOT_LIGHTS": 1, "LIGHT_TILES": 0}


def _frame(renderer, scene) -> np.ndarray:
    renderer.render(scene)  # the frame before: particles and eye adaptation settled at this instant
    return renderer.render(scene).rgba.astype(int)


def test_leaving_the_spot_cone_out_changes_no_pixel(renderer, monkeypatch):
    # The demo's lights are points (a fire and a lamp; rain, sea and surfaces read them): the frame
    # compiles no cone test, and the picture is bit-identical to one that compiles it.
    scene = apply_patch(load_scene("demo"), {"camera": {"width": 160, "height": 90}})
    without = _frame(renderer, scene)
    forcing_defines(monkeypatch, SPOT_LIGHTS=1)
    assert np.array_equal(_frame(renderer, scene), without)


def test_a_frame_with_a_spot_compiles_its_cone(renderer, monkeypatch):
    # harbour_night's searchlight is a spot: its frame keeps the cone (left out, the light would
    # spill all round the boat).
    scene = apply_patch(load_scene("harbour_night"), {"camera": {"width": 160, "height": 90}})
    with_cone = _frame(renderer, scene)
    forcing_defines(monkeypatch, SPOT_LIGHTS=0)
    without_cone = _frame(renderer, scene)
    assert np.abs(with_cone - without_cone).max() > 20
