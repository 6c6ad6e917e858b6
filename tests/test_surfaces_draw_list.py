"""The surfaces pass's draw lists (surfaces.py _draw_list): every primitive of the frame's batches
drawn once, opaque draws grouped by their material's textures (fewer texture binds than the
models' order), blended draws in the models' order, the list kept while the batches are."""

from collections import Counter

import numpy as np
import pytest

from igserver.render.surfaces.surfaces import SurfacesPass
from igserver.scene import apply_patch, load_scene


def _naive(batches, use, blended, alpha_tested):
    out = []
    for batch in batches.values():
        if len(batch.rows[use]) == 0:
            continue
        for prim in batch.model.primitives:
            mode = prim.material.data.alpha_mode
            if blended is not None and (mode == 2) != blended:
                continue
            if alpha_tested is not None and (mode != 0) != alpha_tested:
                continue
            out.append(prim)
    return out


def _binds(materials) -> int:
    """Texture binds of drawing in this order (five units, a unit bound when its texture changes)."""
    held, n = [None] * 5, 0
    for mat in materials:
        for unit, tex in enumerate(mat.texture_set):
            if held[unit] != tex:
                held[unit], n = tex, n + 1
    return n


@pytest.fixture(scope="module")
def demo_pass(renderer_module):
    scene = apply_patch(load_scene("demo"), {"camera": {"width": 64, "height": 36}})
    renderer_module.render(scene)
    return renderer_module, scene, renderer_module.graph.passes["surfaces"]


@pytest.fixture(scope="module")
def renderer_module():
    from igserver.render.renderer import Renderer
    r = Renderer()
    yield r
    r.release()


@pytest.mark.parametrize("use, blended, alpha_tested", [("view", False, None), ("view", True, None),
                                                        ("shadow", None, False)])
def test_every_primitive_once_grouped_by_textures(demo_pass, use, blended, alpha_tested):
    renderer, scene, surfaces = demo_pass
    batches = surfaces._instances(scene, surfaces_view(renderer, scene))
    draws = surfaces._draw_list(batches, use, blended, alpha_tested)
    naive = _naive(batches, use, blended, alpha_tested)
    assert Counter(id(p) for p, _, _, _ in draws) == Counter(id(p) for p in naive)
    assert all(mat is prim.material for prim, mat, _, _ in draws)
    for prim, _, rows, count in draws:  # each primitive's own instance rows
        batch = next(b for b in batches.values() if prim in b.model.primitives)
        expected = batch.rows[use][:, batch.model.primitives.index(prim), :]
        assert count == len(expected) and rows == np.ascontiguousarray(expected, np.float32).tobytes()
    if blended:
        assert [p for p, _, _, _ in draws] == naive  # blending order kept
        return
    sets = [mat.texture_set for _, mat, _, _ in draws]
    runs = [s for i, s in enumerate(sets) if i == 0 or sets[i - 1] != s]
    assert len(runs) == len(set(sets))  # each texture set in one run
    if use == "view":
        assert len(naive) > 10
        assert _binds(m for _, m, _, _ in draws) < _binds(p.material for p in naive)


def surfaces_view(renderer, scene):
    from igserver.render.frame import frame_view
    from igserver.render.depth import zero_to_one
    return frame_view(scene.camera, zero_to_one(renderer.ctx))[0]


def test_the_list_is_kept_with_its_batches_and_made_again_with_new_ones(demo_pass):
    renderer, scene, surfaces = demo_pass
    view = surfaces_view(renderer, scene)
    batches = surfaces._instances(scene, view)
    first = surfaces._draw_list(batches, "view", False, None)
    assert surfaces._draw_list(batches, "view", False, None) is first
    moved = apply_patch(scene, {"camera": {"heading": scene.camera.heading + 1.0}})
    other = surfaces._instances(moved, surfaces_view(renderer, moved))
    assert other is not batches
    assert surfaces._draw_list(other, "view", False, None) is not first
    assert isinstance(surfaces, SurfacesPass)


def test_a_run_of_equal_values_or_textures_is_set_once(demo_pass, monkeypatch):
    import igserver.render.surfaces.surfaces as surfaces_mod
    renderer, scene, surfaces = demo_pass
    batches = surfaces._instances(scene, surfaces_view(renderer, scene))
    draws = surfaces._draw_list(batches, "view", False, None)
    sets, binds, drawn = [], [], []
    monkeypatch.setattr(surfaces_mod, "set_uniforms", lambda program, values: sets.append(values))
    for _, mat, _, _ in draws:
        monkeypatch.setattr(mat, "bind", lambda mat=mat: binds.append(mat.texture_set))
    for prim, _, _, _ in draws:
        monkeypatch.setattr(prim, "draw_rows", lambda *a, prim=prim: drawn.append(prim))
    surfaces._draw_batches(object(), batches, "view", blended=False)

    def runs(values):
        return [v for i, v in enumerate(values) if i == 0 or values[i - 1] != v]
    assert [p for p, _, _, _ in draws] == drawn
    assert [tuple(sorted(v.items())) for v in sets] == runs([m.uniform_state for _, m, _, _ in draws])
    assert binds == runs([m.texture_set for _, m, _, _ in draws])
    assert len(sets) < len(draws) and len(binds) < len(draws)
